"""Generated floor plans: seeded, within the stated sizes, with a leader route clear of walls."""

import itertools

import numpy as np
import pytest

from boids_env.config import EnvConfig
from boids_env.world import floorplans
from boids_env.world.floorplans import CORRIDOR, DOOR, WALL, doorways, floorplan
from boids_env.world.scenes import load_scene, scene_key

SEEDS = (0, 3)


def _arrays(scene):
    return (scene.box, scene.a.tolist(), scene.b.tolist(), scene.radius.tolist(),
            [p.tolist() for p in scene.polygons], scene.names, scene.defaults)


def test_the_same_seed_gives_the_same_plan_and_other_seeds_differ():
    one = floorplan(3)
    cached = load_scene("floorplan:3")
    assert _arrays(floorplan(3)) == _arrays(one)  # built again, not a cached object
    assert _arrays(cached) == _arrays(one)
    assert str(_arrays(floorplan(4))) != str(_arrays(one))


@pytest.mark.parametrize("seed", SEEDS)
def test_corridor_and_door_widths_are_in_range(seed):
    scene = load_scene(f"floorplan:{seed}")
    ys = sorted({round(float(y), 9) for y, name in zip(scene.a[:, 1], scene.names, strict=False)
                 if "corridor wall" in name})
    assert len(ys) == 2, ys
    corridor = ys[1] - ys[0] - 2 * WALL  # between the walls' faces
    assert CORRIDOR[0] <= corridor <= CORRIDOR[1], corridor
    doors = doorways(scene)
    assert len(doors) >= 4
    for side in ("north corridor wall", "south corridor wall"):
        k = [i for i, n in enumerate(scene.names[:len(scene.radius)]) if n == side]
        gaps = [float(np.linalg.norm(scene.a[r] - scene.b[left])) - 2 * WALL
                for left, r in itertools.pairwise(k)]
        assert all(DOOR[0] <= g <= DOOR[1] for g in gaps), gaps


@pytest.mark.parametrize("seed", SEEDS)
def test_the_leader_route_is_clear_and_the_start_fits(seed):
    config = EnvConfig.from_kwargs(scene=f"floorplan:{seed}", robots=19)  # checks the start
    scene = config.scene
    d = scene.defaults
    path = np.array([d["start"], *d["waypoints"]])
    blocked, which = scene.blocked(path[:-1], path[1:], config.world.robot_radius + 0.2)
    assert not blocked.any(), [scene.names[w] for w in which[blocked]]
    # it goes through doors: the route crosses the corridor walls' lines
    assert (np.diff(np.sign(path[:, 1] - doorways(scene)[0, 1])) != 0).any()


def test_names_carry_the_generator_version():
    assert scene_key("floorplan:3") == f"floorplan@{floorplans.VERSION}:3"
    assert EnvConfig.from_kwargs(scene="floorplan:3").world.scene == "floorplan@1:3"
    assert load_scene("floorplan@1:3").defaults == load_scene("floorplan:3").defaults
    with pytest.raises(ValueError, match="generator version 99"):
        load_scene("floorplan@99:3")
    for bad in ("floorplan:", "floorplan:-1", "floorplan:1.5", f"floorplan:{2**32}"):
        with pytest.raises(ValueError, match="floorplan:SEED"):
            load_scene(bad)
    with pytest.raises(ValueError, match="seed"):
        floorplan(-1)
