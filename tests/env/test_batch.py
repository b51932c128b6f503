"""Many worlds per process (boids_env.batch.EnvBatch): each copy's results are the bits it
gives stepped alone, and bad input is refused before any copy steps."""

import numpy as np
import pytest

from boids_env import kernels, parallel_env
from boids_env.batch import EnvBatch
from boids_env.fused import fusable

FIELDS = [{"robots": 7, "max_cycles": 60}, {"robots": 13, "max_cycles": 60, "frame": "leader"},
          {"robots": 7, "max_cycles": 40, "reward": "safe"}]


def test_each_copy_is_bit_identical_to_stepping_it_alone():
    batch = EnvBatch([parallel_env(**f) for f in FIELDS])
    alone = [parallel_env(**f) for f in FIELDS]
    seeds = [3, 4, 5]
    obs = batch.reset_arrays(seeds)
    want = [env.reset_arrays(seed=s) for env, s in zip(alone, seeds, strict=True)]
    np.testing.assert_array_equal(obs, np.concatenate(want))
    assert batch.rows == 6 + 12 + 6 and batch.bounds == [0, 6, 18, 24]
    rng = np.random.default_rng(0)
    for step in range(40):
        act = rng.uniform(-0.8, 0.8, (batch.rows, 2)).astype(np.float32)
        got = batch.step_arrays(act)
        for i, env in enumerate(alone):
            rows = slice(batch.bounds[i], batch.bounds[i + 1])
            res = env.step_arrays(act[rows])
            assert got.observations[rows].tobytes() == res.observations.tobytes(), (step, i)
            assert got.rewards[rows].tobytes() == res.rewards.tobytes(), (step, i)
            assert got.terms[:, rows].tobytes() == res.terms.tobytes(), (step, i)
            assert got.truncated[i] == res.truncated, (step, i)
    # the third copy's episode (40 steps) has ended, the others go on
    assert got.truncated.tolist() == [False, False, True]
    for env, twin in zip(batch.envs, alone, strict=True):
        assert env.episode_metrics() == twin.episode_metrics()
    with pytest.raises(RuntimeError, match="copy 2 has no live episode"):
        batch.step_arrays(np.zeros((batch.rows, 2)))
    again = batch.reset_copy(2, seed=9)
    np.testing.assert_array_equal(again, alone[2].reset_arrays(seed=9))
    assert not batch.step_arrays(np.zeros((batch.rows, 2))).truncated.any()


@pytest.mark.parametrize("actions, message", [
    (np.zeros((23, 2)), r"shape \(24, 2\)"),
    (np.zeros((24, 2), dtype=bool), "real array"),
])
def test_bad_actions_are_refused_before_any_copy_steps(actions, message):
    batch = EnvBatch([parallel_env(**f) for f in FIELDS])
    batch.reset_arrays([0, 1, 2])
    with pytest.raises(ValueError, match=message):
        batch.step_arrays(actions)
    assert [env._world.steps for env in batch.envs] == [0, 0, 0]


def test_a_nan_names_its_copy_and_row_and_nothing_steps():
    batch = EnvBatch([parallel_env(**f) for f in FIELDS])
    batch.reset_arrays([0, 1, 2])
    actions = np.zeros((batch.rows, 2))
    actions[6 + 4, 1] = np.nan  # copy 1, its follower row 4
    with pytest.raises(ValueError, match="copy 1, follower row 4"):
        batch.step_arrays(actions)
    assert [env._world.steps for env in batch.envs] == [0, 0, 0]


def test_the_batch_refuses_a_copy_twice_and_mixed_observation_sizes():
    env = parallel_env(robots=5)
    with pytest.raises(ValueError, match="distinct"):
        EnvBatch([env, env])
    with pytest.raises(ValueError, match="one size"):
        EnvBatch([parallel_env(robots=5), parallel_env(robots=5, neighbours=3)])
    with pytest.raises(TypeError, match="non-empty sequence of BoidsEnv"):
        EnvBatch([])
    with pytest.raises(ValueError, match="one seed"):
        EnvBatch([parallel_env(robots=5)]).reset_arrays([0, 1])


# fused: world frame, leader frame with relative actions (the world frame again with a shorter
# episode); then two that are not (the safety reward terms; sensing noise) and step with
# their own code in the same call
FUSED_FIELDS = [{"robots": 13, "max_cycles": 70},
                {"robots": 19, "max_cycles": 70, "frame": "leader", "relative_actions": True,
                 "startup_time": 0.0, "path": "circle"},
                {"robots": 4, "max_cycles": 50},
                {"robots": 7, "max_cycles": 70, "reward": "safe"},
                {"robots": 7, "max_cycles": 70, "obs_noise": 0.02}]


def test_the_fused_call_gives_each_copy_the_numpy_references_bits(monkeypatch):
    assert kernels.load() is not None
    compiled = kernels.loaded()
    calls = []

    def counted(*args):
        calls.append(len(args[4]))  # the fused copies of the call
        return real(*args)

    real = compiled.batch_after
    monkeypatch.setattr(compiled, "batch_after", counted)
    batch = EnvBatch([parallel_env(**f) for f in FUSED_FIELDS])
    alone = [parallel_env(**f) for f in FUSED_FIELDS]
    seeds = [0, 1, 2, 3, 4]
    obs = batch.reset_arrays(seeds)
    with kernels.reference():
        want = [env.reset_arrays(seed=s) for env, s in zip(alone, seeds, strict=True)]
    assert obs.tobytes() == np.concatenate(want).tobytes()
    assert [fusable(env) for env in batch.envs] == [True, True, True, False, False]
    rng = np.random.default_rng(7)
    for step in range(60):
        act = rng.uniform(-1.6, 1.6, (batch.rows, 2))  # up to twice the speed limit
        got = batch.step_arrays(act)
        for i, env in enumerate(alone):
            rows = slice(batch.bounds[i], batch.bounds[i + 1])
            if not env.agents:
                continue
            with kernels.reference():
                res = env.step_arrays(act[rows])
            assert got.observations[rows].tobytes() == res.observations.tobytes(), (step, i)
            assert got.rewards[rows].tobytes() == res.rewards.tobytes(), (step, i)
            assert got.terms[:, rows].tobytes() == res.terms.tobytes(), (step, i)
            assert got.truncated[i] == res.truncated, (step, i)
        if step == 30:  # reset with sensing noise: the copy leaves the fused call
            batch.reset_copy(0, seed=11, options={"obs_noise": 0.02})
            with kernels.reference():
                alone[0].reset_arrays(seed=11, options={"obs_noise": 0.02})
        if step == 49:  # its episode ended: a reset copy keeps its own counts
            assert got.truncated.tolist() == [False, False, True, False, False]
            batch.reset_copy(2, seed=12)
            with kernels.reference():
                alone[2].reset_arrays(seed=12)
    assert calls == [3] * 31 + [2] * 29
    for env, twin in zip(batch.envs, alone, strict=True):
        assert env.episode_metrics() == twin.episode_metrics()


def test_a_single_env_takes_the_fused_call_and_keeps_the_references_bits(monkeypatch):
    assert kernels.load() is not None
    compiled = kernels.loaded()
    calls = []
    real = compiled.batch_after
    monkeypatch.setattr(compiled, "batch_after",
                        lambda *args: calls.append(1) or real(*args))
    fields = {"robots": 19, "max_cycles": 80, "frame": "leader", "startup_time": 0.0,
              "path": "circle"}
    fast, slow = parallel_env(**fields), parallel_env(**fields)
    fast.reset(seed=5)
    with kernels.reference():
        slow.reset(seed=5)
    rng = np.random.default_rng(3)
    while fast.agents:
        act = {a: rng.uniform(-1.6, 1.6, 2) for a in fast.agents}
        got = fast.step(act)
        with kernels.reference():
            want = slow.step(act)
        for a in want[0]:
            assert got[0][a].tobytes() == want[0][a].tobytes()
        assert got[1:] == want[1:]
    assert len(calls) == 80
    assert fast.episode_metrics() == slow.episode_metrics()


def test_counts_stay_each_envs_own_across_copies_pickles_and_batches():
    """The fused call keeps a copy's violation counts in views of one array: a copied or
    unpickled env, and an env stepped alone, then in a batch, then alone again, still count
    as one env stepped alone does."""
    import copy
    import pickle

    assert kernels.load() is not None
    rng = np.random.default_rng(0)
    env = parallel_env(robots=9, max_cycles=60)
    env.reset_arrays(seed=1)
    for _ in range(20):
        env.step_arrays(rng.uniform(-1, 1, (8, 2)))
    twin, unpickled = copy.copy(env), pickle.loads(pickle.dumps(env))
    with kernels.reference():
        ref = copy.copy(env)
    batch = EnvBatch([env, parallel_env(robots=9, max_cycles=60)])
    batch.envs[1].reset_arrays(seed=2)
    for _ in range(5):
        act = rng.uniform(-1, 1, (16, 2))
        batch.step_arrays(act)
        for other in (twin, unpickled):
            other.step_arrays(act[:8])
        with kernels.reference():
            ref.step_arrays(act[:8])
    for _ in range(3):
        act = rng.uniform(-1, 1, (8, 2))
        for other in (env, twin, unpickled):
            other.step_arrays(act)
        with kernels.reference():
            ref.step_arrays(act)
    want = ref.episode_metrics()
    assert env.episode_metrics() == twin.episode_metrics() == unpickled.episode_metrics() == want
    assert env.episode.rewards.counts is not twin.episode.rewards.counts
