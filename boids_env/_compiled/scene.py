"""Ports of :class:`boids_env.world.scene.Scene`'s queries on its capsules: nearest wall points,
clearance, wall flags, map cells, sight lines and ray casts (and the lidar's robot discs).

The same candidate lists (the scene's spatial index, looked up here), the same operations in
the same order as :func:`boids_env.world.geometry.closest_on_segments`, numpy's minimum and
maximum as ``a < b ? a : b`` and ``a > b ? a : b`` and its clip as two comparisons that keep
``x`` unless it is out of range (numpy's own rules: signed zeros come out the same)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _index_row(px, py, origin, shape):  # pragma: no cover - compiled
    """The row of the scene's index table for a point (``Scene._candidates``; ``origin``
    (x, y, cell size))."""
    cx = math.floor((px - origin[0]) / origin[2])
    cy = math.floor((py - origin[1]) / origin[2])
    cx = min(max(cx, 0), shape[0] - 1)
    cy = min(max(cy, 0), shape[1] - 1)
    return cx * shape[1] + cy


@njit(cache=True)
def _closest(px, py, ax, ay, bx, by):  # pragma: no cover - compiled
    """``geometry.closest_on_segments`` of one point and segment: (cx, cy, distance)."""
    abx = bx - ax
    aby = by - ay
    length2 = abx * abx + aby * aby
    t = ((px - ax) * abx + (py - ay) * aby) / (length2 if length2 > 0 else 1.0)
    if t < 0.0:  # np.clip: -0.0 stays -0.0
        t = 0.0
    if t > 1.0:
        t = 1.0
    cx = ax + t * abx
    cy = ay + t * aby
    ux = px - cx
    uy = py - cy
    return cx, cy, math.sqrt(ux * ux + uy * uy)


@njit(cache=True)
def _surface_candidates(px, py, box, has_box, qa, qb, qr, table, origin, shape, has_shapes,
                        off, cand_d):  # pragma: no cover - compiled
    """``Scene._surface_candidates`` of one point into ``off`` (C, 2) and ``cand_d`` (C,):
    the box's four walls, then the capsules of the point's index row."""
    nbox = 0
    if has_box:
        gaps = (box[2] - px, box[3] - py, px - box[0], py - box[1])
        for w in range(4):
            off[w, 0] = _BOX_DIRECTIONS[w, 0] * gaps[w]
            off[w, 1] = _BOX_DIRECTIONS[w, 1] * gaps[w]
            cand_d[w] = gaps[w]
        nbox = 4
    if has_shapes:
        row = _index_row(px, py, origin, shape)
        for s in range(table.shape[1]):
            q = table[row, s]
            cx, cy, d = _closest(px, py, qa[q, 0], qa[q, 1], qb[q, 0], qb[q, 1])
            scale = (d - qr[q]) / d if d > 0 else 0.0
            off[nbox + s, 0] = (cx - px) * scale
            off[nbox + s, 1] = (cy - py) * scale
            gap = d - qr[q]
            cand_d[nbox + s] = gap if gap > 0.0 else 0.0


@njit(cache=True)
def _pick_slots(off, cand_d, reach, sector_cos, offsets, valid, i):  # pragma: no cover
    """``Scene.nearest_points``' choice of one point's slots among its candidates."""
    c = cand_d.shape[0]
    slots = valid.shape[1]
    dist = np.empty(c)
    for s in range(c):
        dist[s] = cand_d[s] if cand_d[s] <= reach else np.inf
    for k in range(slots):
        pick = 0
        for s in range(1, c):
            if dist[s] < dist[pick]:
                pick = s
        d = dist[pick]
        if not math.isfinite(d):
            return  # this slot and the later ones stay empty
        chx = off[pick, 0]
        chy = off[pick, 1]
        offsets[i, k, 0] = chx
        offsets[i, k, 1] = chy
        valid[i, k] = True
        for s in range(c if k + 1 < slots else 0):
            den = cand_d[s] * d
            den = den if den > 1e-300 else 1e-300
            if (off[s, 0] * chx + off[s, 1] * chy) / den > sector_cos:
                dist[s] = np.inf


_BOX_DIRECTIONS = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
"""The box's walls' directions (east, north, west, south), as ``Scene`` has them."""


@njit(cache=True)
def nearest_points(points, slots, reach, box, has_box, qa, qb, qr, table, origin, shape,
                   has_shapes, sector_cos):  # pragma: no cover - compiled
    """``Scene.nearest_points``: ``(offsets (P, slots, 2), valid (P, slots))``. ``box``
    (xmin, ymin, xmax, ymax) counts when ``has_box``; ``qa, qb, qr`` are the padded query
    capsules, ``table, origin, shape`` the index for ``reach`` (when ``has_shapes``)."""
    p = points.shape[0]
    c = (4 if has_box else 0) + (table.shape[1] if has_shapes else 0)
    offsets = np.zeros((p, slots, 2))
    valid = np.zeros((p, slots), dtype=np.bool_)
    off = np.empty((c, 2))
    cand_d = np.empty(c)
    for i in range(p):
        _surface_candidates(points[i, 0], points[i, 1], box, has_box, qa, qb, qr, table,
                            origin, shape, has_shapes, off, cand_d)
        if c:
            _pick_slots(off, cand_d, reach, sector_cos, offsets, valid, i)
    return offsets, valid


@njit(cache=True)
def shape_clearance(points, qa, qb, qr, table, origin, shape):  # pragma: no cover
    """``Scene._shape_clearance``: each point's distance (P,) to the nearest candidate
    capsule surface (inf with none)."""
    p = points.shape[0]
    out = np.empty(p)
    for i in range(p):
        px = points[i, 0]
        py = points[i, 1]
        row = _index_row(px, py, origin, shape)
        best = np.inf
        for s in range(table.shape[1]):
            q = table[row, s]
            d = _closest(px, py, qa[q, 0], qa[q, 1], qb[q, 0], qb[q, 1])[2] - qr[q]
            best = d if d < best else best
        out[i] = best
    return out


@njit(cache=True)
def capsule_clearance(points, qa, qb, qr):  # pragma: no cover - compiled
    """``Scene.clearance``'s capsule part: each point's distance (P,) to the nearest of all
    capsule surfaces (a minimum: exact in any order)."""
    out = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        best = np.inf
        for q in range(qr.shape[0]):
            d = _closest(points[i, 0], points[i, 1], qa[q, 0], qa[q, 1], qb[q, 0],
                         qb[q, 1])[2] - qr[q]
            best = d if d < best else best
        out[i] = best
    return out


@njit(cache=True)
def occupied(points, cells, resolution, x0, y0, c, s):  # pragma: no cover - compiled
    """``OccupancyGrid.occupied``: whether each point lies in an occupied or unknown cell or
    off the map (``c, s``: the cosine and sine of the map's yaw)."""
    h, w = cells.shape
    out = np.ones(points.shape[0], dtype=np.bool_)
    for i in range(points.shape[0]):
        rx = points[i, 0] - x0
        ry = points[i, 1] - y0
        col = math.floor((rx * c + ry * s) / resolution)
        row = math.floor((-rx * s + ry * c) / resolution)
        if 0 <= col < w and 0 <= row < h:
            out[i] = cells[row, col] != 0
    return out


@njit(cache=True)
def within(points, reach, shapes, qa, qb, qr, table, origin, shape, grid, cells, resolution,
           x0, y0, c, s):  # pragma: no cover - compiled
    """``Scene.within`` of a scene without a box or polygons in one call: a point's
    :func:`shape_clearance` at most ``reach`` (with ``shapes``) or :func:`occupied` (with
    ``grid``)."""
    out = np.zeros(points.shape[0], dtype=np.bool_)
    if shapes:
        clearance = shape_clearance(points, qa, qb, qr, table, origin, shape)
        for i in range(points.shape[0]):
            out[i] = clearance[i] <= reach
    if grid:
        cell = occupied(points, cells, resolution, x0, y0, c, s)
        for i in range(points.shape[0]):
            out[i] = out[i] | cell[i]
    return out


@njit(cache=True)
def box_within(points, box, margins):  # pragma: no cover - compiled
    """``Scene._box_within``: whether each point (P, 2) is within the sum of ``margins`` of
    the box (xmin, ymin, xmax, ymax)'s walls, the margins subtracted one by one from the
    far corner and the negated near one, as the study's arena code did."""
    hx, hy, lx, ly = box[2], box[3], -box[0], -box[1]
    for m in margins:
        hx = hx - m
        hy = hy - m
        lx = lx - m
        ly = ly - m
    out = np.empty(points.shape[0], dtype=np.bool_)
    for i in range(points.shape[0]):
        px, py = points[i, 0], points[i, 1]
        out[i] = (px >= hx) | (py >= hy) | (-px >= lx) | (-py >= ly)
    return out


@njit(cache=True)
def _segments_distance(p0x, p0y, p1x, p1y, ax, ay, bx, by):  # pragma: no cover - compiled
    """``geometry.segments_distance`` of two segments (0 where they cross)."""
    d0 = _closest(p0x, p0y, ax, ay, bx, by)[2]
    d1 = _closest(p1x, p1y, ax, ay, bx, by)[2]
    d2 = _closest(ax, ay, p0x, p0y, p1x, p1y)[2]
    d3 = _closest(bx, by, p0x, p0y, p1x, p1y)[2]
    first = d0 if d0 < d1 else d1
    second = d2 if d2 < d3 else d3
    d = first if first < second else second
    ux = p1x - p0x
    uy = p1y - p0y
    vx = bx - ax
    vy = by - ay
    wx = ax - p0x
    wy = ay - p0y
    denom = ux * vy - uy * vx
    if denom != 0:
        s = (wx * vy - wy * vx) / denom
        t = (wx * uy - wy * ux) / denom
        if 0 <= s <= 1 and 0 <= t <= 1:
            return 0.0
    return d


@njit(cache=True)
def segments_blocked(starts, ends, qa, qb, qr, clearance):  # pragma: no cover - compiled
    """``Scene.blocked``'s capsule test: for each segment (L,) the first capsule it passes
    within ``clearance`` of (``segments_distance - radius < clearance``), -1 where none."""
    out = np.full(starts.shape[0], -1, dtype=np.intp)
    for i in range(starts.shape[0]):
        for q in range(qr.shape[0]):
            d = _segments_distance(starts[i, 0], starts[i, 1], ends[i, 0], ends[i, 1],
                                   qa[q, 0], qa[q, 1], qb[q, 0], qb[q, 1])
            if d - qr[q] < clearance:
                out[i] = q
                break
    return out


@njit(cache=True)
def _ray_circle(ox, oy, dx, dy, cx, cy, r):  # pragma: no cover - compiled
    """``geometry.ray_circles`` of one ray and circle."""
    relx = cx - ox
    rely = cy - oy
    along = relx * dx + rely * dy
    across2 = (relx * relx + rely * rely) - along * along
    disc = r * r - across2
    root = math.sqrt(disc if disc > 0.0 else 0.0)
    if relx * relx + rely * rely <= r * r:
        return 0.0
    t = along - root
    if disc >= 0 and along + root >= 0 and t >= 0:
        return t
    return np.inf


@njit(cache=True)
def _ray_segment(ox, oy, dx, dy, ax, ay, bx, by):  # pragma: no cover - compiled
    """``geometry.ray_segments`` of one ray and segment."""
    vx = bx - ax
    vy = by - ay
    wx = ax - ox
    wy = ay - oy
    denom = dx * vy - dy * vx
    if denom == 0:
        return np.inf
    t = (wx * vy - wy * vx) / denom
    s = (wx * dy - wy * dx) / denom
    return t if t >= 0 and s >= 0 and s <= 1 else np.inf


@njit(cache=True)
def _ray_capsule(ox, oy, dx, dy, ax, ay, bx, by, r):  # pragma: no cover - compiled
    """``geometry.ray_capsules`` of one ray and capsule."""
    e0 = _ray_circle(ox, oy, dx, dy, ax, ay, r)
    e1 = _ray_circle(ox, oy, dx, dy, bx, by, r)
    ends = e0 if e0 < e1 else e1
    vx = bx - ax
    vy = by - ay
    length = math.sqrt(vx * vx + vy * vy)
    sides = np.inf
    if length > 0:
        offx = (-vy / length) * r
        offy = (vx / length) * r
        s0 = _ray_segment(ox, oy, dx, dy, ax + offx, ay + offy, bx + offx, by + offy)
        s1 = _ray_segment(ox, oy, dx, dy, ax - offx, ay - offy, bx - offx, by - offy)
        sides = s0 if s0 < s1 else s1
    if _closest(ox, oy, ax, ay, bx, by)[2] <= r:
        return 0.0
    return ends if ends < sides else sides


@njit(cache=True)
def raycast(origins, directions, box, has_box, qa, qb, qr, table, origin, shape,
            has_shapes):  # pragma: no cover - compiled
    """``Scene.raycast`` before its map cells and range cap: the distance (P, R) along each
    ray ``directions`` (P, R, 2) from ``origins`` (P, 2) to the box's walls and the
    capsules of each origin's index row (inf where none)."""
    p, rays = directions.shape[0], directions.shape[1]
    out = np.full((p, rays), np.inf)
    for i in range(p):
        ox = origins[i, 0]
        oy = origins[i, 1]
        row = _index_row(ox, oy, origin, shape) if has_shapes else 0
        for k in range(rays):
            dx = directions[i, k, 0]
            dy = directions[i, k, 1]
            best = np.inf
            if has_box:
                tx = ((box[2] - ox) / dx if dx > 0 else
                      ((box[0] - ox) / dx if dx < 0 else np.inf))
                ty = ((box[3] - oy) / dy if dy > 0 else
                      ((box[1] - oy) / dy if dy < 0 else np.inf))
                best = tx if tx < ty else ty
                best = best if best > 0.0 else 0.0
            if has_shapes:
                hit = np.inf
                for s in range(table.shape[1]):
                    q = table[row, s]
                    h = _ray_capsule(ox, oy, dx, dy, qa[q, 0], qa[q, 1], qb[q, 0], qb[q, 1],
                                     qr[q])
                    hit = h if h < hit else hit
                best = best if best < hit else hit
            out[i, k] = best
    return out


@njit(cache=True)
def ray_circles_nearest(origins, directions, centres, radii):  # pragma: no cover - compiled
    """``observations.sensing._ranges_along``' robot discs: the distance (F, R) along each ray to
    the nearest of each follower's discs ``centres`` (F, K, 2) of ``radii`` (F, K)."""
    f, rays = directions.shape[0], directions.shape[1]
    out = np.empty((f, rays))
    for i in range(f):
        for k in range(rays):
            hit = np.inf
            for j in range(centres.shape[1]):
                h = _ray_circle(origins[i, 0], origins[i, 1], directions[i, k, 0],
                                directions[i, k, 1], centres[i, j, 0], centres[i, j, 1],
                                radii[i, j])
                hit = h if h < hit else hit
            out[i, k] = hit
    return out
