"""Fuzzing the env's config and actions (hypothesis): every combination is either refused with
a ValueError/TypeError naming a field it was given, or accepted, and then 200 steps of hostile
actions (full speed into a wall, into each other, huge values) keep every robot finite and
inside the arena."""

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from boids_env import parallel_env


def _log_uniform(lo, hi):
    return st.floats(math.log(lo), math.log(hi)).map(math.exp)


WILD = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
                 st.booleans(), st.text(max_size=3), st.none())
PLAUSIBLE = {
    "robot_radius": _log_uniform(0.005, 0.5),
    "robot_mass": _log_uniform(0.0005, 200),
    "max_speed": _log_uniform(0.01, 6),
    "drive_force": _log_uniform(1e-3, 2000),
    "dt": _log_uniform(0.005, 0.6),
    "substeps": st.integers(1, 120),
    "robots": st.integers(2, 25),
    "arena_half_size": st.floats(2, 20),
    "leader_speed": _log_uniform(0.05, 2.5),
    "path": st.sampled_from(["square", "circle", "figure_eight", "random_waypoints",
                             "external"]),
    "path_size": st.floats(0.3, 5),
    "path_rotation": st.floats(-370, 370),
    "init_jitter": st.floats(0, 0.3),
    "layout_spacing": st.floats(0.05, 2),
    "collision_slop": st.floats(0, 0.006),
    "horizon": st.floats(0.1, 3),
    "neighbours": st.integers(0, 30),
    "obs_noise": st.floats(0, 0.2),
}


@st.composite
def configs(draw):
    names = draw(st.lists(st.sampled_from(sorted(PLAUSIBLE)), min_size=1, max_size=8,
                          unique=True))
    out = {}
    for name in names:
        wild = draw(st.integers(0, 9)) == 0  # one field in ten gets a nonsense value
        out[name] = draw(WILD if wild else PLAUSIBLE[name])
    return out


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(fields=configs(), mode=st.sampled_from(["wall", "pile", "random", "huge"]),
       seed=st.integers(0, 2**16))
def test_config_is_refused_by_name_or_the_physics_holds(fields, mode, seed):
    try:
        env = parallel_env(**fields)
    except (ValueError, TypeError) as exc:
        assert any(name in str(exc) for name in fields), f"{fields}: {exc}"
        return
    env.reset(seed=seed)
    half = env.config.world.arena_half_size
    rng = np.random.default_rng(seed)
    external = env.config.scenario.path == "external"
    for step in range(200):
        if not env.agents:
            break
        n = len(env.agents)
        if mode == "wall":
            act = np.tile([10.0, 3.0], (n, 1))
        elif mode == "pile":
            act = -env.snapshot().positions[1:] * 100.0
        elif mode == "random":
            act = rng.uniform(-10, 10, (n, 2))
        else:
            act = rng.choice([-1e300, 1e300, 1e-300], (n, 2))
        if external:
            env.set_leader_command(rng.uniform(-3, 3, 2))
        env.step(dict(zip(env.agents, act, strict=True)))
        pos = env.snapshot().positions
        assert np.isfinite(pos).all(), f"step {step}: non-finite positions, {fields}"
        assert np.abs(pos).max() < half, (f"step {step}: a robot left the arena "
                                          f"({np.abs(pos).max():.3f} m >= {half} m), {fields}")
        state = env.state()
        assert np.array_equal(state[: pos.size], pos.ravel().astype(np.float32))
