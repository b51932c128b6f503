"""A map's occupancy grid, as ROS ``nav_msgs/OccupancyGrid`` holds it: what a map scene is
read into (:mod:`~boids_env.world.maps`), what a scene of shapes is rasterised to
(:meth:`~boids_env.world.scene.Scene.occupancy`) and what ``/map`` and the bags carry. Pure
numpy: no pymunk here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from boids_env import kernels

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class OccupancyGrid:
    """A map's cells as ROS ``nav_msgs/OccupancyGrid`` holds them: row 0 at the origin (the
    bottom of the image), values 0 free, 100 occupied, −1 unknown."""

    cells: npt.NDArray[np.int8]
    """(height, width) occupancy values."""
    resolution: float
    """Metres per cell."""
    origin: tuple[float, float, float]
    """(x, y, yaw) of the lower-left corner of cell (0, 0) (m, m, rad)."""

    def occupied(self, points: FloatArray) -> BoolArray:
        """Whether each point (P, 2) lies in an occupied or unknown cell, or off the map."""
        x0, y0, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        compiled = kernels.compiled()
        if compiled is not None and points.ndim == 2 and np.isfinite(points).all():
            return compiled.occupied(np.ascontiguousarray(points, dtype=np.float64),
                                     self.cells, float(self.resolution), float(x0), float(y0),
                                     c, s)  # the same cells in one loop (boids_env.kernels)
        rel = points - np.array([x0, y0])
        local = np.stack([rel[:, 0] * c + rel[:, 1] * s, -rel[:, 0] * s + rel[:, 1] * c], 1)
        col = np.floor(local[:, 0] / self.resolution).astype(np.int64)
        row = np.floor(local[:, 1] / self.resolution).astype(np.int64)
        h, w = self.cells.shape
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        out = np.ones(len(points), dtype=bool)
        out[inside] = self.cells[row[inside], col[inside]] != 0
        return out
