"""ROS map_server maps: read as specified (thresholds, negate, origin, image rows), refused
when they reach outside their folder or are too large, turned into geometry, and a map
drawn here (not shipped) driven with --map and waypoints."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from boids_env import EnvConfig, parallel_env
from boids_env.eval.episode import run_episode
from boids_env.policies import ReynoldsPolicy
from boids_env.world import maps
from boids_env.world.scenes import DATA


def _map(folder, pixels, **fields):
    """A map YAML + PGM in ``folder`` from ``pixels`` (rows from the top)."""
    Image.fromarray(np.asarray(pixels, dtype=np.uint8)).save(folder / "m.pgm")
    data = {"image": "m.pgm", "resolution": 0.5, "origin": [1.0, -2.0, 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196, **fields}
    (folder / "m.yaml").write_text("\n".join(f"{k}: {json.dumps(v)}" for k, v in data.items()))
    return folder / "m.yaml"


def test_cells_follow_the_thresholds_negate_and_row_order(tmp_path):
    # p = (255 - v) / 255: 0 -> 1.0 occupied, 254 -> 0.004 free, 205 -> 0.196 unknown (not
    # below free_thresh), 100 -> 0.61 unknown, 80 -> 0.686 occupied
    pixels = [[0, 254, 205], [100, 80, 254]]
    cells = maps.read_occupancy(maps.read_map_yaml(_map(tmp_path, pixels)))
    assert cells.tolist() == [[-1, 100, 0], [100, 0, -1]], "row 0 is the image's bottom"
    negated = maps.read_occupancy(maps.read_map_yaml(_map(tmp_path, pixels, negate=1)))
    # negate: p = v / 255: 100 and 80 unknown, 254 and 205 occupied, 0 free
    assert negated.tolist() == [[-1, -1, 100], [0, 100, 100]]


def _pgm(path, pixels, maxval):
    """A binary PGM of ``pixels`` (rows from the top) with its own maxval: 2-byte big-endian
    samples above 255, as the format specifies."""
    pixels = np.asarray(pixels)
    h, w = pixels.shape
    body = pixels.astype(">u2" if maxval > 255 else "u1").tobytes()
    path.write_bytes(f"P5\n{w} {h}\n{maxval}\n".encode() + body)


# the 8-bit map of the test above: 0 occupied, 254 free, 205 unknown (p = 0.196, not below
# free_thresh), 100 unknown (p = 0.61), 80 occupied (p = 0.686)
PIXELS8 = [[0, 254, 205], [100, 80, 254]]
CELLS8 = [[-1, 100, 0], [100, 0, -1]]


@pytest.mark.parametrize("negate", [0, 1])
def test_16_bit_maps_read_as_their_8_bit_copy(tmp_path, negate):
    # issue 39 item 2: every 16-bit level above 255 read as free, so grey walls and unknown
    # space vanished. v * 257 is the same level at 16 bits (255 * 257 = 65535).
    want = maps.read_occupancy(maps.read_map_yaml(_map(tmp_path, PIXELS8, negate=negate)))
    assert want.tolist() == (CELLS8 if not negate else [[-1, -1, 100], [0, 100, 100]])
    wide = np.asarray(PIXELS8) * 257
    _pgm(tmp_path / "m.pgm", wide, 65535)
    cells = maps.read_occupancy(maps.read_map_yaml(tmp_path / "m.yaml"))
    assert cells.tolist() == want.tolist(), "16-bit PGM"
    Image.fromarray(wide.astype(np.uint16)).save(tmp_path / "m.png")
    assert Image.open(tmp_path / "m.png").mode.startswith("I"), "a 16-bit grey PNG"
    yaml = (tmp_path / "m.yaml").read_text().replace('"m.pgm"', '"m.png"')
    (tmp_path / "m.yaml").write_text(yaml)
    cells = maps.read_occupancy(maps.read_map_yaml(tmp_path / "m.yaml"))
    assert cells.tolist() == want.tolist(), "16-bit PNG"


def test_a_pgm_is_read_on_its_own_maxval(tmp_path):
    # maxval 1000: p = (1000 - v) / 1000. 349 -> 0.651 occupied, 350 -> 0.65 unknown (not
    # above occupied_thresh), 804 -> 0.196 unknown (not below free_thresh), 805 -> 0.195 free;
    # 500 -> 0.5 unknown. Pillow stretches the levels to 0..65535 with rounding, which must
    # not move a level across a threshold.
    yaml = _map(tmp_path, [[0]])
    _pgm(tmp_path / "m.pgm", [[349, 350, 804, 805, 500, 1000]], 1000)
    cells = maps.read_occupancy(maps.read_map_yaml(yaml))
    assert cells.tolist() == [[100, -1, -1, 0, -1, 0]]
    _pgm(tmp_path / "m.pgm", [[34, 35, 80, 81, 0, 100]], 100)  # an 8-bit maxval below 255
    cells = maps.read_occupancy(maps.read_map_yaml(yaml))
    assert cells.tolist() == [[100, -1, -1, 0, 100, 0]]


def test_the_origin_places_the_cells_in_the_world(tmp_path):
    scene = maps.load_map(_map(tmp_path, [[0, 254, 254], [254, 254, 254]]))
    # origin (1, -2), 0.5 m cells; the occupied cell is the top-left one: x 1..1.5, y -1.5..-1
    occupied = scene.grid.occupied(np.array([[1.25, -1.25], [1.75, -1.25], [0.5, -1.5]]))
    assert occupied.tolist() == [True, False, True], "off the map counts as occupied"
    assert scene.bounds == (1.0, -2.0, 2.5, -1.0)
    # the contours run along cell edges: the free cells' boundary touches x = 1.5
    assert scene.clearance(np.array([[2.0, -1.5]]))[0] == pytest.approx(0.5, abs=0.006)


@pytest.mark.parametrize("image", ["/etc/hostname", "../m.pgm", "sub/../../m.pgm"])
def test_an_image_outside_the_maps_folder_is_refused(tmp_path, image):
    inner = tmp_path / "inner"
    inner.mkdir()
    _map(tmp_path, [[0]])
    path = _map(inner, [[0]], image=image)
    with pytest.raises(ValueError, match="image"):
        maps.load_map(path)


def test_a_symlink_out_of_the_folder_is_refused(tmp_path):
    inner = tmp_path / "inner"
    inner.mkdir()
    _map(tmp_path, [[0]])
    os.symlink(tmp_path / "m.pgm", inner / "link.pgm")
    with pytest.raises(ValueError, match="outside the map's folder"):
        maps.load_map(_map(inner, [[0]], image="link.pgm"))


def test_an_absolute_image_inside_the_folder_is_read_as_map_saver_writes_it(tmp_path):
    # map_saver -f /abs/path/office writes image: /abs/path/office.pgm
    pixels = [[0, 254, 205], [100, 80, 254]]
    relative = maps.read_occupancy(maps.read_map_yaml(_map(tmp_path, pixels)))
    path = _map(tmp_path, pixels, image=str(tmp_path / "m.pgm"))
    assert maps.read_map_yaml(path)["image"] == (tmp_path / "m.pgm").resolve()
    assert maps.read_occupancy(maps.read_map_yaml(path)).tolist() == relative.tolist()
    # the same map reached through a symlinked folder, its image named through the link
    (tmp_path / "real").mkdir()
    linked = tmp_path / "link"
    os.symlink(tmp_path / "real", linked)
    path = _map(linked, pixels, image=str(linked / "m.pgm"))
    assert maps.read_occupancy(maps.read_map_yaml(path)).tolist() == relative.tolist()


def test_an_absolute_image_outside_the_folder_says_why_and_how_to_fix_it(tmp_path):
    inner = tmp_path / "inner"
    inner.mkdir()
    _map(tmp_path, [[0]])
    with pytest.raises(ValueError, match=r"outside the map's folder .*move the image beside "
                       r"the YAML and make image: relative, e\.g\. image: 'm\.pgm'"):
        maps.load_map(_map(inner, [[0]], image=str(tmp_path / "m.pgm")))
    os.symlink(tmp_path / "m.pgm", inner / "link.pgm")  # absolute, inside, but a link out
    with pytest.raises(ValueError, match="outside the map's folder"):
        maps.load_map(_map(inner, [[0]], image=str(inner / "link.pgm")))


def test_yaml_objects_and_huge_images_are_refused_before_decoding(tmp_path, monkeypatch):
    path = _map(tmp_path, [[0, 0], [0, 0]])
    path.write_text(path.read_text() + "\nx: !!python/object/apply:os.system ['touch pwned']\n")
    with pytest.raises(ValueError, match="not valid YAML"):
        maps.load_map(path)
    assert not (tmp_path / "pwned").exists()
    monkeypatch.setattr(maps, "MAX_CELLS", 3)
    with pytest.raises(ValueError, match="2 × 2 cells; at most 3"):
        maps.load_map(_map(tmp_path, [[0, 0], [0, 0]]))


@pytest.mark.parametrize("fields, match", [
    ({"resolution": 0}, "resolution"), ({"origin": [0, 0]}, "origin"),
    ({"negate": 2}, "negate"), ({"free_thresh": 0.9}, "free_thresh"),
    ({"mode": "raw"}, "mode"), ({"image": "missing.pgm"}, "not found")])
def test_bad_map_fields_are_refused_by_name(tmp_path, fields, match):
    with pytest.raises(ValueError, match=match):
        maps.load_map(_map(tmp_path, [[0]], **fields))


def test_the_shipped_lab_map_is_what_its_drawing_code_draws():
    from lab_map import ORIGIN, RESOLUTION, lab_cells

    fields = maps.read_map_yaml(DATA / "lab.yaml")
    assert (fields["resolution"], fields["origin"]) == (RESOLUTION, ORIGIN)
    assert np.array_equal(maps.read_occupancy(fields), lab_cells())
    assert maps.read_occupancy(fields).shape == (200, 240), "the bench's >= 200 x 200 map"


def _my_room(folder):
    """A 6 m × 4 m room of 5 cm cells, split by a wall at x = 3 m with a 1 m door at
    y = 1.5..2.5 m; origin (0, 0)."""
    cells = np.zeros((80, 120), dtype=np.int8)
    cells[:2], cells[-2:], cells[:, :2], cells[:, -2:] = 100, 100, 100, 100
    cells[:, 59:61] = 100
    cells[30:50, 59:61] = 0
    return maps.write_map(folder / "room.yaml", cells, 0.05)


@pytest.mark.slow
def test_my_own_map_runs_with_waypoints_through_the_door(tmp_path):
    yaml = _my_room(tmp_path)
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "boids_env.train.cli", "run", "--map", str(yaml), "--robots", "7",
         "--start", "1.5,2", "--start-heading", "0", "--waypoints", "4.5,2 4.5,3 4,2 1.5,2",
         "--bag", "--out", str(out)], capture_output=True, text=True, timeout=300, check=False,
        env={**os.environ, "SDL_VIDEODRIVER": "dummy"})
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["wall_fraction"] <= 0.01, "the Reynolds flock avoids the walls by itself"
    assert metrics["min_clearance"] > 0
    from boids_env.rosbag import read_bag
    from boids_env.world.maps import read_map_yaml, read_occupancy

    assert read_bag(out / "episode.bag").metrics()["V_sep"] == metrics["V_sep"]
    want = read_occupancy(read_map_yaml(yaml))
    from rosbags.highlevel import AnyReader

    with AnyReader([out / "episode.bag"]) as reader:
        [(conn, _, raw)] = [m for m in reader.messages() if m[0].topic == "/map"]
        grid = reader.deserialize(raw, conn.msgtype)
    assert (grid.info.width, grid.info.height) == (120, 80)
    assert np.array_equal(np.asarray(grid.data).reshape(80, 120), want)


def test_a_path_through_a_wall_is_refused_naming_the_leg(tmp_path):
    yaml = _my_room(tmp_path)
    with pytest.raises(ValueError, match=r"leg 2 from \(4\.50, 2\.00\) to \(4\.50, 0\.50\)"
                       r"|leg 3 from \(4\.50, 0\.50\) to \(1\.50, 0\.50\) crosses"):
        EnvConfig.from_kwargs(map=str(yaml), robots=7, start=(1.5, 2.0), start_heading=0.0,
                              path="waypoints", waypoints=((4.5, 2.0), (4.5, 0.5), (1.5, 0.5)))
    with pytest.raises(ValueError, match=r"leg 3 from \(4\.50, 0\.50\) to \(1\.50, 0\.50\) "
                       r"crosses or passes closer than robot_radius .* to map contour"):
        EnvConfig.from_kwargs(map=str(yaml), robots=7, start=(1.5, 2.0), start_heading=0.0,
                              path="waypoints", waypoints=((4.5, 2.0), (4.5, 0.5), (1.5, 0.5)))


def test_a_start_inside_a_wall_is_refused_naming_the_robot(tmp_path):
    yaml = _my_room(tmp_path)
    with pytest.raises(ValueError, match=r"the start does not fit scene .*: follower \d+ would "
                       r"start at .* from (map contour|an occupied map cell)"):
        EnvConfig.from_kwargs(map=str(yaml), robots=13, start=(3.6, 0.8), start_heading=0.0,
                              path="waypoints", waypoints=((5.0, 0.8),))


def test_the_lab_scene_runs_clear_of_its_walls():
    result = run_episode(parallel_env(scene="lab"), ReynoldsPolicy(), seed=1)
    assert result.metrics["wall_fraction"] == 0.0
    assert result.metrics["min_clearance"] > 0.1


def test_waypoints_in_python_set_the_waypoints_path_as_the_cli_does(tmp_path):
    """``parallel_env(map=..., waypoints=[...])`` drives the waypoints (as ``boids run
    --waypoints`` does), not the map's default square (which here runs into the wall)."""
    yaml = _my_room(tmp_path)
    env = parallel_env(map=str(yaml), robots=4, start=(1.5, 2.0), start_heading=0.0,
                       waypoints=[(2.5, 2.0), (2.5, 3.0)])
    assert env.config.scenario.path == "waypoints"
    assert env.config.scenario.waypoints == ((2.5, 2.0), (2.5, 3.0))
    env.reset(seed=0)
    for _ in range(30):  # past the 2 s start-up
        env.step({a: np.zeros(2) for a in env.agents})
    x, y = env.snapshot().positions[0]
    assert 1.5 < x < 2.6 and y == pytest.approx(2.0, abs=1e-6), "east, to the first waypoint"
    assert EnvConfig.from_kwargs(waypoints=[(1.0, 0.0)]).scenario.path == "waypoints"
    # a path given stays; no waypoints (the default) leave the study's square
    assert EnvConfig.from_kwargs(path="circle", waypoints=[(1.0, 0.0)]).scenario.path == "circle"
    assert EnvConfig.from_kwargs(waypoints=()) == EnvConfig()
    assert EnvConfig().replace(robots=13) == EnvConfig()
