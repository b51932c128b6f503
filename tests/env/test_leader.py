"""Leader paths: the paper's square corner by corner, the opt-in paths, the external leader."""

import numpy as np
import pytest

from boids_env import parallel_env
from boids_env.world.leader import PAPER_SQUARE


def drive(env, seed=0, exact_speed=True):
    env.reset(seed=seed)
    leader, times = [], []
    while env.agents:
        env.step({a: np.zeros(2) for a in env.agents})
        s = env.snapshot()
        leader.append(s.positions[0].copy())
        times.append(s.time)
        speed_cmd = np.linalg.norm(s.commanded[0])
        if exact_speed:  # waypoint leaders command exactly their speed, or zero
            assert speed_cmd == 0 or abs(speed_cmd - env.config.scenario.leader_speed) < 1e-9
    return np.array(leader), np.array(times)


@pytest.mark.parametrize("speed", [0.5, 0.55, 0.6])
def test_square_visits_corners_in_order_at_speed(speed):
    e = parallel_env(robots=2, leader_speed=speed, init_jitter=0.0)
    path, times = drive(e)
    index = 0
    for corner in PAPER_SQUARE:
        d = np.linalg.norm(path[index:] - corner, axis=1)
        hit = int(np.argmax(d < 0.15))
        assert d[hit] < 0.15, f"corner {corner} not reached after sample {index}"
        index += hit
    moving = np.linalg.norm(np.diff(path, axis=0), axis=1) / 0.1
    cruising = moving[moving > 0.3]
    assert np.median(cruising) == pytest.approx(speed, abs=0.01)
    assert np.all(path[times < 2.0] == 0.0), "the leader waits the 2 s start-up"


def test_default_episode_lasts_about_the_studys_74_6_s():
    _path, times = drive(parallel_env(robots=13))
    assert 70.0 <= times[-1] <= 78.0, times[-1]


@pytest.mark.parametrize("path", ["circle", "figure_eight", "random_waypoints"])
def test_other_paths_finish_inside_the_arena(path):
    e = parallel_env(robots=2, path=path)
    track, _times = drive(e, exact_speed=path == "random_waypoints")
    assert e.leader.finished
    assert np.abs(track).max() < 5.0
    travelled = np.linalg.norm(np.diff(track, axis=0), axis=1).sum()
    assert travelled > 5.0


def test_waypoints_path():
    e = parallel_env(robots=2, path="waypoints", waypoints=[(1.0, 1.0), (-1.0, 2.0)])
    track, _ = drive(e)
    assert np.linalg.norm(track - [1.0, 1.0], axis=1).min() < 0.15
    assert np.linalg.norm(track[-1] - [-1.0, 2.0]) < 0.15


def test_external_leader_follows_commands():
    e = parallel_env(robots=3, path="external", startup_time=0.0, max_cycles=30)
    e.reset(seed=0)
    e.set_leader_command([0.0, -0.4])
    for _ in range(20):
        e.step({a: np.zeros(2) for a in e.agents})
    assert np.allclose(e.snapshot().velocities[0], [0.0, -0.4], atol=1e-6)
    with pytest.raises(ValueError, match="leader velocity"):
        e.set_leader_command([np.nan, 0.0])
    square = parallel_env(robots=3)
    square.reset(seed=0)
    with pytest.raises(RuntimeError, match="path='external'"):
        square.set_leader_command([0.1, 0.0])


def test_external_leader_keeps_a_copy_of_the_callers_command():
    """Editing the array passed to set_leader_command afterwards changes nothing: the leader
    holds its own copy (a NaN written into the caller's array never reaches the world)."""
    e = parallel_env(robots=3, path="external", startup_time=0.0, max_cycles=30)
    e.reset(seed=0)
    command = np.array([0.3, 0.0])
    e.set_leader_command(command)
    command[:] = [np.nan, -1.0]
    obs, *_ = e.step({a: np.zeros(2) for a in e.agents})
    assert e.snapshot().commanded[0].tolist() == [0.3, 0.0]
    for agent, o in obs.items():
        assert np.isfinite(o).all(), f"{agent}: non-finite observation {o}"
    assert command.tolist()[1] == -1.0, "the caller's own array is left as the caller wrote it"
