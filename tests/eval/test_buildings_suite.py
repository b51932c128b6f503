"""The ``buildings`` suite: held-out floor plans, built-in maps, a leader standing in a door."""

import numpy as np
import pytest

from boids_env.config import EnvConfig
from boids_env.environment import BoidsEnv
from boids_env.eval.suites import BUILDING_SEEDS, BUILDINGS, DOORWAY_STOPS, SUITES
from boids_env.policies.reynolds_params import reynolds_params
from boids_env.world.floorplans import doorways


def test_the_suite_enumerates_its_held_out_plans_and_stresses():
    assert SUITES["buildings"] is BUILDINGS
    groups = BUILDINGS.groups
    assert BUILDING_SEEDS == tuple(range(1000, 1020))
    assert [c.env["scene"] for c in groups["held_out"]] == [f"floorplan:{s}"
                                                           for s in range(1000, 1020)]
    assert {c.env["scene"] for c in groups["built_in"]} >= {"lab"}
    assert len(groups["doorway_stop"]) == 3 and len(groups["noise"]) == 6
    # no tuning plan (0-19) is an evaluation plan
    used = {int(c.env["scene"].split(":")[1]) for c in BUILDINGS.cases
            if c.env["scene"].startswith("floorplan")}
    assert used <= set(BUILDING_SEEDS) and not used & set(range(20))
    assert BUILDINGS.seeds == (0, 1, 2, 3, 4)
    reynolds_params("route")


@pytest.mark.parametrize("case", [c for c in BUILDINGS.cases if c.group == "doorway_stop"],
                         ids=lambda c: c.name)
def test_the_leader_stands_in_a_doorway(case):
    config = EnvConfig.from_kwargs(**{**case.env, "robots": 2})
    env = BoidsEnv(config)
    env.reset(seed=0)
    (when, length), = case.env["leader_pauses"]
    steps = round((config.scenario.startup_time + when + length / 2) / config.world.dt)
    for _ in range(steps):
        env.step({a: np.zeros(2) for a in env.agents})
    leader = env._require_world().snapshot().positions[0]
    gap = np.hypot(*(doorways(config.scene) - leader).T).min()
    assert gap < 0.25, (case.name, leader, gap)
    assert DOORWAY_STOPS[int(case.env["scene"].split(":")[1])] == when


def test_a_floor_plan_reads_no_file_so_a_suite_of_plans_runs():
    # input_files once took floorplan@1:1004 for a path, and boids eval --suite buildings
    # stopped at "No such file or directory"
    from boids_env.eval.runner import input_digests

    assert EnvConfig().replace(scene="floorplan:1004").input_files() == ()
    assert input_digests(BUILDINGS) == {}
    assert input_digests(SUITES["robots_buildings"]) == {}


def test_the_robots_buildings_suite_holds_turtlebots_and_gritsbots_on_held_out_plans():
    suite = SUITES["robots_buildings"]
    assert suite.seeds == (0, 1, 2, 3, 4)
    robots = {c.env["robot"] for c in suite.cases}
    assert robots == {"turtlebot3_burger", "gritsbot"}
    for robot in robots:
        scenes = sorted(c.env.get("scene", "arena") for c in suite.cases
                        if c.env["robot"] == robot)
        assert scenes == ["arena", "floorplan:1004", "floorplan:1011", "floorplan:1016"]
    plans = {int(c.env["scene"].split(":")[1]) for c in suite.cases if "scene" in c.env}
    assert plans <= set(BUILDING_SEEDS) and not plans & {3, 5, 8}  # tuned on 3, 5, 8
    for case in suite.cases:  # every case builds (the robots' start fits the plan)
        BoidsEnv(EnvConfig.from_kwargs(**case.env)).reset(seed=0)


def test_the_crowd_buildings_suite_has_eight_pedestrians_in_every_case():
    suite = SUITES["crowd_buildings"]
    assert [c.env["crowd"] for c in suite.cases] == [8, 8, 8]
    assert [c.env.get("scene", "arena") for c in suite.cases] == [
        "arena", "floorplan:1004", "floorplan:1011"]
    assert input_digests_of(suite) == {}


def input_digests_of(suite):
    from boids_env.eval.runner import input_digests

    return input_digests(suite)
