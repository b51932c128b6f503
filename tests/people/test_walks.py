"""Recorded walks: leader="trajectory" replays a CSV of t, x, y on the episode's clock."""

import os

import numpy as np
import pytest

from boids_env import EnvConfig, parallel_env
from boids_env.world.walks import WALKS, read_walk


def write(tmp_path, text, name="walk.csv"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


WALK = "t,x,y\n0,-1,-1\n1.0,-1,-1\n2.5,0.5,-1\n4.0,0.5,0.5\n6.0,-1.0,1.0\n"


def test_a_replayed_walk_is_where_the_file_says_at_every_sample(tmp_path):
    path = write(tmp_path, WALK)
    env = parallel_env(leader="trajectory", leader_trajectory=path, robots=5)
    env.reset(seed=0)
    times, points = read_walk(path)
    seen = [(0.0, env.snapshot().positions[0])]
    while env.agents:
        env.step({a: np.zeros(2) for a in env.agents})
        snap = env.snapshot()
        seen.append((snap.time, snap.positions[0]))
    assert seen[-1][0] >= times[-1] - 1e-9, "the episode ends after the walk"
    for t, p in seen:
        want = [np.interp(t, times, points[:, 0]), np.interp(t, times, points[:, 1])]
        assert np.hypot(*(p - want)) < 1e-3, (t, p.tolist(), want)
    # every row of the file, where the clock passes it (rows at whole tenths)
    by_time = {round(t, 6): p for t, p in seen}
    for t, want in zip(times, points, strict=True):
        assert np.hypot(*(by_time[round(float(t), 6)] - want)) < 1e-3, (t, want.tolist())
    # between rows: linear (t = 1.7 lies 0.7 / 1.5 of the way from row 2 to row 3)
    assert np.allclose(by_time[1.7], [-1 + 1.5 * 0.7 / 1.5, -1.0], atol=1e-3)


def test_the_walk_sets_the_start_and_heading(tmp_path):
    cfg = EnvConfig.from_kwargs(leader="trajectory", leader_trajectory=write(tmp_path, WALK))
    assert cfg.scenario.start == (-1.0, -1.0)
    assert cfg.scenario.start_heading == 0.0  # its first move is along +x


@pytest.mark.parametrize(("text", "message"), [
    ("t,x,y\n0,0,0\n", r"at least two rows"),
    ("t,x,y\n0,0,0\n1,2\n", r"row 3: expected 3 values"),
    ("t,x,y\n0,0,0\n1,a,2\n", r"row 3: t,x,y must be numbers"),
    ("t,x,y\n0,0,0\n1,nan,2\n", r"row 3: values must be finite"),
    ("t,x,y\n0,0,0\n1,0,1e9\n", r"row 3: values must be finite and within"),
    ("t,x,y\n0,0,0\n2,0,0\n1,0,0\n", r"row 4: t must increase, got 1 after 2"),
    ("t,x,y\n-1,0,0\n1,0,0\n", r"row 2: t must be >= 0"),
    ("time,px,py\n0,0,0\n1,0,0\n", r"row 1: the header must be 't,x,y'"),
])
def test_bad_walk_files_are_refused_naming_the_row(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(ValueError, match=message):
        EnvConfig.from_kwargs(leader="trajectory", leader_trajectory=path)


def test_walk_files_are_bounded(tmp_path, monkeypatch):
    from boids_env.world import walks

    monkeypatch.setattr(walks, "WALK_MAX_BYTES", 50)
    with pytest.raises(ValueError, match=r"more than the 50 allowed"):
        read_walk(write(tmp_path, WALK * 3, "big.csv"))
    with pytest.raises(ValueError, match=r"cannot be read"):
        read_walk(str(tmp_path / "missing.csv"))


def test_trajectory_fields_go_together(tmp_path):
    with pytest.raises(ValueError, match=r"leader='trajectory' needs leader_trajectory"):
        EnvConfig.from_kwargs(leader="trajectory")
    with pytest.raises(ValueError, match=r"give leader='trajectory' too"):
        EnvConfig.from_kwargs(leader_trajectory=write(tmp_path, WALK))


def test_the_shipped_walk_is_what_its_generator_records():
    from example_walk import example_walk

    assert WALKS["doorway_walk"].read_text() == example_walk()


@pytest.mark.parametrize("start", ["0,0", "0.5,0"])
def test_a_walk_through_the_arena_wall_is_refused_wherever_it_starts(tmp_path, start):
    # issue 39 item 1: a walk starting exactly at (0, 0) in the default arena skipped the
    # scene check and walked through the wall at x = 5 m to (30, 0)
    path = write(tmp_path, f"t,x,y\n0,{start}\n60,30,0\n")
    with pytest.raises(ValueError, match=r"the walk .*walk.csv reaches \(30.00, 0.00\), "
                                         r"within .* of the east wall"):
        EnvConfig.from_kwargs(leader="trajectory", leader_trajectory=path)


def test_a_walk_inside_the_arena_from_the_origin_is_accepted(tmp_path):
    path = write(tmp_path, "t,x,y\n0,0,0\n10,3,0\n")
    config = EnvConfig.from_kwargs(leader="trajectory", leader_trajectory=path)
    assert config.scenario.start == (0.0, 0.0)


def test_a_file_that_is_not_a_walk_is_never_quoted(tmp_path):
    """Issue 39: ``leader_trajectory=/etc/passwd`` printed the file's first 80 characters."""
    secret = tmp_path / "secret.txt"
    secret.write_text("root:SECRET-TOKEN:0:0\nmore,SECRET2,x\n")
    with pytest.raises(ValueError, match="the header must be 't,x,y'") as info:
        read_walk(secret)
    assert "SECRET" not in str(info.value)
    secret.write_text("t,x,y\n0,0,0\n1,SECRET3,0\n2,0,0,SECRET4\n")
    with pytest.raises(ValueError, match="row 3: t,x,y must be numbers, x is not") as info:
        read_walk(secret)
    assert "SECRET" not in str(info.value)


def test_a_fifo_walk_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "w.csv"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="not a regular file"):
        read_walk(fifo)


def _replay(seeds, **fields):
    """The replayed person's deviation from the walk (m) at every sample, and the samples."""
    times, points = read_walk("doorway_walk")
    worst, steps = 0.0, 0
    for seed in seeds:
        env = parallel_env(scene="doorway", leader="trajectory",
                           leader_trajectory="doorway_walk", **fields)
        env.reset(seed=seed)
        while env.agents:
            env.step({a: np.zeros(2) for a in env.agents})
            snap = env.snapshot()
            want = (np.interp(snap.time, times, points[:, 0]),
                    np.interp(snap.time, times, points[:, 1]))
            worst = max(worst, float(np.hypot(*(snap.positions[0] - want))))
            steps += 1
    return worst, steps


@pytest.mark.slow
def test_a_crowd_yields_to_a_replayed_person():
    # issue 38: 8 pedestrians pushed the replayed person up to 0.25 m off its recording
    worst, steps = _replay((0, 1, 2), crowd=8, robots=5)
    assert steps > 800
    assert worst < 1e-9, f"the replayed person left its walk by {worst:.3g} m"


def test_a_replay_without_a_crowd_is_what_it_was_before_the_crowd_yielded():
    # the digest of 300 steps' positions (to 1 nm) written by the code before issue 38's
    # kinematic replay: without a crowd the replayed person stays a driven body, as before
    import hashlib

    env = parallel_env(scene="doorway", leader="trajectory", leader_trajectory="doorway_walk",
                       robots=5)
    env.reset(seed=3)
    digest = hashlib.sha256()
    for _ in range(300):
        env.step({a: np.full(2, 0.1) for a in env.agents})
        digest.update(np.round(env.snapshot().positions, 9).tobytes())
    assert digest.hexdigest() == (
        "9cd05146e1fd9167a5842d6440f5023f6164d271068588cb7aa05475ab3b91e9")


def test_a_replay_among_a_crowd_pickles_mid_episode():
    import pickle

    env = parallel_env(scene="doorway", leader="trajectory", leader_trajectory="doorway_walk",
                       crowd=8, robots=5)
    env.reset(seed=1)
    for _ in range(60):
        env.step({a: np.full(2, 0.05) for a in env.agents})
    clone = pickle.loads(pickle.dumps(env))
    for step in range(40):
        env.step({a: np.full(2, 0.05) for a in env.agents})
        clone.step({a: np.full(2, 0.05) for a in clone.agents})
        assert np.array_equal(env.snapshot().positions, clone.snapshot().positions), step
        assert np.array_equal(env._world.pedestrian_positions,
                              clone._world.pedestrian_positions), step
