"""Bad input raises a clear error naming the problem, and never corrupts the env's state."""

import contextlib
import re
import warnings

import numpy as np
import pytest

from boids_env import EnvConfig, parallel_env
from boids_env.policies.reynolds_params import reynolds_params
from boids_env.recording import Recording


@pytest.mark.parametrize("field, value, allowed", [
    ("robots", 1, r"\[2, 10000\]"), ("robots", 13.5, "integer"), ("robots", True, "integer"),
    ("leader_speed", 0.0, r"\(0.0, 2.0\] m/s"), ("leader_speed", float("nan"), "m/s"),
    ("leader_speed", "fast", "number"), ("robot_radius", -0.01, "m"),
    ("robot_mass", 0, "kg"), ("robot_mass", 1e-20, r"\[0.001, 100\] kg"), ("dt", 2.0, "s"),
    ("substeps", 0, r"\[1, 1000\]"),
    ("horizon", 0.0, "m"), ("neighbours", -1, r"\[0, 1024\]"), ("path", "spiral", "square"),
    ("init_jitter", 0.5, "m"), ("separation_threshold", -1, "m"),
    ("alignment_threshold_deg", 400, "degrees"), ("wrap_alignment", "yes", "True or False"),
    ("max_cycles", 0, r"\[1, "), ("waypoints", [(1, 2, 3)], "pairs"),
    ("reward_gap", -1.0, r"\[0.0, 1000"), ("reward_gap", float("inf"), "reward_gap"),
])
def test_bad_config_values_name_field_and_range(field, value, allowed):
    with pytest.raises(ValueError, match=field) as info:
        parallel_env(**{field: value})
    assert re.search(allowed, str(info.value)), f"{info.value} does not state {allowed}"


def test_unknown_config_field_is_a_type_error():
    with pytest.raises(TypeError, match=r"unknown config field.*leader_sped"):
        parallel_env(leader_sped=0.5)
    with pytest.raises(ValueError, match="preset must be one of"):
        reynolds_params("fancy")
    with pytest.raises(ValueError, match="leader_weight"):
        reynolds_params(leader_weight=-1)
    with pytest.raises(ValueError, match="waypoints must hold"):
        EnvConfig.from_kwargs(path="waypoints")


@pytest.mark.parametrize("value", [["34"], "34", [("1", 2.0)], [(True, 0.0)], [(0.0, False)],
                                   [(1 + 2j, 0.0)], [(None, 1.0)], [b"12"], [{1: 2, 3: 4}]])
def test_waypoints_must_be_pairs_of_real_numbers(value):
    """A string is not a pair ("34" once became (3, 4)), and strings, bools, complex numbers and
    None are not coordinates (they were coerced by float())."""
    with pytest.raises(ValueError, match=r"waypoints must be a sequence of \(x, y\) pairs"):
        EnvConfig.from_kwargs(path="waypoints", waypoints=value)


def test_waypoints_take_numeric_pairs_of_any_kind():
    for value in ([(1, 2)], [[1.0, 2.0]], np.array([[1.0, 2.0]]), [np.array([1, 2])]):
        config = EnvConfig.from_kwargs(path="waypoints", waypoints=value)
        assert config.scenario.waypoints == ((1.0, 2.0),), value


def stepped_env(steps=10):
    e = parallel_env(robots=5)
    e.reset(seed=0)
    for _ in range(steps):
        e.step({a: np.full(2, 0.1) for a in e.agents})
    return e


def good(e):
    return {a: np.full(2, 0.2) for a in e.agents}


BAD_ACTIONS = [
    (lambda e: {**good(e), "follower_1": np.array([np.nan, 0.0])}, ValueError, "finite"),
    (lambda e: {**good(e), "follower_2": np.array([np.inf, 0.0])}, ValueError, "follower_2"),
    (lambda e: {**good(e), "follower_1": np.zeros(3)}, ValueError, "follower_1 must be 2"),
    (lambda e: {**good(e), "follower_1": "up"}, ValueError, "follower_1 must be 2"),
    (lambda e: {**good(e), "follower_9": np.zeros(2)}, KeyError, "follower_9"),
    (lambda e: {a: v for a, v in good(e).items() if a != "follower_3"}, KeyError, "follower_3"),
    (lambda e: [np.zeros(2)] * 4, TypeError, "dict"),
    (lambda e: {**good(e), "follower_1": [True, 0.1]}, ValueError, "real numbers"),
    (lambda e: {**good(e), "follower_1": ["0.1", 0.2]}, ValueError, "real numbers"),
    (lambda e: {**good(e), "follower_1": np.array([1 + 2j, 0])}, ValueError, "real numbers"),
    (lambda e: {**good(e), "follower_1": np.array([True, False])}, ValueError, "real numbers"),
]


@pytest.mark.parametrize("make, error, message", BAD_ACTIONS)
def test_bad_actions_raise_and_leave_state_untouched(make, error, message):
    e, twin = stepped_env(), stepped_env()
    with pytest.raises(error, match=message):
        e.step(make(e))
    assert np.array_equal(e.snapshot().positions, twin.snapshot().positions)
    a, b = e.step(good(e)), twin.step(good(twin))
    assert all(np.array_equal(a[0][k], b[0][k]) for k in a[0])
    assert a[1] == b[1]


def test_out_of_range_actions_are_clipped_to_the_speed_limit():
    e = stepped_env(0)
    e.step({a: np.array([3.0, 4.0]) for a in e.agents})
    cmd = e.snapshot().commanded[1:]
    assert np.allclose(np.linalg.norm(cmd, axis=1), 0.5)
    assert np.allclose(cmd, [0.3, 0.4])


def test_step_before_reset():
    with pytest.raises(RuntimeError, match="before reset"):
        parallel_env().step({})
    with pytest.raises(RuntimeError, match="reset"):
        parallel_env().snapshot()


def test_step_after_the_episode_ended():
    e = parallel_env(robots=3, max_cycles=5)
    e.reset(seed=0)
    for _ in range(5):
        e.step({a: np.zeros(2) for a in e.agents})
    assert e.agents == []
    assert e.step({}) == ({}, {}, {}, {}, {})
    with pytest.raises(RuntimeError, match="episode has ended"):
        e.step({"follower_1": np.zeros(2)})
    e.reset(seed=0)
    assert len(e.agents) == 2, "usable again after reset"


@pytest.mark.parametrize("seed", [-1, 1.5, "7", True])
def test_bad_seeds(seed):
    e = stepped_env()
    before = e.snapshot().positions
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        e.reset(seed=seed)
    assert np.array_equal(before, e.snapshot().positions)
    assert e.agents, "the episode goes on"


def test_bad_options():
    e = stepped_env()
    before = e.snapshot().positions
    with pytest.raises(ValueError, match="leader_speed"):
        e.reset(seed=1, options={"leader_speed": -1})
    with pytest.raises(ValueError, match="cannot change robots"):
        e.reset(seed=1, options={"robots": 7})
    with pytest.raises(TypeError, match="options must be a dict"):
        e.reset(seed=1, options=[("leader_speed", 0.5)])
    assert np.array_equal(before, e.snapshot().positions)
    with pytest.warns(UserWarning, match="unknown option"):
        e.reset(seed=1, options={"leader_sped": 0.5})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        e.reset(seed=1, options={"leader_speed": 0.6, "path": "circle"})
    assert e.episode_config.scenario.leader_speed == 0.6
    assert e.config.scenario.leader_speed == 0.55, "options last one episode"
    e.reset(seed=1)
    assert e.episode_config.scenario.path == "square"


def test_unknown_agent_spaces():
    e = parallel_env(robots=3)
    with pytest.raises(KeyError, match="unknown agent 'leader'"):
        e.observation_space("leader")
    with pytest.raises(KeyError, match="follower_3"):
        e.action_space("follower_3")


def test_bad_render_mode():
    with pytest.raises(ValueError, match="render_mode must be one of"):
        parallel_env(render_mode="ascii")


def test_unreadable_recording(tmp_path):
    junk = tmp_path / "junk.parquet"
    junk.write_bytes(b"not parquet at all")
    with pytest.raises(ValueError, match="cannot read recording"):
        Recording.from_parquet(junk)
    with pytest.raises(FileNotFoundError):
        Recording.from_parquet(tmp_path / "missing.parquet")


def test_huge_finite_actions_keep_their_direction():
    e = stepped_env(0)
    e.step({"follower_1": np.array([1e155, 0.0]), "follower_2": [0.0, -1e308],
            "follower_3": np.array([1e308, 1e308]), "follower_4": np.array([1e-300, 0.0])})
    cmd = e.snapshot().commanded[1:]
    np.testing.assert_allclose(cmd[:3], [[0.5, 0.0], [0.0, -0.5],
                                         [0.5 / np.sqrt(2), 0.5 / np.sqrt(2)]])
    assert cmd[3].tolist() == [1e-300, 0.0]


def test_huge_external_leader_command_keeps_its_direction():
    e = parallel_env(robots=2, path="external", startup_time=0)
    e.reset(seed=0)
    e.set_leader_command([-1e200, 0.0])
    e.step({"follower_1": np.zeros(2)})
    np.testing.assert_allclose(e.snapshot().commanded[0], [-2.0, 0.0])
    for bad in ([True, 0.0], ["1", 0], [np.nan, 0]):
        with pytest.raises(ValueError, match="leader velocity"):
            e.set_leader_command(bad)


@pytest.mark.parametrize("fields, message", [
    ({"robot_radius": 0.3, "layout_spacing": 0.1, "arena_half_size": 20},
     "initial robots could overlap"),
    ({"layout_spacing": 0.15, "init_jitter": 0.05}, "layout_spacing"),
    ({"drive_force": 1000.0}, r"drive_force / robot_mass must be at most 100"),
    ({"max_speed": 5.0, "drive_force": 10.0}, "substeps >= 14"),
    ({"dt": 0.5, "substeps": 1}, "dt / substeps too coarse"),
    ({"collision_slop": 0.01}, "collision_slop must be at most a quarter of robot_radius"),
    ({"separation_threshold": 3.0}, "below cohesion_threshold"),
    ({"path_rotation": 45}, "path_rotation=45"),
])
def test_physically_meaningless_combinations_are_refused(fields, message):
    with pytest.raises(ValueError, match=message):
        parallel_env(**fields)


def test_copy_copy_is_an_independent_env():
    import copy

    e = stepped_env(30)
    c = copy.copy(e)
    c.step(good(c))
    assert e.episode_metrics()["steps"] == 30 and c.episode_metrics()["steps"] == 31
    assert e.snapshot().time == pytest.approx(3.0)
    twin = stepped_env(30)
    np.testing.assert_array_equal(e.step(good(e))[0]["follower_1"],
                                  twin.step(good(twin))[0]["follower_1"])


def test_aec_refuses_a_bad_action_when_given_and_caches_nothing():
    from boids_env import env as aec_env

    a = aec_env(robots=3)
    a.reset(seed=0)
    with pytest.raises(ValueError, match="follower_1"):
        a.step(np.array([np.nan, 0.0]))
    a.step(np.array([0.1, 0.0]))  # the same agent again: nothing bad was cached
    a.step(np.array([0.1, 0.0]))
    assert a.agent_selection == "follower_1"


def test_resets_allocate_no_new_pymunk_buffers(monkeypatch):
    import pymunk.batch

    e = parallel_env(robots=7)
    e.reset(seed=0)
    made = []
    original = pymunk.batch.Buffer.__init__

    def counting(self):
        made.append(1)
        original(self)

    monkeypatch.setattr(pymunk.batch.Buffer, "__init__", counting)
    for seed in range(50):
        e.reset(seed=seed)
        e.step(good(e))
    assert made == [], f"{len(made)} buffers made over 50 resets (pymunk never frees them)"


def test_a_flat_field_name_in_two_config_sections_is_refused():
    # issue 39 item 7: FIELD_OWNER was last-wins, so a name in two sections silently reached
    # only one of them
    from dataclasses import dataclass

    from boids_env.config import FIELD_OWNER, WorldConfig, field_owners

    @dataclass(frozen=True)
    class Other:
        dt: float = 0.05

    with pytest.raises(TypeError, match="'dt' is in both 'world' and 'other'"):
        field_owners({"world": WorldConfig, "other": Other})
    assert FIELD_OWNER["dt"] == "world" and FIELD_OWNER["horizon"] == "observation"


NON_FINITE_CASES = [
    {},
    {"frame": "leader", "relative_actions": True},  # rotated, then the leader velocity added
    {"leader": "person", "crowd": 4, "path": "square"},  # the crowd walks before physics
    {"safety_filter": True, "scene": "pillars"},
    {"realism": "ros"},
    {"robot": "gritsbot", "action": "unicycle"},  # native (v, ω): no speed limit's kernel
]


@pytest.mark.parametrize("compiled", [True, False], ids=["kernels", "numpy"])
@pytest.mark.parametrize("fields", NON_FINITE_CASES, ids=lambda f: ",".join(f) or "default")
def test_a_nan_or_inf_action_is_refused_before_anything_moves(fields, compiled):
    """The finiteness check rides on the speed limit (its kernel sees every speed): a NaN or
    inf is still refused with the followers named, through both APIs, and the env steps on
    as if the bad call never happened (the crowd, the leader and the random streams too)."""
    from boids_env import kernels

    assert kernels.load() is not None
    context = contextlib.nullcontext() if compiled else kernels.reference()
    with context:
        e, twin = (parallel_env(robots=5, max_cycles=50, **fields) for _ in range(2))
        for env in (e, twin):
            env.reset(seed=3)
            for _ in range(3):
                env.step_arrays(np.full((4, 2), 0.1))
        bad = np.full((4, 2), 0.1)
        bad[1, 0], bad[3, 1] = np.nan, -np.inf
        with pytest.raises(ValueError, match=r"finite; NaN or inf from \['follower_2', "
                                             r"'follower_4'\]"):
            e.step_arrays(bad)
        with pytest.raises(ValueError, match=r"finite; NaN or inf from \['follower_2', "
                                             r"'follower_4'\]"):
            e.step(dict(zip(e.agents, bad, strict=True)))
        huge = np.full((4, 2), 1e308)  # finite: its speed overflows, and is limited
        for env in (e, twin):
            a = env.step_arrays(huge)
        b = twin.step_arrays(np.full((4, 2), 0.1))
        c = e.step_arrays(np.full((4, 2), 0.1))
    assert np.all(np.isfinite(a.observations))
    assert c.observations.tobytes() == b.observations.tobytes()
    assert c.rewards.tobytes() == b.rewards.tobytes()
    assert e.snapshot().positions.tobytes() == twin.snapshot().positions.tobytes()


@pytest.mark.parametrize("fields, named", [
    ({"dt": 5e-324}, r"dt=.* s is too fine: one second .* dt must be at least 1e-09 s"),
    ({"dt": 1e-7, "startup_time": 600}, r"dt=1e-07 s is too fine: startup_time \(600 s\)"),
    ({"dt": 1e-8}, r"leader_speed=0.55 m/s is too slow .* at dt=1e-08 s"),
    ({"leader_speed": 5e-324}, r"leader_speed=.* m/s is too slow for its path"),
    ({"leader_speed": 1e-300, "path": "random_waypoints"}, "leader_speed="),
    ({"leader_speed": 1e-300, "leader": "person", "robots": 4}, "leader_speed="),
])
def test_a_clock_that_counts_infinite_steps_is_refused_at_construction(fields, named):
    """Issue 55: a dt or leader_speed just above zero (each inside its own range) passed the
    config and ended the first reset in ``OverflowError: cannot convert float infinity to
    integer``; the config refuses it, naming the field and the bound."""
    with pytest.raises(ValueError, match=named):
        parallel_env(**fields)


def test_a_slow_clock_within_bounds_still_runs():
    env = parallel_env(leader_speed=1e-4, robots=3, dt=0.05)
    env.reset(seed=0)
    assert 3 * 16 / 1e-4 / 0.05 < env.episode.step_limit <= 10**9, env.episode.step_limit
    env = parallel_env(leader_speed=1e-300, max_cycles=3, robots=3)  # the limit is given
    env.reset(seed=0)
    env.step({a: np.zeros(2) for a in env.agents})
