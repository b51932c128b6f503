"""Third-party clients run on the env unchanged: SuperSuit, TorchRL, PettingZoo's module tests."""

import numpy as np
import supersuit
from pettingzoo.test import max_cycles_test
from torchrl.envs.libs.pettingzoo import PettingZooWrapper

from boids_env import boids_leader_v0, parallel_env
from boids_env.environment import REWARD_INFO_KEYS


def test_np_random_is_the_seeded_generator():
    env = parallel_env(robots=4)
    env.reset(seed=5)
    first = env.np_random.uniform()
    env.reset(seed=5)
    assert env.np_random.uniform() == first


def test_supersuit_frame_skip_repeats_actions_and_sums_rewards():
    skip = 3
    wrapped = supersuit.frame_skip_v0(parallel_env(robots=5, max_cycles=30, init_jitter=0.0), skip)
    plain = parallel_env(robots=5, max_cycles=30, init_jitter=0.0)
    wrapped.reset(seed=1)
    plain.reset(seed=1)
    act = {a: np.array([0.0, 0.4]) for a in plain.possible_agents}
    obs_w, rew_w, *_ = wrapped.step(act)
    total = dict.fromkeys(plain.possible_agents, 0.0)
    for _ in range(skip):
        obs_p, rew_p, *_ = plain.step(act)
        for a in total:
            total[a] += rew_p[a]
    for a in plain.possible_agents:
        np.testing.assert_array_equal(obs_w[a], obs_p[a], err_msg=a)
        assert rew_w[a] == total[a], (a, rew_w[a], total[a])
    assert plain.snapshot().time == wrapped.unwrapped.snapshot().time == 3 * 0.1


def test_torchrl_rollout_carries_the_reward_terms():
    env = PettingZooWrapper(parallel_env(robots=4, max_cycles=25, leader_speed=0.6),
                            return_state=False, use_mask=False)
    td = env.rollout(25)
    group = td["next", "follower"]
    info = group["info"]
    assert set(REWARD_INFO_KEYS) <= set(info.keys()), list(info.keys())
    # the per-term rewards add up to the reward of every follower at every step
    terms = sum(info[k] for k in REWARD_INFO_KEYS)
    np.testing.assert_allclose(terms.numpy(), group["reward"][..., 0].numpy(), atol=1e-7)
    # during the 2 s start-up the followers hold still beside a leader at rest: some term fires
    assert (terms != 0).any()


def test_pettingzoo_max_cycles_test_on_the_versioned_module():
    max_cycles_test(boids_leader_v0)
    assert callable(boids_leader_v0.raw_env) and callable(boids_leader_v0.env)


def test_environment_module_is_not_shadowed_by_the_aec_factory():
    import boids_env.environment as module

    assert module.__name__ == "boids_env.environment"
    assert module.BoidsEnv is boids_leader_v0.BoidsEnv
