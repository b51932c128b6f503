"""The episode's clock checked as a whole: every duration the env turns into a number of
steps (``seconds / dt``) and the default step limit (three times the leader's nominal
episode) must be a number of steps an episode can count, or the first reset would end in
``OverflowError: cannot convert float infinity to integer`` (a ``dt`` or a ``leader_speed``
just above zero, each inside its own range)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from boids_env.config import EnvConfig

MAX_STEPS = 10**9
"""The most steps any duration of an episode may take (``max_cycles``' own bound)."""


def check_clock(config: EnvConfig) -> None:
    """``ValueError`` naming ``dt`` when a duration takes more than :data:`MAX_STEPS` steps
    of it, or ``leader_speed`` when the default step limit (no ``max_cycles``) would."""
    from boids_env.world.people import STUCK_TIME

    dt, sc = config.world.dt, config.scenario
    for name, seconds in (("one second", 1.0), ("startup_time", sc.startup_time),
                          ("tail_time", sc.tail_time), ("goal_pause", sc.goal_pause),
                          ("parked_after", config.metrics.parked_after),
                          ("a pedestrian's stuck time", STUCK_TIME)):
        if seconds / dt > MAX_STEPS:
            raise ValueError(
                f"dt={dt:g} s is too fine: {name} ({seconds:g} s) would take "
                f"{seconds / dt:.3g} steps, at most {MAX_STEPS:.0e}; dt must be at least "
                f"{seconds / MAX_STEPS:.3g} s")
    if sc.max_cycles is not None:
        return
    driving = _path_time(config)
    if driving is None:
        return
    steps = 3 * (sc.startup_time + driving + sc.tail_time) / dt
    if not steps <= MAX_STEPS:
        raise ValueError(
            f"leader_speed={sc.leader_speed:g} m/s is too slow for its path at dt={dt:g} s: "
            f"the default step limit (3 × the nominal episode) would be {steps:.3g} steps, at "
            f"most {MAX_STEPS:.0e}; raise leader_speed or dt, or give max_cycles")


def _path_time(config: EnvConfig) -> float | None:
    """An upper bound of the leader's nominal path time (s), pauses included; None for an
    external leader (its step limit is fixed)."""
    from boids_env.world.leader import preview_path
    from boids_env.world.people import GAIT_RANGE

    sc = config.scenario
    walk = sc.leader_kind.walk(sc)
    pauses = sum(length for _, length in sc.leader_pauses)
    if walk is not None:  # a recorded walk keeps its own clock
        return float(walk[0][-1]) + pauses
    if sc.path == "external":
        return None
    if sc.path == "random_waypoints":  # every leg at most the draw box's diagonal
        length = sc.random_waypoint_count * 2 * math.sqrt(2) * sc.path_size
        corners = sc.random_waypoint_count
    else:
        path = preview_path(sc, config.world.dt)
        if path is None:
            return None
        legs = np.diff(path, axis=0)
        length = float(np.hypot(legs[:, 0], legs[:, 1]).sum())
        corners = len(path)
    # a person walks at its slowest gait and pauses at every corner
    if sc.leader_kind.walks(sc):
        return length / sc.leader_speed / GAIT_RANGE[0] + pauses + sc.goal_pause * corners
    return length / sc.leader_speed + pauses
