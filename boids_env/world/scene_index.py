"""The spatial index of a scene's shapes: a grid whose every cell lists the capsules (and
polygon edges) that can lie within a query's reach of it, so that a query on a point tests
only the shapes near it (:class:`~boids_env.world.scene.Scene` builds one per reach, lazily).
Pure numpy: no pymunk here.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from boids_env.world import geometry as geo

FloatArray = npt.NDArray[np.float64]

INDEX_CELL = 0.5
"""Cell size (m) of the spatial index that narrows a query to the shapes near a point."""
FAR = 1e9
"""Coordinates of the padding capsule the index points empty entries at (never hit)."""


def build_index(bounds: tuple[float, float, float, float], qa: FloatArray, qb: FloatArray,
                qr: FloatArray, reach: float
                ) -> tuple[FloatArray, tuple[int, int], npt.NDArray[np.intp]]:
    """A grid of :data:`INDEX_CELL` cells over ``bounds`` ``(xmin, ymin, xmax, ymax)``: for
    each cell the capsules ``qa``–``qb`` (S, 2) of radii ``qr`` (S,) within ``reach`` of any
    point of the cell (conservatively, from the cell's centre).

    Returns:
        ``(origin (2,), (nx, ny), table (nx·ny, C))``: the grid's lower-left corner, its
        cells along x and y, and each cell's capsule indices, padded with ``S`` (the index of
        a dummy capsule at :data:`FAR` that the queries append).
    """
    x0, y0, x1, y1 = bounds
    margin = reach + INDEX_CELL
    origin = np.array([x0 - margin, y0 - margin])
    nx = max(1, math.ceil((x1 - x0 + 2 * margin) / INDEX_CELL))
    ny = max(1, math.ceil((y1 - y0 + 2 * margin) / INDEX_CELL))
    gx, gy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    centres = origin + (np.stack([gx.ravel(), gy.ravel()], axis=1) + 0.5) * INDEX_CELL
    lo = np.minimum(qa, qb) - qr[:, None]  # each capsule's bounding box
    hi = np.maximum(qa, qb) + qr[:, None]
    slack = reach + INDEX_CELL * math.sqrt(0.5)
    lists = []
    for start in range(0, len(centres), 512):
        c = centres[start:start + 512]
        # only capsules whose box comes near this chunk's cells can be near any of them (the
        # same lists as testing all, in bounded time and memory)
        near_box = np.all((lo <= c.max(axis=0) + slack) & (hi >= c.min(axis=0) - slack), axis=1)
        pick = np.flatnonzero(near_box)
        for part in range(0, len(c), max(1, 1_000_000 // max(len(pick), 1))):
            cc = c[part:part + max(1, 1_000_000 // max(len(pick), 1))]
            _, d = geo.closest_on_segments(cc[:, None, :], qa[None, pick], qb[None, pick])
            near = d - qr[None, pick] <= slack
            lists += [pick[np.flatnonzero(row)] for row in near]
    width = max(1, max(len(x) for x in lists))
    table = np.full((len(lists), width), len(qr), dtype=np.intp)  # the dummy capsule
    for i, x in enumerate(lists):
        table[i, :len(x)] = x
    return origin, (nx, ny), table
