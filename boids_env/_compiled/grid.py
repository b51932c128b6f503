"""Many robots' neighbours on a grid of cells (from ``KD_TREE_MIN_ROBOTS`` robots on): the
KD-tree's distances and order, bit for bit, or a declined step where an exact tie could
order them otherwise."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _grid(positions, horizon):  # pragma: no cover - compiled
    """The robots sorted into cells a little wider than ``horizon`` (two robots within it
    are never two cells apart, whatever the rounding of the cell coordinates), doubled
    until there are at most 4n + 16: each robot's cell ``(cx, cy)``, the grid's width
    ``nx`` and height, each cell's first entry ``start`` in ``members`` (robot indices in
    cell order) and their coordinates in that order."""
    n = positions.shape[0]
    x0 = positions[:, 0].min()
    y0 = positions[:, 1].min()
    width = positions[:, 0].max() - x0
    height = positions[:, 1].max() - y0
    cell = horizon * (1.0 + 1e-9)
    while (width / cell + 1.0) * (height / cell + 1.0) > 4.0 * n + 16.0:
        cell *= 2.0
    nx = int(width / cell) + 1
    ny = int(height / cell) + 1
    cx = np.empty(n, dtype=np.intp)
    cy = np.empty(n, dtype=np.intp)
    start = np.zeros(nx * ny + 1, dtype=np.intp)
    for j in range(n):
        cx[j] = min(int((positions[j, 0] - x0) / cell), nx - 1)
        cy[j] = min(int((positions[j, 1] - y0) / cell), ny - 1)
        start[cy[j] * nx + cx[j] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    members = np.empty(n, dtype=np.intp)
    fill = start[:-1].copy()
    for j in range(n):
        c = cy[j] * nx + cx[j]
        members[fill[c]] = j
        fill[c] += 1
    sorted_xy = np.empty((n, 2))
    for m in range(n):
        sorted_xy[m, 0] = positions[members[m], 0]
        sorted_xy[m, 1] = positions[members[m], 1]
    return cx, cy, nx, ny, start, members, sorted_xy


RANK_LIMIT = 48
"""Up to this many robots within a follower's horizon, :func:`nearest_grid` places each by
counting the nearer ones (no branch to mispredict: 3x faster than an insertion sort at
1000 robots and 15 neighbours a follower); beyond it, it sorts them by insertion."""


@njit(cache=True)
def _grid_gather(r, px, py, horizon, cx, cy, nx, ny, start, members, xy, cand_d,
                 cand_j):  # pragma: no cover - compiled
    """Robot ``r``'s robots within ``horizon`` (unsorted) into ``cand_d`` and ``cand_j``
    (room for every robot and one more): their count, or -1 for another robot exactly on
    it. Branch-free: every robot of the 3 x 3 cells is written at ``count``, which moves on
    only past one within the horizon that is not ``r`` itself."""
    count = 0
    on = False
    for gy in range(max(cy[r] - 1, 0), min(cy[r] + 2, ny)):
        for gx in range(max(cx[r] - 1, 0), min(cx[r] + 2, nx)):
            c = gy * nx + gx
            for m in range(start[c], start[c + 1]):
                dx = px - xy[m, 0]
                dy = py - xy[m, 1]
                d = math.sqrt(dx * dx + dy * dy)
                j = members[m]
                cand_d[count] = d
                cand_j[count] = j
                on |= (d <= 0.0) & (j != r)
                count += (d > 0.0) & (d <= horizon)
    return -1 if on else count


@njit(cache=True)
def _place_ranked(i, count, cand_d, cand_j, index, distance):  # pragma: no cover - compiled
    """Follower ``i``'s ``count`` candidates into its row of ``index`` and ``distance`` by
    rank (how many are strictly nearer); False where two share a rank within the row (an
    exact tie: the caller declines)."""
    k = index.shape[1]
    for t in range(count):
        d = cand_d[t]
        rank = np.intp(0)  # an intp throughout, as numba types the sum anyway
        for s in range(count):
            rank += np.intp(cand_d[s] < d)
        if rank < k:
            if index[i, rank] >= 0:
                return False
            index[i, rank] = cand_j[t]
            distance[i, rank] = d
    return True


@njit(cache=True)
def _place_sorted(i, count, cand_d, cand_j, index, distance):  # pragma: no cover - compiled
    """:func:`_place_ranked` by an insertion sort of the candidates (many of them)."""
    for t in range(1, count):
        d = cand_d[t]
        j = cand_j[t]
        q = t
        while q > 0 and cand_d[q - 1] > d:
            cand_d[q] = cand_d[q - 1]
            cand_j[q] = cand_j[q - 1]
            q -= 1
        cand_d[q] = d
        cand_j[q] = j
    k = index.shape[1]
    for q in range(1, min(count, k + 1)):
        if cand_d[q] == cand_d[q - 1]:
            return False
    for q in range(min(count, k)):
        index[i, q] = cand_j[q]
        distance[i, q] = cand_d[q]
    return True


@njit(cache=True)
def nearest_grid(positions, horizon, k):  # pragma: no cover - compiled
    """``observations.nearest_neighbours``'s KD-tree branch (many robots) on a grid of cells
    at least ``horizon`` wide: ``(status, index, distance)``. Each follower's robots within
    ``horizon`` are sorted by the KD-tree's own distance (``sqrt(dx * dx + dy * dy)``, the
    follower's coordinates minus the other's: the same bits), nearest first. Status 1
    declines the step (the KD-tree then runs it) where its order could differ: two of a
    follower's k + 1 nearest exactly equally far (the KD-tree orders such ties its own way)
    or another robot exactly on a follower (the KD-tree's k + 1 query then keeps fewer)."""
    n = positions.shape[0]
    followers = n - 1
    index = np.full((followers, k), -1, dtype=np.intp)
    distance = np.full((followers, k), np.inf)
    for j in range(n):  # a NaN or infinite coordinate has no cell: the KD-tree decides
        if not (math.isfinite(positions[j, 0]) and math.isfinite(positions[j, 1])):
            return 1, index, distance
    cx, cy, nx, ny, start, members, xy = _grid(positions, horizon)
    cand_d = np.empty(n + 1)
    cand_j = np.empty(n + 1, dtype=np.intp)
    for i in range(followers):
        r = i + 1
        count = _grid_gather(r, positions[r, 0], positions[r, 1], horizon, cx, cy, nx, ny,
                             start, members, xy, cand_d, cand_j)
        if count < 0:
            return 1, index, distance
        placed = (_place_ranked(i, count, cand_d, cand_j, index, distance)
                  if count <= RANK_LIMIT
                  else _place_sorted(i, count, cand_d, cand_j, index, distance))
        if not placed:
            return 1, index, distance
    return 0, index, distance
