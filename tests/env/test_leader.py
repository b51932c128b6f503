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


def test_a_pause_stops_the_leader_for_its_length_then_it_drives_on():
    """leader_pauses=((20, 30),): 20 s of driving after the 2 s start-up, the leader stands
    still for exactly 30 s where it stopped, then finishes the square; the episode is 30 s
    longer than the study's."""
    e = parallel_env(robots=2, init_jitter=0.0, leader_pauses=((20.0, 30.0),))
    path, times = drive(e)
    plain, plain_times = drive(parallel_env(robots=2, init_jitter=0.0))
    assert times[-1] == pytest.approx(plain_times[-1] + 30.0, abs=0.05)
    still = (times > 22.2) & (times < 51.95)  # after its 0.1 s of braking
    drift = np.linalg.norm(path[still] - path[still][0], axis=1).max()
    assert drift < 1e-3, f"the leader stands during the pause (moved {drift} m)"
    moving = np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-6
    assert moving[(times[1:] > 20.0) & (times[1:] < 22.0)].all()
    assert moving[(times[1:] > 52.2) & (times[1:] < 55.0)].all()
    np.testing.assert_allclose(path[-1], plain[-1], atol=0.15)


def test_a_curve_leader_goes_on_from_where_it_paused():
    """The circle's reference point waits with the leader: after the pause the leader drives
    on at its speed, it does not jump to where the reference point would have gone."""
    e = parallel_env(robots=2, path="circle", path_size=3.0, init_jitter=0.0,
                     leader_pauses=((5.0, 10.0),))
    path, times = drive(e, exact_speed=False)
    step = np.linalg.norm(np.diff(path, axis=0), axis=1) / 0.1
    assert step.max() < 0.55 * 1.5 + 0.05, step.max()
    assert np.all(step[(times[1:] > 7.2) & (times[1:] < 16.9)] < 0.01)


def test_driving_time_leaves_the_pauses_out():
    from boids_env.world.leader import Leader

    leader = Leader(0.5, 2.0, pauses=((1.0, 2.0), (5.0, 1.0)))
    assert [leader.driving_time(t) for t in (0.5, 1.5, 3.5, 7.5, 8.5)] == [0.5, None, 1.5,
                                                                            None, 5.5]


@pytest.mark.parametrize("bad, message", [
    (((1.0, 2.0), (0.5, 1.0)), "increasing order"),
    (((1.0, 0.0),), r"how long in \(0, 3600\]"),
    (((-1.0, 2.0),), r"when in \[0, 3600\]"),
    ("ab", "pairs of finite numbers in seconds"),
])
def test_bad_pauses_are_refused_by_name(bad, message):
    with pytest.raises(ValueError, match=message):
        parallel_env(leader_pauses=bad)
    with pytest.raises(ValueError, match="do not apply to path='external'"):
        parallel_env(path="external", leader_pauses=((1.0, 2.0),))
