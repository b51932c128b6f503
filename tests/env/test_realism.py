"""Opt-in ROS/Stage realism: off by default, each mechanism does what it says, seeded."""

import numpy as np
import pytest

from boids_env import EnvConfig, parallel_env
from boids_env.world.realism import REALISM_PRESETS


def run(env, steps, act, seed=0):
    env.reset(seed=seed)
    snaps = []
    for _ in range(steps):
        env.step({a: np.asarray(act(env, a), dtype=float) for a in env.agents})
        snaps.append(env.snapshot())
    return snaps


def test_realism_is_off_by_default_and_none_changes_nothing():
    assert not EnvConfig().realism.active
    a = run(parallel_env(robots=7), 60, lambda e, a: [0.2, 0.3])
    b = run(parallel_env(robots=7, realism="none"), 60, lambda e, a: [0.2, 0.3])
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.positions, y.positions)


def test_ros_preset_is_deterministic_per_seed_and_differs_across_seeds():
    def go(seed):
        return run(parallel_env(robots=7, realism="ros"), 80, lambda e, a: [0.0, 0.4], seed)
    a, b, c = go(1), go(1), go(2)
    assert all(np.array_equal(x.positions, y.positions) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[-1].positions, c[-1].positions)
    resolved = EnvConfig.from_kwargs(realism="ros").realism.resolved()
    assert resolved == {k: v for k, v in REALISM_PRESETS["ros"].items()}
    over = EnvConfig.from_kwargs(realism="ros", command_noise=0.0).realism.resolved()
    assert over["command_noise"] == 0.0 and over["stall"] is True


def test_stall_stops_robots_before_they_touch():
    # two followers driven head-on (cells (-0.2,-0.2) and (0.2,-0.2) at 0.2 m spacing)
    fields = dict(robots=3, layout_spacing=0.2, init_jitter=0.0, startup_time=0.0)
    def head_on(e, a):
        return [0.5, 0.0] if a == "follower_1" else [-0.5, 0.0]
    free = run(parallel_env(**fields), 20, head_on)
    stalled = run(parallel_env(**fields, stall=True, stall_margin=0.05), 20, head_on)
    gap = [np.linalg.norm(s.positions[1] - s.positions[2]) for s in stalled]
    assert min(np.linalg.norm(s.positions[1] - s.positions[2]) for s in free) < 0.073
    assert min(gap) >= 2 * 0.036 + 0.05 - 0.03, f"closest {min(gap):.3f} m"
    # the recorded command is still the controller's
    assert np.allclose(stalled[-1].commanded[1], [0.5, 0.0])


def test_command_noise_moves_robots_but_not_the_recorded_commands():
    noisy = run(parallel_env(robots=4, command_noise=0.1, startup_time=0.0), 30,
                lambda e, a: [0.2, 0.0])
    clean = run(parallel_env(robots=4, startup_time=0.0), 30, lambda e, a: [0.2, 0.0])
    assert np.array_equal(noisy[-1].commanded, clean[-1].commanded)
    assert not np.allclose(noisy[-1].positions[1:], clean[-1].positions[1:], atol=1e-3)
    # the leader is not jittered unless asked
    assert np.array_equal(noisy[-1].positions[0], clean[-1].positions[0])


def test_start_jitter_holds_each_follower_until_its_own_start():
    env = parallel_env(robots=6, start_jitter=1.0, startup_time=0.5)
    snaps = run(env, 20, lambda e, a: [0.3, 0.0])
    starts = env.episode.realism.start
    assert np.all((starts >= 0.5) & (starts <= 1.5)) and np.ptp(starts) > 0.1
    for k, snap in enumerate(snaps):
        t_before = k * 0.1  # the step began at this time
        moving = np.abs(snap.velocities[1:, 0]) > 1e-9
        expected = t_before >= starts - 1e-9
        assert np.array_equal(moving, expected), (k, moving, starts)


def test_latency_and_dropped_commands_execute_older_commands():
    env = parallel_env(robots=6, command_latency=2, startup_time=0.0)
    env.reset(seed=3)
    lat = env.episode.realism.latency
    assert set(lat.tolist()) <= {0, 1, 2} and len(set(lat.tolist())) > 1
    history = []
    for k in range(6):
        cmd = np.array([0.05 * (k + 1), 0.0])
        history.append(cmd)
        env.step({a: cmd for a in env.agents})
        executed = env.episode.history[-1][1][1:]
        for i, delay in enumerate(lat):
            want = history[k - delay] if k - delay >= 0 else np.zeros(2)
            assert np.allclose(executed[i], want), (k, i, delay)
    dropped = parallel_env(robots=6, drop_commands=0.5, startup_time=0.0)
    dropped.reset(seed=0)
    repeats = 0
    for k in range(40):
        dropped.step({a: np.array([0.01 * (k + 1), 0.0]) for a in dropped.agents})
        executed = dropped.episode.history[-1][1][1:, 0]
        repeats += int(np.sum(~np.isclose(executed, 0.01 * (k + 1))))
    assert 40 < repeats < 160, repeats  # about half of 200 follower-steps


def test_stale_observations_repeat_the_previous_row():
    env = parallel_env(robots=8, stale_observations=0.5, startup_time=0.0)
    obs, _ = env.reset(seed=0)
    same = 0
    for _ in range(20):
        new, *_ = env.step({a: np.array([0.3, 0.1]) for a in env.agents})
        same += sum(np.array_equal(new[a], obs[a]) for a in env.agents)
        obs = new
    assert 35 < same < 105, same  # about half of 140


def test_stale_rows_come_from_the_episode_seed_alone():
    # A ROS controller node builds observations itself and must draw the same stale rows:
    # a StaleObservations of the episode seed, whatever the other mechanisms draw.
    from boids_env.world.realism import StaleObservations

    for extra in ({}, {"timing_jitter": 0.3, "command_noise": 0.05}):
        env = parallel_env(robots=6, stale_observations=0.4, startup_time=0.0, **extra)
        first, _ = env.reset(seed=11)
        mirror = StaleObservations(0.4, 11)
        fresh = np.stack([first[a] for a in env.agents])
        assert np.array_equal(mirror(fresh), fresh)  # the first observation is never stale
        for _ in range(15):
            before = {a: first[a].copy() for a in env.agents}
            first, *_ = env.step({a: np.array([0.2, -0.1]) for a in env.agents})
            drawn = mirror.rng.random(len(env.agents)) < 0.4
            repeated = np.array([np.array_equal(first[a], before[a]) for a in env.agents])
            assert np.array_equal(drawn, repeated), (extra, drawn, repeated)


def test_pickle_mid_episode_with_realism_continues_identically():
    import pickle

    env = parallel_env(robots=7, realism="ros", drop_commands=0.2, command_latency=1)
    env.reset(seed=5)
    for _ in range(40):
        env.step({a: np.array([0.1, 0.4]) for a in env.agents})
    twin = pickle.loads(pickle.dumps(env))
    for _ in range(40):
        a = env.step({x: np.array([0.3, 0.1]) for x in env.agents})
        b = twin.step({x: np.array([0.3, 0.1]) for x in twin.agents})
        assert all(np.array_equal(a[0][k], b[0][k]) for k in a[0])


@pytest.mark.parametrize("fields, message", [
    ({"realism": "stage"}, "realism must be one of"),
    ({"stall_margin": -0.1}, "stall_margin"),
    ({"command_latency": 1.5}, "command_latency"),
    ({"drop_commands": 1.0}, "drop_commands"),
    ({"stall": "yes"}, "stall must be True or False"),
])
def test_bad_realism_values(fields, message):
    with pytest.raises(ValueError, match=message):
        parallel_env(**fields)
