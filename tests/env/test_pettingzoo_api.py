"""PettingZoo's and Gymnasium's own conformance tests."""

import warnings

import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
)
from pettingzoo.utils.conversions import parallel_to_aec

import boids_env
from boids_env import env, parallel_env
from boids_env.single import SingleFollowerEnv


def test_parallel_api():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the test passes an unknown reset option
        parallel_api_test(parallel_env(robots=7, max_cycles=120), num_cycles=200)


def test_parallel_api_runs_to_truncation():
    # max_cycles shorter than num_cycles: every agent must be truncated and removed.
    e = parallel_env(robots=4, max_cycles=30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        parallel_api_test(e, num_cycles=100)
    assert e.agents == []


def test_aec_api():
    api_test(parallel_to_aec(parallel_env(robots=5, max_cycles=60)), num_cycles=100)


def test_seed_tests():
    seed_test(lambda: env(robots=5, max_cycles=40), num_cycles=40)
    parallel_seed_test(lambda: parallel_env(robots=5, max_cycles=40), num_cycles=40)


def test_render_modes():
    render_test(lambda render_mode=None: env(robots=5, max_cycles=20, render_mode=render_mode))


def test_max_cycles():
    max_cycles_test(boids_env)  # the package exposes parallel_env and env


@pytest.mark.parametrize("path", ["square", "circle"])
def test_gymnasium_check_env_single_follower(path):
    check_env(SingleFollowerEnv(path=path, max_cycles=50), skip_render_check=True)
