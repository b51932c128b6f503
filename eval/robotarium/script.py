"""The Robotarium script of a :class:`~boids_env.eval.robotarium.case.RobotariumCase`: its
text, from ``template.py.txt`` beside this module, with the case's numbers written in."""

from __future__ import annotations

import math
from pathlib import Path
from string import Template

import numpy as np

from boids_env.eval.robotarium.case import (
    HALF_BASE,
    MAX_LINEAR,
    TIME_STEP,
    RobotariumCase,
    initial_poses,
    waypoints,
)

TEMPLATE = Path(__file__).with_name("template.py.txt")
"""The script's text with ``$name`` placeholders."""
ARRIVED = 0.05
"""The leader takes its next target within this distance (m): the study's 0.1 m, halved."""


def _literal(array: np.ndarray) -> str:
    """A nested list literal of ``array``, every float written exactly (repr)."""
    return repr(np.asarray(array, dtype=float).tolist())


def script_text(case: RobotariumCase, figure: bool = True) -> str:
    """The Robotarium script of ``case`` (Python source); ``figure``: ``show_figure`` and
    ``sim_in_real_time`` on (a submission's), off for a fast local check."""
    from boids_env import __version__

    config = case.env_config()
    params = case.reynolds()
    turn = 2 * MAX_LINEAR / (2 * HALF_BASE)  # turning in place at the wheels' top speed
    values = {
        "version": __version__, "figure": repr(bool(figure)),
         "robots": case.robots, "last": case.robots - 1,
        "iterations": case.iterations(config), "dt": TIME_STEP,
        "startup_steps": case.startup_steps(config),
        "startup_seconds": f"{config.scenario.startup_time:g}",
        "initial_conditions": _literal(initial_poses(config)),
        "waypoints": _literal(np.array(waypoints(config))), "leader_speed": case.leader,
        "arrived": ARRIVED, "separation_weight": params.separation_weight,
        "cohesion_weight": params.cohesion_weight, "alignment_weight": params.alignment_weight,
        "leader_weight": params.leader_weight, "horizon": params.horizon,
        "desired_separation": params.desired_separation, "max_speed": params.max_speed,
        "max_force": params.max_force, "mass": params.mass,
        "safety_radius": case.safety_radius, "projection_distance": case.projection_distance,
        "barrier_gain": case.barrier_gain, "turn_gain": round(turn / 2, 9),
        "wheel_limit": round(case.wheel_margin * MAX_LINEAR, 9),
        "wheel_percent": f"{100 * case.wheel_margin:g}"}
    assert math.isfinite(case.leader)
    return Template(TEMPLATE.read_text()).substitute(values)


def write_script(case: RobotariumCase, out: str | Path, figure: bool = True) -> Path:
    """Writes the script of ``case`` to ``out`` (atomically); returns its path."""
    from boids_env.files import write_text

    return write_text(Path(out), script_text(case, figure))
