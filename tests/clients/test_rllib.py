"""RLlib: ``boids_env.integrations.rllib.register`` makes the env an RLlib env name, and PPO
trains one tiny iteration on it with one policy shared by the followers (the ``rllib`` extra,
``ray[rllib]``; CI installs it). About 25 s, most of it ``ray.init``."""

import numpy as np
import pytest

pytest.importorskip("ray.rllib")

from ray.tune.registry import ENV_CREATOR, _global_registry

from boids_env import parallel_env
from boids_env.integrations import rllib


def test_register_makes_the_env_with_its_fields_updated_by_env_config():
    name = rllib.register("boids_test_fields", robots=4, max_cycles=20)
    env = _global_registry.get(ENV_CREATOR, name)({"lidar_rays": 8, "scene": "small_room"})
    plain = parallel_env(robots=4, max_cycles=20, lidar_rays=8, scene="small_room")
    assert sorted(env.possible_agents) == plain.possible_agents
    obs, _ = env.reset(seed=2)
    expected, _ = plain.reset(seed=2)
    for agent in plain.possible_agents:
        np.testing.assert_array_equal(obs[agent], expected[agent])
        assert env.observation_space[agent] == plain.observation_space(agent)
    _, _, terminated, truncated, _ = env.step({a: np.zeros(2) for a in plain.possible_agents})
    assert terminated["__all__"] is False and truncated["__all__"] is False


def test_register_refuses_bad_input_before_registering():
    with pytest.raises(ValueError, match="robots"):
        rllib.register("boids_test_bad", robots=1)
    assert not _global_registry.contains(ENV_CREATOR, "boids_test_bad")
    with pytest.raises(TypeError, match="name must be a non-empty str"):
        rllib.register("")


@pytest.mark.slow
def test_ppo_trains_one_iteration_with_a_shared_policy():
    import ray
    from ray.rllib.algorithms.ppo import PPOConfig

    name = rllib.register("boids_test_ppo", robots=4, max_cycles=20)
    config = (PPOConfig().environment(name, env_config={"leader_speed": 0.6})
              .env_runners(num_env_runners=0, rollout_fragment_length=20)
              .learners(num_learners=0)
              .training(train_batch_size_per_learner=40, minibatch_size=20, num_epochs=1)
              .multi_agent(**rllib.shared_policy())
              .debugging(seed=0))
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        algo = config.build_algo()
        try:
            result = algo.train()
            shared = algo.get_module(rllib.POLICY)
        finally:
            algo.stop()
    finally:
        if started:
            ray.shutdown()
    assert result["training_iteration"] == 1
    assert result["env_runners"]["num_env_steps_sampled_lifetime"] >= 40
    assert shared is not None  # the followers' one module
