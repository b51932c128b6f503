"""FlockVecEnv against SB3's VecEnv contract."""

import os
import subprocess
import sys

import numpy as np
import pytest

from boids_env.train.vec_env import EPISODE_INFO, CopySpec, FlockVecEnv

SHORT = {"max_cycles": 25}


def _specs(*sizes, speeds=(0.55,)):
    return [CopySpec(n, speeds, env_fields=dict(SHORT)) for n in sizes]


def _rollout(venv, steps, seed=0):
    rng = np.random.default_rng(seed)
    obs = [venv.reset()]
    out = []
    for _ in range(steps):
        actions = rng.uniform(-0.5, 0.5, (venv.num_envs, 2)).astype(np.float32)
        o, r, d, infos = venv.step(actions)
        obs.append(o)
        out.append((o, r, d, infos))
    return obs, out


def test_shapes_spaces_and_slots_of_mixed_group_sizes():
    venv = FlockVecEnv(_specs(7, 13, 5), seed=1)
    try:
        assert venv.num_envs == 6 + 12 + 4
        obs = venv.reset()
        assert obs.shape == (22, *venv.observation_space.shape) and obs.dtype == np.float32
        assert all(venv.observation_space.contains(o) for o in obs)
        o, r, d, infos = venv.step(np.zeros((22, 2), np.float32))
        assert o.shape == obs.shape and r.shape == (22,) and d.shape == (22,)
        assert r.dtype == np.float32 and d.dtype == bool and len(infos) == 22
        assert venv.get_attr("render_mode") == [None] * 22
        robots = venv.get_attr("config", indices=[0, 6, 21])
        assert [c.scenario.robots for c in robots] == [7, 13, 5]
    finally:
        venv.close()


def test_auto_reset_truncation_and_terminal_observation():
    venv = FlockVecEnv(_specs(4, 3), seed=2)
    try:
        _obs, steps = _rollout(venv, 25)
        for _o, _r, d, infos in steps[:-1]:
            assert not d.any() and all("terminal_observation" not in i for i in infos)
        last_obs, _, done, infos = steps[-1]
        assert done.all()
        assert all(i["TimeLimit.truncated"] is True for i in infos)
        terminal = np.stack([i["terminal_observation"] for i in infos])
        # the returned observation is the next episode's first (everything at rest)
        assert not np.array_equal(terminal, last_obs)
        assert np.all(last_obs[:, 0:2] == 0) and np.any(terminal[:, 0:2] != 0)
        first = [i for i in infos if EPISODE_INFO in i]
        assert len(first) == 2 and {f[EPISODE_INFO]["robots"] for f in first} == {3, 4}
        # episode continues after the auto-reset
        _, _, d, _ = venv.step(np.zeros((venv.num_envs, 2), np.float32))
        assert not d.any()
    finally:
        venv.close()


def test_seeding_is_reproducible_and_copies_never_share_streams():
    def run(seed):
        venv = FlockVecEnv(_specs(5, 5, speeds=(0.5, 0.6)), seed=seed)
        try:
            obs, steps = _rollout(venv, 60)
            return np.stack(obs), [s[3] for s in steps]
        finally:
            venv.close()

    a, _info_a = run(3)
    b, _ = run(3)
    c, _ = run(4)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    # the two identical copies got different episodes (their own seed streams)
    assert not np.array_equal(a[:, :4], a[:, 4:])


def test_worker_processes_give_the_same_trajectories():
    specs = _specs(5, 7, 4)
    one = FlockVecEnv(specs, seed=5)
    two = FlockVecEnv(specs, seed=5, processes=2)
    try:
        obs1, steps1 = _rollout(one, 30)
        obs2, steps2 = _rollout(two, 30)
        assert np.array_equal(np.stack(obs1), np.stack(obs2))
        assert all(np.array_equal(s1[1], s2[1]) for s1, s2 in zip(steps1, steps2, strict=True))
        assert two.env_method("episode_metrics", indices=[0])[0]["steps"] == 5
    finally:
        one.close()
        two.close()


def test_bad_arguments_are_clear_errors():
    with pytest.raises(ValueError, match="processes must be an integer in"):
        FlockVecEnv(_specs(5), processes=2)
    with pytest.raises(ValueError, match="robots must be >= 2"):
        FlockVecEnv([CopySpec(1)])
    with pytest.raises(ValueError, match="same observation size"):
        FlockVecEnv([CopySpec(5), CopySpec(5, env_fields={"neighbours": 3})])
    venv = FlockVecEnv(_specs(5))
    try:
        venv.reset()
        with pytest.raises(ValueError, match=r"actions must have shape \(4, 2\)"):
            venv.step(np.zeros((3, 2), np.float32))
        with pytest.raises(ValueError, match="finite"):
            venv.step(np.full((4, 2), np.nan, np.float32))
        with pytest.raises(ValueError, match="seed must be"):
            venv.seed(-1)
    finally:
        venv.close()


def test_worker_processes_with_shared_memory_match_one_process_exactly():
    from boids_env.train.vec_env import CopySpec, FlockVecEnv

    specs = [CopySpec(5, (0.5, 0.6), env_fields={"max_cycles": 40}),
             CopySpec(7, env_fields={"max_cycles": 40}),
             CopySpec(4, env_fields={"max_cycles": 40})]
    one, many = FlockVecEnv(specs, seed=3, processes=1), FlockVecEnv(specs, seed=3, processes=3)
    try:
        rng = np.random.default_rng(0)
        np.testing.assert_array_equal(one.reset(), many.reset())
        for step in range(90):  # crosses two episode ends (auto-reset)
            act = rng.uniform(-0.5, 0.5, (one.num_envs, 2)).astype(np.float32)
            a, b = one.step(act), many.step(act)
            for x, y, name in zip(a[:3], b[:3], ("obs", "rewards", "dones"), strict=True):
                np.testing.assert_array_equal(x, y, err_msg=f"step {step}: {name}")
            assert [sorted(i) for i in a[3]] == [sorted(i) for i in b[3]], step
    finally:
        one.close()
        many.close()


def test_default_processes_and_threads_split_the_cores():
    from boids_env.train.vec_env import default_processes, default_threads

    # on 2 cores one torch thread: a second spins against the env stepped in-process
    assert default_processes(6, cores=2) == 1 and default_threads(1, cores=2) == 1
    assert default_threads(2, cores=2) == 1
    assert default_processes(6, cores=1) == 1 and default_threads(1, cores=1) == 1
    # from 3 cores on: half the cores step the env copies, the rest run torch
    assert default_processes(32, cores=16) == 8 and default_threads(8, cores=16) == 8
    assert default_processes(32, cores=3) == 1 and default_threads(1, cores=3) == 2
    assert default_processes(6, cores=16) == 6 and default_threads(6, cores=16) == 10
    assert default_processes(32, cores=9) == 4 and default_threads(4, cores=9) == 5


def test_train_config_resolves_processes_and_threads_from_the_cores(monkeypatch):
    import os

    from boids_env.train.config import TrainConfig

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(16)), raising=False)
    config = TrainConfig(copies=16)
    assert (config.resolved_processes(), config.resolved_threads()) == (8, 8)
    pinned = config.replace(processes=4, torch_threads=3)
    assert (pinned.resolved_processes(), pinned.resolved_threads()) == (4, 3)
    assert config.replace(processes=12).resolved_threads() == 4


def test_training_copies_load_the_compiled_kernels_at_once():
    """A process left alone loads the kernels only after some 10,000 calls (about 400 steps
    of the defaults' six copies), switching mid-rollout; copies made for training repay the
    load at once."""
    code = ("from boids_env import kernels\n"
            "from boids_env.train.vec_env import CopySpec, FlockVecEnv\n"
            "print(kernels.loaded() is None)\n"
            "venv = FlockVecEnv([CopySpec(3, env_fields={'max_cycles': 5})], seed=0)\n"
            "venv.reset()\n"
            "print(kernels.loaded() is None)\n"
            "venv.close()\n")
    env = {k: v for k, v in os.environ.items() if k != "BOIDS_KERNELS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=300, check=True)
    assert out.stdout.split() == ["True", "False"]


def test_processes_count_the_training_process_which_steps_the_first_shard():
    import multiprocessing as mp

    from boids_env.train.shards import RemoteShard, Shard

    before = set(mp.active_children())
    venv = FlockVecEnv(_specs(5, 7, 4), seed=1, processes=2)
    try:
        workers = set(mp.active_children()) - before
        assert len(workers) == 1 and venv.processes == 2
        local, remote = venv.shards
        assert isinstance(local, Shard) and isinstance(remote, RemoteShard)
        # the split balances followers: copies of 4 + 6 followers here, 3 in the worker
        assert venv.shard_sizes == [10, 3]
    finally:
        venv.close()


@pytest.mark.parametrize(("threshold", "expected"), [(0.0, 2), (1e9, 1)])
def test_auto_processes_on_two_cores_add_a_worker_for_slow_copies_only(
        monkeypatch, threshold, expected):
    import boids_env.train.vec_env as vec_env

    monkeypatch.setattr(vec_env, "available_cores", lambda: 2)
    monkeypatch.setattr(vec_env, "SECOND_CORE_STEP", threshold)
    specs = [CopySpec(5, env_fields={"max_cycles": 12}), CopySpec(6, env_fields={"max_cycles": 12})]
    auto, one = FlockVecEnv(specs, seed=2, processes=0), FlockVecEnv(specs, seed=2, processes=1)
    try:
        assert auto.processes == expected and len(auto.shards) == expected
        # the timing probe steps throwaway copies: the trajectories are one process's
        obs_auto, steps_auto = _rollout(auto, 30)
        obs_one, steps_one = _rollout(one, 30)
        assert np.array_equal(np.stack(obs_auto), np.stack(obs_one))
        assert all(np.array_equal(a[1], b[1]) for a, b in zip(steps_auto, steps_one, strict=True))
    finally:
        auto.close()
        one.close()


def test_auto_processes_time_no_copies_off_two_cores(monkeypatch):
    import boids_env.train.vec_env as vec_env

    def no_probe(specs):
        raise AssertionError("the step was timed")

    monkeypatch.setattr(vec_env, "_step_seconds", no_probe)
    for cores, expected in ((1, 1), (16, 2)):
        monkeypatch.setattr(vec_env, "available_cores", lambda cores=cores: cores)
        venv = FlockVecEnv(_specs(5, 6), processes=0)
        try:
            assert venv.processes == expected
        finally:
            venv.close()


def test_a_worker_imports_neither_torch_nor_stable_baselines3():
    # a worker unpickles its CopySpecs and steps its shard from boids_env.train.shards:
    # importing the learner's modules would cost each worker some 2 s and 190 MiB
    code = ("import sys, pickle\n"
            "from boids_env.train.shards import CopySpec, _worker\n"
            "pickle.loads(pickle.dumps([CopySpec(5)]))\n"
            "heavy = sorted({'torch', 'stable_baselines3'} & set(sys.modules))\n"
            "assert not heavy, heavy\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr


def test_a_failed_build_leaves_no_worker_behind(monkeypatch):
    import multiprocessing as mp

    import boids_env.train.vec_env as vec_env

    def broken(specs):
        raise RuntimeError("this process's copies could not be built")

    before = set(mp.active_children())
    monkeypatch.setattr(vec_env, "Shard", broken)
    with pytest.raises(RuntimeError, match="could not be built"):
        FlockVecEnv(_specs(5, 6), processes=2)
    assert not [p for p in set(mp.active_children()) - before if p.is_alive()]
