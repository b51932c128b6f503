"""The versioned module ``boids_leader_v0`` takes any config (env fields by flat name) and passes
PettingZoo's conformance tests with it: a scene with lidar, TurtleBot3s, a person with a crowd.
(``tests/env/test_pettingzoo_api.py`` runs them on the study's case.)"""

import importlib.util
import warnings

import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test

from boids_env import boids_leader_v0

CONFIGS = {
    "lidar_scene": {"robots": 4, "scene": "small_room", "lidar_rays": 8, "max_cycles": 40},
    "turtlebot3": {"robots": 4, "robot": "turtlebot3_burger", "action": "unicycle",
                   "max_cycles": 40},
    "person_crowd": {"robots": 4, "scene": "doorway", "leader": "person", "crowd": 3,
                     "max_cycles": 40},
}


def _config(name):
    if name == "person_crowd" and importlib.util.find_spec("jupedsim") is None:
        pytest.skip("the crowd needs the people extra (jupedsim)")
    return CONFIGS[name]


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_parallel_api_on_a_non_default_config(name):
    config = _config(name)
    env = boids_leader_v0.parallel_env(**config)
    assert env.config == boids_leader_v0.BoidsEnv(**config).config
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # the test passes an unknown reset option
        parallel_api_test(env, num_cycles=60)
    assert env.agents == []  # truncated at max_cycles=40, within the 60 cycles


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_aec_api_on_a_non_default_config(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        api_test(boids_leader_v0.env(**_config(name)), num_cycles=30)


def test_parallel_seed_test_with_a_crowd():
    config = _config("person_crowd")
    parallel_seed_test(lambda: boids_leader_v0.parallel_env(**config), num_cycles=20)
