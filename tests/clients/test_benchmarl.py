"""BenchMARL: the shipped task (``boids_env.integrations.benchmarl``) describes the env right and
MAPPO trains one iteration on it (the ``benchmarl`` extra; CI installs it)."""

import numpy as np
import pytest

pytest.importorskip("benchmarl")

from benchmarl.algorithms import MappoConfig
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.models.mlp import MlpConfig

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
