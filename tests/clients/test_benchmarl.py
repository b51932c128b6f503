"""BenchMARL: the shipped task (``boids_env.integrations.benchmarl``) describes the env right and
MAPPO trains one iteration on it (the ``benchmarl`` extra; CI installs it)."""

import numpy as np
import pytest

pytest.importorskip("benchmarl")

from benchmarl.algorithms import MappoConfig
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.models.mlp import MlpConfig
from torchrl.envs import SerialEnv

from boids_env import parallel_env
from boids_env.integrations.benchmarl import BoidsTask

CONFIG = {"robots": 4, "max_cycles": 20, "scene": "small_room", "lidar_rays": 8}


def test_the_task_describes_the_env():
    task = BoidsTask.LEADER_FOLLOWING.get_task(config=CONFIG)
    env = task.get_env_fun(num_envs=1, continuous_actions=True, seed=0, device="cpu")()
    plain = parallel_env(**CONFIG)
    agents = plain.possible_agents
    assert task.group_map(env) == {"follower": agents}
    obs = task.observation_spec(env)["follower", "observation"]
    assert tuple(obs.shape) == (len(agents), *plain.observation_space(agents[0]).shape)
    action = task.action_spec(env)["follower", "action"]
    space = plain.action_space(agents[0])
    np.testing.assert_array_equal(action.space.high[0].numpy(), space.high)
    np.testing.assert_array_equal(action.space.low[0].numpy(), space.low)
    assert set(task.info_spec(env)["follower", "info"].keys()) >= {"reward_separation"}
    assert task.max_steps(env) == 20
    assert task.supports_continuous_actions() and not task.supports_discrete_actions()
    assert task.state_spec(env) is None and task.action_mask_spec(env) is None


def test_a_bad_field_is_refused_when_the_env_function_is_made():
    task = BoidsTask.LEADER_FOLLOWING.get_task(config={"robots": 1})
    with pytest.raises(ValueError, match="robots"):
        task.get_env_fun(num_envs=1, continuous_actions=True, seed=0, device="cpu")


def test_mappo_runs_one_iteration_on_the_task(tmp_path):
    config = ExperimentConfig.get_from_yaml()
    config.max_n_iters = 1
    config.on_policy_collected_frames_per_batch = 40
    config.on_policy_n_envs_per_worker = 2
    config.on_policy_n_minibatch_iters = 1
    config.on_policy_minibatch_size = 20
    config.evaluation = False
    config.render = False
    config.loggers = []
    config.create_json = False
    config.checkpoint_at_end = False
    config.save_folder = str(tmp_path)
    experiment = Experiment(task=BoidsTask.LEADER_FOLLOWING.get_task(config=CONFIG),
                            algorithm_config=MappoConfig.get_from_yaml(),
                            model_config=MlpConfig.get_from_yaml(),
                            critic_model_config=MlpConfig.get_from_yaml(), seed=0, config=config)
    before = [p.detach().clone() for p in experiment.policy.parameters()]
    experiment.run()
    assert experiment.n_iters_performed == 1
    assert experiment.total_frames == 40
    after = list(experiment.policy.parameters())
    assert any(not np.array_equal(a.detach().numpy(), b.numpy()) for a, b in zip(after, before,
                                                                                 strict=True))


def _first_observations(seed):
    task = BoidsTask.LEADER_FOLLOWING.get_task(config={"robots": 3, "max_cycles": 20})
    env = SerialEnv(3, task.get_env_fun(num_envs=3, continuous_actions=True, seed=seed,
                                        device="cpu"))
    return env.reset()["follower", "observation"].numpy()


def _second_episode_start(seed):
    """The first observations of the env seeded with ``seed`` at its second reset (TorchRL's
    wrapper resets with the seed when it is made; the batch's reset is the second)."""
    env = parallel_env(robots=3, max_cycles=20)
    env.reset(seed=seed)
    obs, _ = env.reset()
    return np.stack([obs[a] for a in env.possible_agents])


def test_the_copies_benchmarl_collects_from_start_different_episodes_reproducibly():
    obs = _first_observations(4)
    assert not np.array_equal(obs[0], obs[1]) and not np.array_equal(obs[1], obs[2])
    np.testing.assert_array_equal(obs, _first_observations(4))
    # each copy runs the episodes of its own seed, 4 + k for the k-th env made (TorchRL's
    # batch makes one more env than its copies, for the specs)
    starts = {seed: _second_episode_start(seed) for seed in range(4, 8)}
    seeds = [[s for s, row in starts.items() if np.array_equal(obs[k], row)] for k in range(3)]
    assert all(len(found) == 1 for found in seeds), seeds
    assert len({found[0] for found in seeds}) == 3, seeds
