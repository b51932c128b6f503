"""Many worlds per process (boids_env.batch.EnvBatch): each copy's results are the bits it
gives stepped alone, and bad input is refused before any copy steps."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.batch import EnvBatch

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
