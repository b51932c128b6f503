"""The static scene's queries on a hand-made scene: a 6 m × 4 m box, a pillar, a wall
segment and a block; and the shapes-file reader."""

import json
import math

import numpy as np
import pytest

from boids_env.world.scene import Scene
from boids_env.world.shapes import load_shapes


@pytest.fixture(scope="module")
def scene():
    return Scene("test", box=(-3.0, -2.0, 3.0, 2.0),
                 a=np.array([[1.0, 0.0], [-1.0, -1.0]]), b=np.array([[1.0, 0.0], [-1.0, 1.0]]),
                 radius=np.array([0.2, 0.05]),
                 polygons=(np.array([[2.0, 1.0], [2.5, 1.0], [2.5, 1.5], [2.0, 1.5]]),),
                 names=("the pillar", "the wall", "the block"))


def test_clearance_is_the_distance_to_the_nearest_surface(scene):
    pts = np.array([[0.0, 0.0], [1.5, 0.0], [-2.5, 1.9], [2.25, 1.25], [0.0, 1.5]])
    # (0,0): wall face at x=-0.95 -> 0.95, pillar surface at 0.8 -> 0.8
    # (1.5, 0): pillar surface 0.3; (-2.5, 1.9): north wall 0.1
    # (2.25, 1.25): inside the block -> 0; (0, 1.5): north wall 0.5, wall end (-1,1)+0.05
    want = [0.8, 0.3, 0.1, 0.0, 0.5]
    np.testing.assert_allclose(scene.clearance(pts), want, atol=1e-12)
    assert scene.within(pts, 0.2).tolist() == [False, False, True, True, False]
    assert scene.within(np.array([[0.0, 1.85]]), 0.1, 0.05).tolist() == [True]


def test_nearest_points_fill_slots_by_direction(scene):
    offsets, valid = scene.nearest_points(np.array([[0.0, 1.5], [-2.0, 0.0]]), 3, 1.2)
    # (0, 1.5): north wall 0.5 up, then the wall capsule's end towards (-1, 1) (more than
    # 45° away from up); the pillar is 1.3 m away (beyond reach)
    np.testing.assert_allclose(offsets[0, 0], [0.0, 0.5], atol=1e-12)
    end = np.array([-1.0, 1.0]) - np.array([0.0, 1.5])
    np.testing.assert_allclose(offsets[0, 1], end / np.linalg.norm(end) * (
        np.linalg.norm(end) - 0.05), atol=1e-12)
    assert valid[0].tolist() == [True, True, False]
    # (-2, 0): west wall 1.0 left and the wall capsule's face 0.95 right, both within reach
    np.testing.assert_allclose(offsets[1, 0], [0.95, 0.0], atol=1e-12)
    np.testing.assert_allclose(offsets[1, 1], [-1.0, 0.0], atol=1e-12)


def test_rays_stop_at_walls_pillars_and_blocks(scene):
    origins = np.array([[0.0, 0.0], [2.25, 0.0]])
    dirs = np.array([[[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]],
                     [[0.0, 1.0], [0.0, -1.0], [1.0, 0.0]]])
    got = scene.raycast(origins, dirs, 10.0)
    np.testing.assert_allclose(got, [[0.8, 2.0, 0.95], [1.0, 2.0, 0.75]], atol=1e-12)
    assert scene.raycast(origins[:1], dirs[:1, :1], 0.5)[0, 0] == 0.5, "capped at the range"


def test_blocked_legs_name_the_obstacle(scene):
    hit, which = scene.blocked(np.array([[0.0, -1.5], [-2.0, -1.5], [0.0, 1.2]]),
                               np.array([[1.8, 0.75], [-2.0, 1.5], [2.9, 1.2]]), 0.036)
    assert hit.tolist() == [True, False, True]
    assert [scene.names[k] for k in which[hit]] == ["the pillar", "the block"]
    assert scene.nearest_name(np.array([0.0, 1.9])) == "the north wall"


def test_a_shapes_file_reads_into_the_same_scene(tmp_path):
    toml = tmp_path / "room.toml"
    toml.write_text("""
box = [-3.0, -2.0, 3.0, 2.0]
[[circle]]
center = [1.0, 0.0]
radius = 0.2
[[segment]]
a = [-1.0, -1.0]
b = [-1.0, 1.0]
radius = 0.05
[[polygon]]
points = [[2.0, 1.0], [2.0, 1.5], [2.5, 1.5], [2.5, 1.0]]
[defaults]
path = "waypoints"
waypoints = [[2.0, -1.0], [-2.0, -1.5]]
start = [-2.0, 1.0]
""")
    read = load_shapes(toml)
    pts = np.array([[0.0, 0.0], [1.5, 0.0], [2.25, 1.25]])
    np.testing.assert_allclose(read.clearance(pts), [0.8, 0.3, 0.0], atol=1e-12)
    assert read.defaults["waypoints"] == ((2.0, -1.0), (-2.0, -1.5))
    assert read.defaults["start"] == (-2.0, 1.0)
    as_json = tmp_path / "room.json"
    as_json.write_text(json.dumps({"box": [-3, -2, 3, 2], "circle": [{"center": [1, 0],
                                                                      "radius": 0.2}]}))
    assert load_shapes(as_json).clearance(np.array([[1.5, 0.0]]))[0] == pytest.approx(0.3)


@pytest.mark.parametrize("text, match", [
    ("box = [0, 0, -1, 1]", "box must be"),
    ("[[circle]]\ncenter = [0, 0]\nradius = -1", "circle 0 radius"),
    ("[[circle]]\ncenter = [0, 'x']\nradius = 1", "circle 0 center"),
    ("[[polygon]]\npoints = [[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]]", "convex"),
    ("walls = 3", "unknown key"),
    ("box = [-1, -1, 1, 1]\n[defaults]\nrobots = 7", "defaults must be"),
    ("", "no box and no shapes"),
])
def test_bad_shapes_files_are_refused_by_name(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_shapes(path)


def test_a_scene_survives_pickling_with_its_queries(scene):
    import pickle

    scene.clearance(np.zeros((1, 2)))
    scene.raycast(np.zeros((1, 2)), np.array([[[1.0, 0.0]]]), 3.0)  # fills the caches
    back = pickle.loads(pickle.dumps(scene))
    assert back._cache == {}
    pts = np.random.default_rng(0).uniform(-2.9, 2.9, (50, 2)) * [1, 0.66]
    np.testing.assert_array_equal(back.clearance(pts), scene.clearance(pts))
    dirs = np.broadcast_to([math.sqrt(0.5), math.sqrt(0.5)], (50, 1, 2))
    np.testing.assert_array_equal(back.raycast(pts, dirs, 3.0), scene.raycast(pts, dirs, 3.0))
