"""The study's initial grids and their extension to any group size, as pure geometry.

The paper's grids for N = 7, 13 and 19 robots are reproduced cell for cell;
any other N extends the same grid behind the leader, nearest cells first, left before right.
Positions are in metres, the leader at the origin; no randomness here (see ``scenario``).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

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


def follower_cells(robots: int, spacing: float = 0.5) -> npt.NDArray[np.float64]:
    """The followers' cells (robots - 1, 2): the study's for N = 7, 13, 19 at 0.5 m spacing,
    the grid extension otherwise."""
    followers = robots - 1
    if followers in (6, 12, 18) and spacing == 0.5:
        return np.array(PAPER_LAYOUTS[robots], dtype=float)
    return grid_cells(followers, spacing)
