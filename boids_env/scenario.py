"""Initial positions (the study's grids of :mod:`boids_env.layout` plus seeded jitter) and the
episode's length."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from boids_env.config import scene_matrix
from boids_env.layout import PAPER_LAYOUTS, follower_cells, grid_cells
from boids_env.vectors import times_matrix

if TYPE_CHECKING:
    from boids_env.config import ScenarioConfig

__all__ = ["PAPER_LAYOUTS", "grid_cells", "initial_positions", "step_limit"]

def initial_positions(scenario: ScenarioConfig, rng: np.random.Generator | None
                      ) -> npt.NDArray[np.float64]:
    """Initial positions (N, 2) in metres, the leader first at the origin.

    The study's cells for N = 7, 13, 19 at 0.5 m spacing; the grid extension otherwise; turned
    with the path by ``path_rotation`` / ``path_mirror``. Every follower gets a uniform jitter
    of ±``init_jitter`` per coordinate from ``rng``.
    """
    cells = follower_cells(scenario.robots, scenario.layout_spacing)
    if scenario.path_rotation or scenario.path_mirror:
        cells = times_matrix(cells, scene_matrix(scenario).T)
    if rng is not None and scenario.init_jitter > 0:
        cells = cells + rng.uniform(-scenario.init_jitter, scenario.init_jitter, cells.shape)
    return np.concatenate([np.zeros((1, 2)), cells])


def step_limit(scenario: ScenarioConfig, nominal_path_time: float | None, dt: float) -> int:
    """Hard step limit: ``max_cycles`` if set, else 3× the nominal episode (1000 steps for an
    external leader, whose path never ends)."""
    if scenario.max_cycles is not None:
        return scenario.max_cycles
    if nominal_path_time is None:
        return 1000
    nominal = scenario.startup_time + nominal_path_time + scenario.tail_time
    return max(1, math.ceil(3 * nominal / dt))
