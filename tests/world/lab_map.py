"""The shipped ``lab`` map (boids_env/world/data/lab.pgm) as code: a test checks the file is
exactly what this draws, so the map can be rebuilt and changed on purpose only."""

from __future__ import annotations

import numpy as np

RESOLUTION = 0.05
ORIGIN = (-6.0, -5.0, 0.0)
SIZE = (200, 240)  # rows (y), columns (x): 10 m × 12 m


def lab_cells() -> np.ndarray:
    """Occupancy (rows from the bottom): 100 occupied, 0 free, -1 unknown."""
    cells = np.zeros(SIZE, dtype=np.int8)
    y = ORIGIN[1] + (np.arange(SIZE[0]) + 0.5) * RESOLUTION
    x = ORIGIN[0] + (np.arange(SIZE[1]) + 0.5) * RESOLUTION
    gx, gy = np.meshgrid(x, y)

    def box(x0: float, y0: float, x1: float, y1: float, value: int = 100) -> None:
        cells[(gx >= x0) & (gx <= x1) & (gy >= y0) & (gy <= y1)] = value

    box(-6.0, -5.0, 6.0, -4.9)  # outer walls, 10 cm
    box(-6.0, 4.9, 6.0, 5.0)
    box(-6.0, -5.0, -5.9, 5.0)
    box(5.9, -5.0, 6.0, 5.0)
    box(2.4, -5.0, 2.5, -1.6)  # the workshop's wall, doors at y -1.6..-0.4 and 2.4..3.6
    box(2.4, -0.4, 2.5, 2.4)
    box(2.4, 3.6, 2.5, 5.0)
    box(-5.9, -1.5, -5.1, 1.5)  # desks along the west wall
    box(-2.5, -0.3, -0.5, 0.3)  # the central desk island
    cells[(gx + 1.5) ** 2 + (gy - 2.9) ** 2 <= 0.2**2] = 100  # a column
    box(4.8, 0.0, 5.9, 2.0)  # workshop machines and bench
    box(2.6, 0.2, 3.2, 1.8)
    box(3.0, 4.3, 5.9, 4.9, value=-1)  # a storage nook never mapped (unknown)
    return cells
