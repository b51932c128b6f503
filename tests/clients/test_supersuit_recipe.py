"""SuperSuit + SB3: ``make_vec_env`` gives every copy its own episode, a seed repeats the run,
and ``PPO(seed=...)`` works (SuperSuit's own SB3 wrapper has no working ``seed``)."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.integrations.supersuit import make_vec_env

pytest.importorskip("stable_baselines3")

FIELDS = {"robots": 3, "max_cycles": 12, "leader_speed": 0.6}
FOLLOWERS = FIELDS["robots"] - 1


def _first_obs(seed):
    env = parallel_env(**FIELDS)
    obs, _ = env.reset(seed=seed)
    return np.stack([obs[a] for a in env.possible_agents])


def _run(vec, steps=30):
    """Observations and rewards over ``steps`` (past the end of the 12-step episodes, so each
    copy's automatic reset is in it), with fixed actions."""
    out = [vec.reset()]
    actions = np.tile([[0.3, -0.2]], (vec.num_envs, 1))
    for _ in range(steps):
        obs, rewards, dones, _ = vec.step(actions)
        out += [obs.ravel(), rewards, dones]
    return np.concatenate([np.ravel(x).astype(np.float64) for x in out])


def test_copy_i_starts_the_episode_of_seed_plus_i():
    obs = make_vec_env(3, seed=5, **FIELDS).reset()
    assert obs.shape[0] == 3 * FOLLOWERS
    for i in range(3):
        np.testing.assert_array_equal(obs[FOLLOWERS * i:FOLLOWERS * (i + 1)], _first_obs(5 + i))
    assert not np.array_equal(obs[:FOLLOWERS], obs[FOLLOWERS:2 * FOLLOWERS])


def test_unseeded_copies_run_different_episodes():
    obs = make_vec_env(3, **FIELDS).reset()
    blocks = [obs[FOLLOWERS * i:FOLLOWERS * (i + 1)] for i in range(3)]
    assert not np.array_equal(blocks[0], blocks[1])
    assert not np.array_equal(blocks[1], blocks[2])


def test_a_seed_repeats_the_run_and_seed_then_reset_reseeds():
    a = _run(make_vec_env(2, seed=9, **FIELDS))
    b = _run(make_vec_env(2, seed=9, **FIELDS))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, _run(make_vec_env(2, seed=10, **FIELDS)))
    vec = make_vec_env(2, **FIELDS)
    assert vec.seed(9) == [9, 9, 10, 10]  # per sub-env: its copy's seed
    np.testing.assert_array_equal(_run(vec), a)


def test_ppo_with_a_seed_learns_and_repeats():
    from stable_baselines3 import PPO

    def learn():
        model = PPO("MlpPolicy", make_vec_env(2, **FIELDS), seed=3, n_steps=32, batch_size=64,
                    n_epochs=2, device="cpu")
        model.learn(256)
        assert model.num_timesteps >= 256
        return np.concatenate([p.detach().numpy().ravel() for p in model.policy.parameters()])

    first = learn()
    np.testing.assert_array_equal(first, learn())


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"n_copies": 0}, "n_copies must be an integer >= 1, got 0"),
    ({"n_copies": True}, "n_copies must be an integer >= 1, got True"),
    ({"n_copies": 2, "seed": -1}, "seed must be a non-negative integer or None, got -1"),
    ({"n_copies": 2, "seed": 1.5}, "seed must be a non-negative integer or None, got 1.5"),
])
def test_bad_arguments_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_vec_env(**kwargs, **FIELDS)
