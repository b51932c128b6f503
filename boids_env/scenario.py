"""Initial layouts (the study's grids), seeded jitter, and the episode's length.

The paper's grids for N = 7, 13 and 19 robots are reproduced cell for cell (DESIGN section 2);
any other N extends the same grid behind the leader, nearest cells first, left before right.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from boids_env.config import EnvConfig, ScenarioConfig

_LEFT_13 = [(-0.5, -0.5), (-1.0, -0.5), (-0.5, -1.0), (-1.0, -1.0), (-1.5, -1.0), (-1.0, -1.5)]
_RIGHT_13 = [(-x, y) for x, y in _LEFT_13]
_EXTRA_19 = [(-1.5, -0.5), (1.5, -0.5), (-0.5, -1.5), (0.5, -1.5), (-1.5, -1.5), (1.5, -1.5)]
PAPER_LAYOUTS: dict[int, list[tuple[float, float]]] = {
    7: _LEFT_13[:3] + _RIGHT_13[:3],
    13: _LEFT_13 + _RIGHT_13,
    19: _LEFT_13 + _RIGHT_13 + _EXTRA_19,
}
"""Initial follower positions (m) of the study, robot 1 first, for a 0.5 m spacing."""


def grid_cells(count: int, spacing: float = 0.5) -> npt.NDArray[np.float64]:
    """The ``count`` grid cells behind the leader (y < 0, x != 0), nearest first.

    Ties in distance go nearer row first, then left before right, so the layout stays
    symmetric whenever ``count`` is even.
    """
    if count == 0:
        return np.zeros((0, 2))
    radius = 1
    while True:  # grow the candidate half-disc until it holds enough cells
        ks = np.arange(1, radius + 1)
        xs = np.concatenate([-ks, ks])
        gx, gy = np.meshgrid(xs, -ks)
        cells = np.stack([gx.ravel(), gy.ravel()], axis=1).astype(float)
        dist2 = (cells**2).sum(axis=1)
        inside = dist2 <= radius**2
        if inside.sum() >= count:
            cells, dist2 = cells[inside], dist2[inside]
            order = np.lexsort((np.abs(cells[:, 0]), cells[:, 0] > 0, -cells[:, 1], dist2))
            return cells[order[:count]] * spacing
        radius *= 2


def initial_positions(scenario: ScenarioConfig, rng: np.random.Generator | None
                      ) -> npt.NDArray[np.float64]:
    """Initial positions (N, 2) in metres, the leader first at the origin.

    The study's cells for N = 7, 13, 19 at 0.5 m spacing; the grid extension otherwise. Every
    follower gets a uniform jitter of ±``init_jitter`` per coordinate from ``rng``.
    """
    followers = scenario.robots - 1
    if followers in (6, 12, 18) and scenario.layout_spacing == 0.5:
        cells = np.array(PAPER_LAYOUTS[scenario.robots], dtype=float)
    else:
        cells = grid_cells(followers, scenario.layout_spacing)
    if rng is not None and scenario.init_jitter > 0:
        cells = cells + rng.uniform(-scenario.init_jitter, scenario.init_jitter, cells.shape)
    return np.concatenate([np.zeros((1, 2)), cells])


def layout_extent(scenario: ScenarioConfig) -> float:
    """Largest |coordinate| (m) an initial position can take, jitter included."""
    cells = initial_positions(scenario, None)
    return float(np.abs(cells).max()) + scenario.init_jitter


def path_extent(scenario: ScenarioConfig) -> float:
    """Largest |coordinate| (m) the leader's path reaches (0 for an external leader)."""
    if scenario.path == "waypoints":
        return float(np.abs(np.array(scenario.waypoints)).max())
    if scenario.path == "external":
        return 0.0
    return scenario.path_size


def check_fits(config: EnvConfig) -> None:
    """Raises ``ValueError`` if the initial layout or the leader path leaves the arena."""
    half = config.world.arena_half_size
    room = half - config.world.robot_radius
    need = layout_extent(config.scenario)
    if need >= room:
        raise ValueError(
            f"arena_half_size must exceed {need + config.world.robot_radius:.2f} m to hold the "
            f"initial grid of robots={config.scenario.robots}, got {half}")
    reach = path_extent(config.scenario)
    if reach + config.scenario.arrival_margin >= room:
        raise ValueError(
            f"the leader path '{config.scenario.path}' reaches {reach:.2f} m: path_size / "
            f"waypoints must stay below {room - config.scenario.arrival_margin:.2f} m for "
            f"arena_half_size={half}")


def step_limit(scenario: ScenarioConfig, nominal_path_time: float | None, dt: float) -> int:
    """Hard step limit: ``max_cycles`` if set, else 3× the nominal episode (1000 steps for an
    external leader, whose path never ends)."""
    if scenario.max_cycles is not None:
        return scenario.max_cycles
    if nominal_path_time is None:
        return 1000
    nominal = scenario.startup_time + nominal_path_time + scenario.tail_time
    return max(1, math.ceil(3 * nominal / dt))
