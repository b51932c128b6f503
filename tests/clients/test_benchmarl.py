"""BenchMARL: the shipped task (``boids_env.integrations.benchmarl``) describes the env right,
loads from its YAML and BenchMARL's registry, and MAPPO trains one iteration on it, from the
YAML loader and from BenchMARL's command line (the ``benchmarl`` extra; CI installs it)."""

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("benchmarl")

from benchmarl.algorithms import MappoConfig
from benchmarl.environments import task_config_registry
from benchmarl.experiment import Experiment, ExperimentConfig
from benchmarl.models.mlp import MlpConfig

from boids_env import parallel_env
from boids_env.integrations.benchmarl import BoidsTask
from boids_env.integrations.benchmarl_run import SEARCH_PATH, argv_with_search_path
from boids_env.integrations.torchrl import BoidsTorchRLEnv

CONFIG = {"robots": 4, "max_cycles": 20, "scene": "small_room", "lidar_rays": 8}


def test_the_task_describes_the_env():
    task = BoidsTask.LEADER_FOLLOWING.get_task(config=CONFIG)
    env = task.get_env_fun(num_envs=2, continuous_actions=True, seed=0, device="cpu")()
    assert isinstance(env, BoidsTorchRLEnv) and env.batch_size == (2,)  # one batched env
    plain = parallel_env(**CONFIG)
    agents = plain.possible_agents
    assert task.group_map(env) == {"agents": agents}
    obs = task.observation_spec(env)["agents", "observation"]  # one world's, as BenchMARL's
    assert tuple(obs.shape) == (len(agents), *plain.observation_space(agents[0]).shape)
    action = task.action_spec(env)["agents", "action"]
    space = plain.action_space(agents[0])
    np.testing.assert_array_equal(action.space.high[0].numpy(), space.high)
    np.testing.assert_array_equal(action.space.low[0].numpy(), space.low)
    assert set(task.info_spec(env)["agents", "info"].keys()) >= {"reward_separation"}
    assert task.max_steps(env) == 20
    assert task.supports_continuous_actions() and not task.supports_discrete_actions()
    assert task.state_spec(env) is None and task.action_mask_spec(env) is None


def test_the_task_loads_from_its_shipped_yaml_and_benchmarls_registry():
    task = BoidsTask.LEADER_FOLLOWING.get_from_yaml()
    assert task.config == {}  # the study's case
    assert BoidsTask.LEADER_FOLLOWING.get_task() == task
    assert task_config_registry["boids/leader_following"] is BoidsTask.LEADER_FOLLOWING


def test_a_yaml_of_the_users_is_read_and_a_non_mapping_refused(tmp_path):
    mine = tmp_path / "mine.yaml"
    mine.write_text("robots: 5\nscene: small_room\n")
    task = BoidsTask.LEADER_FOLLOWING.get_from_yaml(str(mine))
    assert task.config == {"robots": 5, "scene": "small_room"}
    mine.write_text("- robots\n")
    with pytest.raises(ValueError, match=r"mine\.yaml must hold a mapping"):
        BoidsTask.LEADER_FOLLOWING.get_from_yaml(str(mine))


def test_the_command_line_puts_our_configs_on_hydras_search_path():
    assert argv_with_search_path(["task=boids/leader_following"]) == [
        "task=boids/leader_following", f"hydra.searchpath=[{SEARCH_PATH}]"]
    assert argv_with_search_path(["hydra.searchpath=[file:///mine]"]) == [
        f"hydra.searchpath=[file:///mine,{SEARCH_PATH}]"]


def test_a_bad_field_is_refused_when_the_env_function_is_made():
    task = BoidsTask.LEADER_FOLLOWING.get_task(config={"robots": 1})
    with pytest.raises(ValueError, match="robots"):
        task.get_env_fun(num_envs=1, continuous_actions=True, seed=0, device="cpu")


def test_mappo_runs_one_iteration_on_the_task_from_its_yaml(tmp_path):
    task = BoidsTask.LEADER_FOLLOWING.get_from_yaml()
    task.config.update(CONFIG)  # small: 4 robots, 20 steps
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
    experiment = Experiment(task=task,
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
    env = task.get_env_fun(num_envs=3, continuous_actions=True, seed=seed, device="cpu")()
    return env.reset()["agents", "observation"].numpy()


def _second_episode_start(seed):
    """The first observations of the env seeded with ``seed`` at its second reset (the batched
    env resets with the seed when it is made; BenchMARL's collector's reset is the second)."""
    env = parallel_env(robots=3, max_cycles=20)
    env.reset(seed=seed)
    obs, _ = env.reset()
    return np.stack([obs[a] for a in env.possible_agents])


def test_the_worlds_benchmarl_collects_from_start_different_episodes_reproducibly():
    obs = _first_observations(4)
    assert not np.array_equal(obs[0], obs[1]) and not np.array_equal(obs[1], obs[2])
    np.testing.assert_array_equal(obs, _first_observations(4))
    for k in range(3):  # world k runs the episodes of seed 4 + k
        np.testing.assert_array_equal(obs[k], _second_episode_start(4 + k), err_msg=f"world {k}")


@pytest.mark.slow
def test_benchmarls_command_line_trains_mappo_on_the_task(tmp_path):
    overrides = ["algorithm=mappo", "task=boids/leader_following", "+task.robots=4",
                 "+task.max_cycles=20", "experiment.max_n_iters=1",
                 "experiment.on_policy_collected_frames_per_batch=40",
                 "experiment.on_policy_n_envs_per_worker=2",
                 "experiment.on_policy_n_minibatch_iters=1",
                 "experiment.on_policy_minibatch_size=20", "experiment.evaluation=false",
                 "experiment.loggers=[]", "experiment.create_json=false",
                 "experiment.checkpoint_at_end=false", f"experiment.save_folder={tmp_path}",
                 "experiment.sampling_device=cpu", "experiment.train_device=cpu",
                 f"hydra.run.dir={tmp_path}"]
    done = subprocess.run([sys.executable, "-m", "boids_env.integrations.benchmarl_run",
                           *overrides], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Task: boids/leader_following" in done.stdout, done.stdout[-2000:]
    assert "mean return" in done.stderr, done.stderr[-2000:]
