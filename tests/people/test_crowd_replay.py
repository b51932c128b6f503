"""Replayed crowds: ETH/UCY and TrajNet++ files (crowd_file) read as untrusted input and
their pedestrians walked on their recorded tracks, interpolated to the env's dt."""

import json
import pickle

import numpy as np
import pytest

from boids_env import EnvConfig, parallel_env
from boids_env.eval.episode import run_episode
from boids_env.policies import ReynoldsPolicy
from boids_env.world import crowd_files
from boids_env.world.crowd_files import read_crowd
from boids_env.world.crowd_replay import OFF_STAGE, OFF_STAGE_SPACING

# pedestrian 1: frames 0, 10, 20 (t = 0, 0.4, 0.8 s); pedestrian 2: frames 10, 20, 30
ETH = """# frame ped x y
0\t1\t0.0\t0.0
10  1  0.4  0.0
10  2  1.0  1.0
20  1  0.8  0.2
20  2  1.0  1.4
30  2  1.0  1.8
"""
ROWS = [(0, 1, 0.0, 0.0), (10, 1, 0.4, 0.0), (10, 2, 1.0, 1.0), (20, 1, 0.8, 0.2),
        (20, 2, 1.0, 1.4), (30, 2, 1.0, 1.8)]
TRAJNET = "\n".join(
    [json.dumps({"scene": {"id": 0, "p": 1, "s": 0, "e": 20, "fps": 2.5, "tag": 1}})]
    + [json.dumps({"track": {"f": f, "p": p, "x": x, "y": y}}) for f, p, x, y in ROWS]) + "\n"
PLACE = {"crowd_offset": (2.0, 1.0), "start": (-3.0, -3.0), "path_size": 1.0,
         "robots": 3}
"""The crowd's origin at (2, 1) m, the robots far from it (no contact in the tests that read
positions)."""


def write(tmp_path, text, name="crowd.txt"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(("text", "name"), [(ETH, "eth.txt"), (TRAJNET, "crowd.ndjson")])
def test_both_formats_read_the_same_tracks(tmp_path, text, name):
    tracks = read_crowd(write(tmp_path, text, name))
    assert tracks.ids.tolist() == [1, 2]
    assert tracks.start.tolist() == [0, 3, 6]
    assert np.allclose(tracks.times, [0.0, 0.4, 0.8, 0.4, 0.8, 1.2])  # frame / (10 · 2.5)
    assert tracks.points.tolist() == [[0.0, 0.0], [0.4, 0.0], [0.8, 0.2],
                                      [1.0, 1.0], [1.0, 1.4], [1.0, 1.8]]
    assert np.allclose(tracks.max_speeds(), [np.hypot(0.4, 0.2) / 0.4, 1.0])


def test_frame_step_and_rate_set_the_clock(tmp_path):
    tracks = read_crowd(write(tmp_path, ETH), frame_step=1, rate=25.0)  # every frame, 25 fps
    assert np.allclose(tracks.times, [0.0, 0.4, 0.8, 0.4, 0.8, 1.2])
    tracks = read_crowd(write(tmp_path, ETH), frame_step=5, rate=2.5)  # 2 s per 10 frames
    assert np.allclose(tracks.times, [0.0, 0.8, 1.6, 0.8, 1.6, 2.4])


def run_positions(path, steps, **fields):
    env = parallel_env(crowd_file=path, **{**PLACE, **fields})
    env.reset(seed=0)
    seen = [env.unwrapped._world.pedestrian_positions.copy()]
    for _ in range(steps):
        env.step({a: np.zeros(2) for a in env.agents})
        seen.append(env.unwrapped._world.pedestrian_positions.copy())
    return env, seen


@pytest.mark.parametrize(("text", "name"), [(ETH, "eth.txt"), (TRAJNET, "crowd.ndjson")])
def test_pedestrians_walk_their_tracks_interpolated_to_dt(tmp_path, text, name):
    _, seen = run_positions(write(tmp_path, text, name), 16)
    off1, off2 = list(OFF_STAGE), [OFF_STAGE[0] + OFF_STAGE_SPACING, OFF_STAGE[1]]
    # by hand, the crowd's origin at (2, 1), dt = 0.1 s
    want = {0: [[2.0, 1.0], off2], 2: [[2.2, 1.0], off2],
            4: [[2.4, 1.0], [3.0, 2.0]],  # pedestrian 2 comes on stage at 0.4 s
            6: [[2.6, 1.1], [3.0, 2.2]],  # halfway from (0.4, 0) to (0.8, 0.2)
            8: [[2.8, 1.2], [3.0, 2.4]],  # pedestrian 1's last sample
            9: [off1, [3.0, 2.5]], 12: [off1, [3.0, 2.8]], 13: [off1, off2],
            16: [off1, off2]}  # waiting off stage, apart: still
    for step, expected in want.items():
        assert np.allclose(seen[step], expected, atol=1e-6), (step, seen[step].tolist())


def test_placement_turns_scales_and_shifts_the_clock(tmp_path):
    # 90° then × 2 then (2, 1): file (x, y) -> (2 - 2y, 1 + 2x); the file's 0.4 s at t = 0
    _, seen = run_positions(write(tmp_path, ETH), 3, crowd_rotation=90.0, crowd_scale=2.0,
                            crowd_time=0.4)
    assert np.allclose(seen[0], [[2.0, 1.8], [0.0, 3.0]], atol=1e-6), seen[0].tolist()
    assert np.allclose(seen[2], [[1.8, 2.2], [-0.4, 3.0]], atol=1e-6), seen[2].tolist()


def test_robots_see_them_and_the_metrics_count_their_contacts(tmp_path):
    # a pedestrian walks along the followers' row (y = -0.5) at 1 m/s, the robots held still
    text = "".join(f"{10 * k} 7 {-2.0 + 0.4 * k} -0.5\n" for k in range(11))
    env = parallel_env(crowd_file=write(tmp_path, text), robots=3, max_cycles=40,
                       startup_time=60.0, pedestrian_slots=2)
    result = run_episode(env, ReynoldsPolicy(), seed=0)
    assert result.metrics["pedestrian_contacts"] >= 1, result.metrics
    assert result.metrics["min_pedestrian_distance"] < 0.3, result.metrics
    env.reset(seed=0)
    for _ in range(5):  # the pedestrian at (-1.5, -0.5) m: in the first follower's slots
        obs, *_ = env.step({a: np.zeros(2) for a in env.agents})
    slots = env.unwrapped.layout.pedestrian_slots(obs["follower_1"])
    assert slots[0, 4] == 1.0 and slots[1, 4] == 0.0, slots.tolist()


def test_a_replayed_crowd_is_deterministic_and_pickles(tmp_path):
    path = write(tmp_path, ETH)
    env_a, seen_a = run_positions(path, 5)
    copy = pickle.loads(pickle.dumps(env_a.unwrapped))
    _, seen_b = run_positions(path, 5)
    assert all(np.array_equal(a, b) for a, b in zip(seen_a, seen_b, strict=True))
    for env in (env_a.unwrapped, copy):  # on through pedestrian 2's arrival and 1's exit
        for _ in range(6):
            env.step({a: np.zeros(2) for a in env.agents})
    assert np.array_equal(env_a.unwrapped._world.pedestrian_positions,
                          copy._world.pedestrian_positions)
    assert np.array_equal(env_a.unwrapped._world.positions, copy._world.positions)


def test_the_default_has_no_replayed_crowd():
    cfg = EnvConfig()
    assert cfg.scenario.crowd_file is None and cfg.pedestrian_slots == 0


@pytest.mark.parametrize(("text", "message"), [
    ("0 1 0 0\n10 1 0\n", r"line 2: expected 4 values 'frame ped x y'"),
    ("0 1 0 0\n10 one 0 0\n", r"line 2: ped must be a number"),
    ("0 1 0 0\n10.5 1 0 0\n", r"line 2: frame must be a whole number in \[0, 1000000000\]"),
    ("0 1 0 0\n-10 1 0 0\n", r"line 2: frame must be a whole number in \[0, "),
    ("0 1 0 0\n10 1 nan 0\n", r"line 2: x must be finite and within ±1000 m"),
    ("0 1 0 0\n10 1 0 5000\n", r"line 2: y must be finite and within ±1000 m"),
    ("0 1 0 0\n10 1 1 0\n0 1 2 0\n", r"line 3: pedestrian 1 is in frame 0 twice \(also line 1\)"),
    ("# nothing\n\n", r"no samples"),
    ('{"track": {"f": 0, "p": 1, "x": 0, "y": 0}}\n{"track": {"f": 10, "p": 1, "x": 0}}\n',
     r"line 2: a track must be an object with keys f, p, x, y"),
    ('{"track": {"f": 0, "p": 1, "x": 0, "y": 0}}\n{"track": {"f": 1, "p": 1, "x": "0", '
     '"y": 0}}\n', r"line 2: x must be a number"),
    ('{"track": {"f": 0, "p": true, "x": 0, "y": 0}}\n', r"line 1: ped \(p\) must be a number"),
    ('{"track": {"f": 0, "p": 1, "x": 0, "y": 0}}\n{"track": \n', r"line 2: not valid JSON"),
    ('{"scene": {"fps": 25}}\n', r"line 1: the scene's fps must be crowd_rate \(2.5"),
    ('{"walk": 1}\n', r"line 1: expected one object"),
    ('{"track": ' + "[" * 40 + "]" * 40 + "}\n", r"line 1: nested more than 32 levels"),
])
def test_bad_crowd_files_are_refused_naming_file_and_line(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(ValueError, match=message) as caught:
        EnvConfig.from_kwargs(crowd_file=path, **PLACE)
    assert str(caught.value).startswith(f"crowd_file {path}"), caught.value


def test_caps_on_size_rows_and_pedestrians(tmp_path, monkeypatch):
    many = "".join(f"0 {p} {p * 0.5} 0\n" for p in range(501))
    with pytest.raises(ValueError, match=r"501 pedestrians, more than the 500 allowed"):
        read_crowd(write(tmp_path, many, "many.txt"))
    monkeypatch.setattr(crowd_files, "CROWD_MAX_ROWS", 3)
    with pytest.raises(ValueError, match=r"more than 3 samples"):
        read_crowd(write(tmp_path, ETH, "rows.txt"))
    monkeypatch.setattr(crowd_files, "CROWD_MAX_BYTES", 20)
    with pytest.raises(ValueError, match=r"more than the 20 allowed"):
        read_crowd(write(tmp_path, ETH, "big.txt"))
    with pytest.raises(ValueError, match=r"not a regular file"):
        read_crowd(tmp_path)
    with pytest.raises(ValueError, match=r"cannot be read"):
        read_crowd(tmp_path / "missing.txt")


@pytest.mark.parametrize(("fields", "message"), [
    ({"crowd": 2}, r"give crowd=0 with it"),
    ({"leader": "person"}, r"would not see the replayed pedestrians; use leader='robot'"),
    ({"crowd_rate": 0.0}, r"crowd_rate must be in \(0"),
    ({"crowd_scale": -1.0}, r"crowd_scale must be in \(0"),
    ({"crowd_format": "sdd"}, r"crowd_format must be one of \('auto', 'eth_ucy', 'trajnet'\)"),
    ({"crowd_offset": (1.0,)}, r"crowd_offset must be an \(x, y\) offset"),
])
def test_bad_replay_fields_are_refused(tmp_path, fields, message):
    with pytest.raises(ValueError, match=message):
        EnvConfig.from_kwargs(crowd_file=write(tmp_path, ETH), **{**PLACE, **fields})


def test_a_crowd_placed_in_a_wall_or_on_a_robot_is_refused(tmp_path):
    path = write(tmp_path, ETH)
    env = parallel_env(crowd_file=path, crowd_offset=(20.0, 0.0), robots=3)
    with pytest.raises(ValueError, match=r"pedestrian 1 at t=0 s is at \(20, 0\) m, inside the "
                                         r"static geometry of scene 'arena'"):
        env.reset(seed=0)
    env = parallel_env(crowd_file=path, robots=3)  # pedestrian 1 starts on the leader
    with pytest.raises(ValueError, match=r"pedestrian 1 starts at \(0, 0\) m on robot 0's "
                                         r"start; place the crowd elsewhere"):
        env.reset(seed=0)
