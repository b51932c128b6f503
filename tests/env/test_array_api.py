"""The array API (reset_arrays / step_arrays) is the dict API without dicts: bit-identical."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.environment import REWARD_INFO_KEYS


@pytest.mark.parametrize("fields", [
    {"robots": 7, "leader_speed": 0.6},
    {"robots": 13, "reward": "safe", "frame": "leader", "obs_noise": 0.02, "path": "circle"},
])
def test_array_api_is_bit_identical_to_the_dict_api(fields):
    by_dict, by_array = parallel_env(**fields), parallel_env(**fields)
    obs_d, _ = by_dict.reset(seed=3)
    obs_a = by_array.reset_arrays(seed=3)
    agents = by_dict.possible_agents
    np.testing.assert_array_equal(obs_a, np.stack([obs_d[a] for a in agents]))
    rng = np.random.default_rng(0)
    step = 0
    while by_dict.agents:
        act = rng.uniform(-0.7, 0.7, (len(agents), 2))
        obs_d, rew_d, term_d, trunc_d, info_d = by_dict.step(dict(zip(agents, act,
                                                                      strict=True)))
        res = by_array.step_arrays(act)
        np.testing.assert_array_equal(res.observations, np.stack([obs_d[a] for a in agents]),
                                      err_msg=f"step {step}")
        assert res.rewards.tolist() == [rew_d[a] for a in agents], f"step {step}"
        for row, key in enumerate(REWARD_INFO_KEYS):
            assert res.terms[row].tolist() == [info_d[a][key] for a in agents], (step, key)
        assert all(list(info_d[a]) == list(REWARD_INFO_KEYS) for a in agents)
        assert all(type(v) is float for a in agents for v in info_d[a].values())
        assert len({id(info_d[a]) for a in agents}) == len(agents)  # a dict each
        assert res.truncated == trunc_d[agents[0]] and not any(term_d.values())
        step += 1
    assert res.truncated and not by_array.agents
    assert by_array.episode_metrics() == by_dict.episode_metrics()
    with pytest.raises(RuntimeError, match="episode has ended"):
        by_array.step_arrays(np.zeros((len(agents), 2)))


@pytest.mark.parametrize("actions, message", [
    (np.zeros((5, 2)), r"shape \(6, 2\)"),
    (np.zeros((6, 3)), r"shape \(6, 2\)"),
    (np.full((6, 2), np.nan), "finite"),
    (np.zeros((6, 2), dtype=bool), "real array"),
    ([["a", "b"]] * 6, "real array"),
])
def test_array_api_bad_actions_are_clear_errors_and_change_nothing(actions, message):
    env, twin = parallel_env(robots=7), parallel_env(robots=7)
    env.reset_arrays(seed=0)
    twin.reset_arrays(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step_arrays(actions)
    good = np.full((6, 2), 0.1)
    np.testing.assert_array_equal(env.step_arrays(good).observations,
                                  twin.step_arrays(good).observations)


def test_step_arrays_before_reset():
    with pytest.raises(RuntimeError, match="reset"):
        parallel_env(robots=3).step_arrays(np.zeros((2, 2)))
