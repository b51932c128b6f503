"""The numba kernels behind :mod:`boids_env.kernels` (imported on first use, never at
``import boids_env``). Each is a loop port of a numpy reference and rounds exactly as it does:
no ``fastmath`` (LLVM then never contracts ``a * b + c`` into one fused multiply-add, which
rounds once instead of twice), the same operations in the same order, ``sqrt`` and the
float64 → float32 cast (both correctly rounded), and no transcendental function (numpy's SIMD
``arctan2`` and the C library's differ in the last bit: the angles come in from numpy).
``cache=True``: compiled once per machine into ``__pycache__``, loaded afterwards."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def nearest(positions, horizon, k):  # pragma: no cover - compiled
    """``observations.nearest_neighbours`` for all pairs: the ``k`` nearest robots within
    ``horizon`` of every follower, nearest first, exact ties by index (numpy's stable
    argsort), -1 and inf in empty slots."""
    n = positions.shape[0]
    followers = n - 1
    index = np.full((followers, k), -1, dtype=np.intp)
    distance = np.full((followers, k), np.inf)
    for i in range(followers):
        px = positions[i + 1, 0]
        py = positions[i + 1, 1]
        count = 0
        for j in range(n):
            dx = px - positions[j, 0]
            dy = py - positions[j, 1]
            d = math.sqrt(dx * dx + dy * dy)
            if d <= 0.0 or d > horizon:
                continue
            if count == k and not d < distance[i, k - 1]:
                continue  # a tie with the last slot: the lower index keeps it
            m = count if count < k else k - 1
            while m > 0 and distance[i, m - 1] > d:
                distance[i, m] = distance[i, m - 1]
                index[i, m] = index[i, m - 1]
                m -= 1
            distance[i, m] = d
            index[i, m] = j
            if count < k:
                count += 1
    return index, distance


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
        rank = 0
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


@njit(cache=True)
def reynolds_forces(obs, start, k, horizon, desired, max_force,
                    max_speed):  # pragma: no cover - compiled
    """``policies.reynolds.reynolds_forces``'s separation, cohesion and alignment (F, 2)
    each, from observations ``obs`` (F, D) float64 whose own velocity is columns 0:2 and
    whose ``k`` neighbour slots start at column ``start``. Each sum over the slots runs in
    slot order from 0.0, one product added at a time, as numpy's ``einsum`` contractions
    there do (the same bits: tested against them), and the divisions, clips and the
    ``has``-neighbour factor are the numpy code's, in its order."""
    rows = obs.shape[0]
    separation = np.empty((rows, 2))
    cohesion = np.empty((rows, 2))
    alignment = np.empty((rows, 2))
    pull = max_force / horizon
    for f in range(rows):
        count = 0.0
        close = 0
        m0 = 0.0
        m1 = 0.0
        p0 = 0.0
        p1 = 0.0
        t0 = 0.0
        t1 = 0.0
        for j in range(k):
            c = start + 5 * j
            r0 = obs[f, c]
            r1 = obs[f, c + 1]
            d = math.sqrt(r0 * r0 + r1 * r1)
            near = obs[f, c + 4] > 0.5 and d > 0 and d <= horizon
            w = 1.0 if near else 0.0
            count += w
            m0 += w * r0
            m1 += w * r1
            t0 += w * obs[f, c + 2]
            t1 += w * obs[f, c + 3]
            inv_cube = 0.0
            if near and d < desired:
                close += 1
                inv_cube = 1.0 / (d * d * d)
            p0 += inv_cube * r0
            p1 += inv_cube * r1
        n = max(count, 1.0)
        cohesion[f, 0] = pull * (m0 / n)
        cohesion[f, 1] = pull * (m1 / n)
        n = float(max(close, 1))
        x0 = -p0 / n
        x1 = -p1 / n
        norm = math.sqrt(x0 * x0 + x1 * x1)
        scale = min(1.0, (2 * max_force) / max(norm, 1e-300))
        separation[f, 0] = x0 * scale
        separation[f, 1] = x1 * scale
        norm = math.sqrt(t0 * t0 + t1 * t1)
        d0 = t0 / norm if norm > 0 else 1.0
        d1 = t1 / norm if norm > 0 else 0.0
        a0 = d0 * max_speed - obs[f, 0]
        a1 = d1 * max_speed - obs[f, 1]
        norm = math.sqrt(a0 * a0 + a1 * a1)
        scale = min(1.0, max_force / max(norm, 1e-300))
        has = 1.0 if count > 0 else 0.0
        alignment[f, 0] = (a0 * scale) * has
        alignment[f, 1] = (a1 * scale) * has
    return separation, cohesion, alignment


@njit(cache=True)
def _clip(x, bound):  # pragma: no cover - compiled
    """``np.minimum(np.maximum(x, -bound), bound)`` of one finite value."""
    low = x if x > -bound else -bound
    return low if low < bound else bound


@njit(cache=True)
def fill_observations(positions, velocities, index, velocity_bound, reach, obs,
                      start):  # pragma: no cover - compiled
    """The study's blocks of every follower's observation row in ``obs`` (F, size) float32:
    own velocity, leader position, leader velocity and the neighbour slots of ``index``
    (F, K) from column ``start`` on, as ``observations.build_observations`` writes them."""
    followers = positions.shape[0] - 1
    k = index.shape[1]
    lvx = _clip(velocities[0, 0], velocity_bound)
    lvy = _clip(velocities[0, 1], velocity_bound)
    for i in range(followers):
        r = i + 1
        px = positions[r, 0]
        py = positions[r, 1]
        obs[i, 0] = _clip(velocities[r, 0], velocity_bound)
        obs[i, 1] = _clip(velocities[r, 1], velocity_bound)
        obs[i, 2] = _clip(positions[0, 0] - px, reach)
        obs[i, 3] = _clip(positions[0, 1] - py, reach)
        obs[i, 4] = lvx
        obs[i, 5] = lvy
        for s in range(k):
            j = index[i, s]
            c = start + 5 * s
            if j < 0:
                for q in range(5):
                    obs[i, c + q] = 0.0
            else:
                obs[i, c] = positions[j, 0] - px
                obs[i, c + 1] = positions[j, 1] - py
                obs[i, c + 2] = _clip(velocities[j, 0], velocity_bound)
                obs[i, c + 3] = _clip(velocities[j, 1], velocity_bound)
                obs[i, c + 4] = 1.0


@njit(cache=True)
def violations(positions, commanded, angle, separation, cohesion, alignment_deg, wrap,
               scale, counts, codes, terms):  # pragma: no cover - compiled
    """``metrics.violation_flags`` of one step, added to ``counts`` (3, F) and scaled into
    ``terms[:3]`` (−weight · dt · flag, as ``np.multiply(scale, flags)``); each follower's
    three flags as the bits of ``codes`` (F,) (separation 1, cohesion 2, alignment 4: which
    info dict it gets). ``angle`` (N,) is numpy's ``arctan2`` of the commands (rad)."""
    followers = positions.shape[0] - 1
    still0 = commanded[0, 0] == 0 and commanded[0, 1] == 0
    lead = 0.0 if still0 else np.degrees(angle[0])
    for i in range(followers):
        r = i + 1
        ox = positions[r, 0] - positions[0, 0]
        oy = positions[r, 1] - positions[0, 1]
        d = math.sqrt(ox * ox + oy * oy)
        still = commanded[r, 0] == 0 and commanded[r, 1] == 0
        heading = 0.0 if still else np.degrees(angle[r])
        diff = abs(lead - heading)
        turn = min(diff, 360.0 - diff) if wrap else diff
        flags = (d < separation, d > cohesion, turn > alignment_deg)
        code = 0
        for row in range(3):
            counts[row, i] += flags[row]
            terms[row, i] = scale[row] * (1.0 if flags[row] else 0.0)
            code += (1 << row) if flags[row] else 0
        codes[i] = code


@njit(cache=True)
def _rotated(v, m):  # pragma: no cover - compiled
    """``vectors.times_matrix(v, m)``: rows (M, 2) into the frame of the (2, 2) ``m``."""
    out = np.empty_like(v)
    for i in range(v.shape[0]):
        out[i, 0] = v[i, 0] * m[0, 0] + v[i, 1] * m[1, 0]
        out[i, 1] = v[i, 0] * m[0, 1] + v[i, 1] * m[1, 1]
    return out


@njit(cache=True)
def unicycle_substep(buffer, n, hx, hy, c, s, turn, theta, velocities, speed
                     ):  # pragma: no cover - compiled
    """``Unicycle._substep``'s arithmetic in one loop: every heading (``hx``, ``hy``) turned
    by the substep's (``c``, ``s``), ``theta`` advanced by ``turn``, the robots' velocities
    (``velocities``, pymunk's flat read) copied into ``buffer``'s rows ``0..n-1`` and the
    control bodies' rows ``n..2n-1`` pointed along the new heading at ``speed`` (angle, vx,
    vy). The same products, sums and roundings as the numpy code, element by element."""
    for i in range(n):
        x = hx[i]
        y = hy[i]
        nx = x * c[i]
        nx -= y * s[i]
        ny = x * s[i]
        ny += y * c[i]
        hx[i] = nx
        hy[i] = ny
        theta[i] += turn[i]
        buffer[i, 1] = velocities[2 * i]
        buffer[i, 2] = velocities[2 * i + 1]
        buffer[n + i, 0] = theta[i]
        buffer[n + i, 1] = nx * speed[i]
        buffer[n + i, 2] = ny * speed[i]


@njit(cache=True)
def batch_after(positions, velocities, commanded, angle, ints, params, bounds, counts, codes,
                obs, terms):  # pragma: no cover - compiled
    """The study's observations, violation flags and reward terms of K copies in one call.

    Copy ``c`` has robots ``ints[c, 0]:ints[c, 1]`` of the concatenated ``positions``,
    ``velocities``, ``commanded`` and ``angle`` (its leader first) and its followers' rows
    from ``ints[c, 2]`` on in ``obs``, ``terms`` and ``counts``; ``ints[c, 3:6]``: whether it
    observes in the leader frame, its neighbour slots, the column of its first slot;
    ``params[c]``: horizon, velocity bound, reach, the separation, cohesion and alignment
    thresholds, wrap, the three reward scales, then its frame's matrix (row by row);
    ``bounds[c]``: its Box's low and high. Each copy's arrays go through :func:`nearest`,
    :func:`fill_observations` and :func:`violations` as one env's do (rotated into its frame
    first, and then clipped to the Box as numpy's array ``clip`` does: the bound on a tie);
    ``codes``: each follower's flags as :func:`violations` writes them."""
    for c in range(ints.shape[0]):
        a = ints[c, 0]
        b = ints[c, 1]
        r0 = ints[c, 2]
        r1 = r0 + (b - a - 1)
        k = ints[c, 4]
        pos = positions[a:b]
        vel = velocities[a:b]
        if ints[c, 3]:
            frame = params[c, 10:14].reshape(2, 2)
            pos = _rotated(pos, frame)
            vel = _rotated(vel, frame)
        if k > 0 and b - a > 1:
            index = nearest(pos, params[c, 0], k)[0]
        else:
            index = np.full((b - a - 1, k), -1, dtype=np.intp)
        block = obs[r0:r1]
        fill_observations(pos, vel, index, params[c, 1], params[c, 2], block, ints[c, 5])
        if ints[c, 3]:
            low = bounds[c, 0]
            high = bounds[c, 1]
            for i in range(block.shape[0]):
                for j in range(block.shape[1]):
                    x = block[i, j]
                    x = x if x > low[j] else low[j]
                    block[i, j] = x if x < high[j] else high[j]
        violations(positions[a:b], commanded[a:b], angle[a:b], params[c, 3], params[c, 4],
                   params[c, 5], params[c, 6] != 0.0, params[c, 7:10], counts[:, r0:r1],
                   codes[r0:r1], terms[:, r0:r1])


@njit(cache=True)
def clip_speed(v, limit):  # pragma: no cover - compiled
    """``vectors.clip_speed`` of rows (M, 2) whose speeds are all finite: ``(status, out)``,
    status 0 when no row is over the limit (``out`` is ``v``), 1 when scaled, 2 when some
    speed overflows (the caller's numpy path then handles it)."""
    rows = v.shape[0]
    speed = np.empty(rows)
    over = False
    for i in range(rows):
        s = math.sqrt(v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1])
        if not math.isfinite(s):
            return 2, v
        speed[i] = s
        over = over or s > limit
    if not over:
        return 0, v
    out = np.empty_like(v)
    for i in range(rows):
        scale = min(1.0, limit / max(speed[i], 1e-300))
        out[i, 0] = v[i, 0] * scale
        out[i, 1] = v[i, 1] * scale
    return 1, out


@njit(cache=True)
def nearest_other(positions):  # pragma: no cover - compiled
    """Every follower's distance (F,) to the nearest other robot (the leader included), as
    ``cKDTree(positions).query(positions[1:], k=2)[0][:, 1]`` gives it (a robot exactly on
    another: 0)."""
    n = positions.shape[0]
    out = np.empty(n - 1)
    for i in range(1, n):
        best = np.inf
        for j in range(n):
            if j == i:
                continue
            dx = positions[i, 0] - positions[j, 0]
            dy = positions[i, 1] - positions[j, 1]
            d = dx * dx + dy * dy
            if d < best:
                best = d
        out[i - 1] = math.sqrt(best)
    return out


@njit(cache=True)
def safety_gap_terms(positions, near_static, safety_scale, safety_distance,
                     contact_distance, safety_on, gap_scale, cohesion_threshold, gap_on,
                     terms):  # pragma: no cover - compiled
    """The env's opt-in safety rows (``terms[3:6]``: ``safety_scale[r] × flag``, the flags of
    ``metrics.safety_flags`` from :func:`nearest_other`'s distances and ``near_static``) and
    cohesion-gap row (``terms[6]``: ``gap_scale × max(d − threshold, 0)``, ``d`` the straight
    distance to the leader as ``np.linalg.norm`` computes it: ``sqrt(dx·dx + dy·dy)``), as
    ``BoidsEnv._safety_terms`` and ``_gap_term`` compute them (a flag as 1.0 or 0.0 times its
    scale: an unflagged term is ``scale × 0.0``, −0.0 for a negative scale)."""
    f = positions.shape[0] - 1
    if safety_on:
        nearest = nearest_other(positions)
        for i in range(f):
            d = nearest[i]
            terms[3, i] = safety_scale[0] * (1.0 if d < safety_distance else 0.0)
            terms[4, i] = safety_scale[1] * (1.0 if d < contact_distance else 0.0)
            terms[5, i] = safety_scale[2] * (1.0 if near_static[i] else 0.0)
    if gap_on:
        lx = positions[0, 0]
        ly = positions[0, 1]
        for i in range(f):
            dx = positions[i + 1, 0] - lx
            dy = positions[i + 1, 1] - ly
            excess = math.sqrt(dx * dx + dy * dy) - cohesion_threshold
            # np.maximum(excess, 0.0): a NaN stays NaN, a tie keeps the first (+0.0 either way)
            gap = excess if (excess >= 0.0 or excess != excess) else 0.0
            terms[6, i] = gap_scale * gap


# ------------------------------------------------------------------ static geometry
# Ports of boids_env.world.scene's queries on its capsules: the same candidate lists (the
# scene's spatial index, looked up here), the same operations in the same order as
# boids_env.world.geometry.closest_on_segments, numpy's minimum and maximum as ``a < b ? a : b``
# and ``a > b ? a : b`` and its clip as two comparisons that keep ``x`` unless it is out of
# range (numpy's own rules: signed zeros come out the same).


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
def static_block(offsets, valid, frame, turned):  # pragma: no cover - compiled
    """``observations._static_block`` from ``Scene.nearest_points``'s offsets (P, M, 2) and
    valid flags (P, M): (P, 3M) float64, each slot's offset turned into ``frame`` (when
    ``turned``; ``vectors.times_matrix``'s products and add) times its flag, then the flag."""
    p, slots = valid.shape
    out = np.empty((p, 3 * slots))
    for i in range(p):
        for k in range(slots):
            x, y = offsets[i, k, 0], offsets[i, k, 1]
            if turned:
                x, y = (x * frame[0, 0] + y * frame[1, 0], x * frame[0, 1] + y * frame[1, 1])
            flag = 1.0 if valid[i, k] else 0.0
            out[i, 3 * k] = x * flag
            out[i, 3 * k + 1] = y * flag
            out[i, 3 * k + 2] = flag
    return out


@njit(cache=True)
def noisy_observations(obs, noise, scaled, flags, zeroed, low, high):  # pragma: no cover
    """``Observer``'s sensing noise and bounds: ``noise`` (F, D) float64 (numpy's draw,
    overwritten) times each ``scaled`` column's valid flag (the ``flags`` column of ``obs``),
    zero in the ``zeroed`` columns, added to ``obs`` (F, D) float32 in float64, clipped to
    ``low`` and ``high`` as ``np.clip`` does (a NaN stays; ``x > lo ? x : lo``, then
    ``x < hi ? x : hi``) and rounded to float32."""
    rows, cols = obs.shape
    out = np.empty((rows, cols), dtype=np.float32)
    for i in range(rows):
        for q in range(scaled.shape[0]):
            noise[i, scaled[q]] = noise[i, scaled[q]] * np.float64(obs[i, flags[q]])
        for q in range(zeroed.shape[0]):
            noise[i, zeroed[q]] = 0.0
        for c in range(cols):
            v = np.float64(obs[i, c]) + noise[i, c]
            if not math.isnan(v):
                lo = np.float64(low[c])
                hi = np.float64(high[c])
                v = v if v > lo else lo
                v = v if v < hi else hi
            out[i, c] = np.float32(v)
    return out


@njit(cache=True)
def in_sight_ahead(points, node, nxt, centres, free, origin_x, origin_y, cell, t,
                   steps):  # pragma: no cover - compiled
    """``route._in_sight_ahead``: the farthest node up to ``steps`` nodes along each
    follower's route (``nxt``) that it sees through free cells (``free`` (H, W)) at the
    samples ``t`` of each sight line, every earlier one seen too; the next node where it
    sees none."""
    h, w = free.shape
    out = np.empty(points.shape[0], dtype=np.intp)
    for i in range(points.shape[0]):
        px = points[i, 0]
        py = points[i, 1]
        cur = nxt[node[i]]
        best = cur
        for _ in range(steps):
            ex = centres[cur, 0] - px
            ey = centres[cur, 1] - py
            seen = True
            for s in range(1, t.shape[0]):  # the follower's own spot may touch a wall
                col = math.floor((px + t[s] * ex - origin_x) / cell)
                row = math.floor((py + t[s] * ey - origin_y) / cell)
                if not (0 <= col < w and 0 <= row < h and free[row, col]):
                    seen = False
                    break
            if not seen:
                break
            best = cur
            cur = nxt[cur]
        out[i] = best
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
    """``observations._ranges_along``' robot discs: the distance (F, R) along each ray to
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


# ------------------------------------------------------------------ the safety filter
_FREE = 1e9
_TOLERANCE = 1e-9


@njit(cache=True)
def _static_rows(surfaces, valid, i, radius, alpha, margin, a, b, hard):  # pragma: no cover
    """``barrier_constraints``' rows of follower ``i``'s surface points (the first M)."""
    for s in range(surfaces.shape[1]):
        sx = surfaces[i, s, 0]
        sy = surfaces[i, s, 1]
        d = math.sqrt(sx * sx + sy * sy)
        if valid[i, s] and d > 0.0:
            a[s, 0] = sx / d
            a[s, 1] = sy / d
            b[s] = alpha * (d - radius - margin)
        else:
            a[s, 0] = 0.0
            a[s, 1] = 0.0
            b[s] = _FREE
        hard[s] = True


@njit(cache=True)
def _robots_in_reach(positions, r, reach, k, order, dists):  # pragma: no cover - compiled
    """The robots within ``reach`` of robot ``r`` into ``order``/``dists``, nearest first:
    their count, or -1 where the KD-tree would decide (a robot exactly on ``r`` or at
    ``reach`` within 1e-9, two of the ``k + 1`` nearest exactly equally far)."""
    n = positions.shape[0]
    px = positions[r, 0]
    py = positions[r, 1]
    count = 0
    for j in range(n):
        if j == r:
            continue
        dx = px - positions[j, 0]
        dy = py - positions[j, 1]
        d = math.sqrt(dx * dx + dy * dy)
        if not d > 0.0 or abs(d - reach) <= 1e-9 * reach:
            return -1
        if d >= reach:
            continue
        q = count
        while q > 0 and dists[q - 1] > d:
            dists[q] = dists[q - 1]
            order[q] = order[q - 1]
            q -= 1
        dists[q] = d
        order[q] = j
        count += 1
    for q in range(min(count - 1, k)):
        if dists[q] == dists[q + 1]:
            return -1
    return count


@njit(cache=True)
def _robot_rows(positions, velocities, lead, r, count, order, dists, radius, alpha, margin,
                m, a, b, hard):  # pragma: no cover - compiled
    """``barrier_constraints``' rows of robot ``r``'s nearest robots (after the first M)."""
    px = positions[r, 0]
    py = positions[r, 1]
    for s in range(b.shape[0] - m):
        row = m + s
        if s >= count:
            a[row, 0] = 0.0
            a[row, 1] = 0.0
            b[row] = _FREE
            hard[row] = False
            continue
        j = order[s]
        d = dists[s]
        ax = (positions[j, 0] - px) / d
        ay = (positions[j, 1] - py) / d
        a[row, 0] = ax
        a[row, 1] = ay
        gap = alpha * (d - 2.0 * radius - margin)
        if j == 0:
            b[row] = gap + (lead[0] * ax + lead[1] * ay)
        else:
            own = velocities[r, 0] * ax + velocities[r, 1] * ay
            theirs = velocities[j, 0] * ax + velocities[j, 1] * ay
            b[row] = 0.5 * gap + (own if own < theirs else theirs)
        hard[row] = j == 0


@njit(cache=True)
def safety_filter(commands, positions, velocities, lead, radius, alpha, margin, reach, k,
                  surfaces, valid):  # pragma: no cover - compiled
    """``world.safety``'s barrier constraints and ``nearest_allowed`` for every follower:
    ``(status, out (F, 2))``, status 1 where the numpy reference must run instead (two of a
    follower's nearest robots exactly equally far, one exactly on it or at ``reach`` within
    1e-9: the KD-tree's order and bound decide those; or a NaN)."""
    n = positions.shape[0]
    m = surfaces.shape[1]
    rows = m + k
    out = commands.copy()
    a = np.zeros((rows, 2))
    b = np.empty(rows)
    hard = np.zeros(rows, dtype=np.bool_)
    excess = np.empty(rows)
    order = np.empty(n, dtype=np.intp)
    dists = np.empty(n)
    for i in range(n - 1):
        _static_rows(surfaces, valid, i, radius, alpha, margin, a, b, hard)
        count = _robots_in_reach(positions, i + 1, reach, k, order, dists) if k else 0
        if count < 0:
            return 1, out
        _robot_rows(positions, velocities, lead, i + 1, count, order, dists, radius, alpha,
                    margin, m, a, b, hard)
        cx = out[i, 0]
        cy = out[i, 1]
        active = False
        for q in range(rows):
            excess[q] = a[q, 0] * cx + a[q, 1] * cy - b[q]
            if excess[q] != excess[q]:
                return 1, out
            active = active or excess[q] > _TOLERANCE
        if active:
            status, vx, vy = _solve(cx, cy, a, b, hard, excess)
            if status:
                return 1, out
            out[i, 0] = vx
            out[i, 1] = vy
    return 0, out


@njit(cache=True)
def _solve_candidates(cx, cy, a, b, excess):  # pragma: no cover - compiled
    """``safety._solve``'s candidates (C, 2): the command, its projections onto each line,
    the lines' crossings (i < j, row by row); which are real; which rows are used."""
    rows = b.shape[0]
    total = 1 + rows + rows * (rows - 1) // 2
    cand = np.empty((total, 2))
    real = np.empty(total, dtype=np.bool_)
    used = np.empty(rows, dtype=np.bool_)
    cand[0, 0] = cx
    cand[0, 1] = cy
    real[0] = True
    for q in range(rows):
        used[q] = a[q, 0] != 0.0 or a[q, 1] != 0.0
        cand[1 + q, 0] = cx - excess[q] * a[q, 0]
        cand[1 + q, 1] = cy - excess[q] * a[q, 1]
        real[1 + q] = used[q]
    c = 1 + rows
    for p in range(rows):
        for q in range(p + 1, rows):
            det = a[p, 0] * a[q, 1] - a[p, 1] * a[q, 0]
            crossing = abs(det) > 1e-9
            safe = det if crossing else 1.0
            cand[c, 0] = (b[p] * a[q, 1] - b[q] * a[p, 1]) / safe
            cand[c, 1] = (a[p, 0] * b[q] - a[q, 0] * b[p]) / safe
            real[c] = crossing and used[p] and used[q]
            c += 1
    return cand, real, used


@njit(cache=True)
def _violations(a, b, hard, used, x, y):  # pragma: no cover - compiled
    """A candidate's worst violation of all used rows, of the hard ones, of the soft ones
    (-inf where none; NaN if one is NaN)."""
    worst = -np.inf
    worst_hard = -np.inf
    worst_soft = -np.inf
    for q in range(b.shape[0]):
        if not used[q]:
            continue
        v = a[q, 0] * x + a[q, 1] * y - b[q]
        if v != v:
            return v, v, v
        worst = v if v > worst else worst
        if hard[q]:
            worst_hard = v if v > worst_hard else worst_hard
        else:
            worst_soft = v if v > worst_soft else worst_soft
    return worst, worst_hard, worst_soft


@njit(cache=True)
def _solve(cx, cy, a, b, hard, excess):  # pragma: no cover - compiled
    """``safety._solve`` of one follower: (status, vx, vy), status 1 on a NaN. Each pick is
    numpy's argmin: the first of equal keys."""
    cand, real, used = _solve_candidates(cx, cy, a, b, excess)
    best, best_d, soft, soft_v, least, least_v = 0, np.inf, 0, np.inf, 0, np.inf
    any_feasible = any_keeps = False
    for c in range(cand.shape[0]):
        worst, worst_hard, worst_soft = _violations(a, b, hard, used, cand[c, 0], cand[c, 1])
        if worst != worst:
            return 1, cx, cy
        if not real[c]:
            worst = worst_hard = np.inf
        dx = cand[c, 0] - cx
        dy = cand[c, 1] - cy
        feasible = worst <= _TOLERANCE
        any_feasible = any_feasible or feasible
        key = (dx * dx + dy * dy if real[c] else np.inf) if feasible else np.inf
        if key < best_d:
            best, best_d = c, key
        keeps = worst_hard <= _TOLERANCE
        any_keeps = any_keeps or keeps
        key = worst_soft if keeps else np.inf
        if key < soft_v:
            soft, soft_v = c, key
        if worst < least_v:
            least, least_v = c, worst
    pick = best if any_feasible else (soft if any_keeps else least)
    return 0, cand[pick, 0], cand[pick, 1]


# ------------------------------------------------------------------ exact MLP products
# boids_env.policies.exact's elementwise parts in loops: the integer slices before the
# products (which stay numpy's BLAS calls: exact in any order, see that module) and the sums,
# scalings, bias and tanh after them, the same + - * / in the same order.
_SLICE = 65536.0
_PADE_1680 = 1.0 / 1680.0
_PADE_3_28 = 3.0 / 28.0
_PADE_84 = 1.0 / 84.0
_HALVINGS = np.ldexp(1.0, -np.arange(65))
"""2^-k for k = 0..64: tanh's scalings (exact products)."""


@njit(cache=True)
def exact_slices(x):  # pragma: no cover - compiled
    """``exact.ExactLinear``'s integer slices of ``x`` (F, K) (float32 or float64, finite):
    ``(slices (2F, K), exponents (F,))``, the high slices' rows then the low ones'."""
    f, inputs = x.shape
    slices = np.empty((2 * f, inputs))
    exponents = np.empty(f, dtype=np.int64)
    for i in range(f):
        biggest = 0.0
        for j in range(inputs):
            v = abs(np.float64(x[i, j]))
            biggest = v if v > biggest else biggest
        e = math.frexp(biggest)[1]
        exponents[i] = e
        up = _power_of_two(16 - e)  # x * 2^k, correctly rounded: ldexp's bits
        for j in range(inputs):
            v = np.float64(x[i, j])
            scaled = v * up if up > 0.0 else math.ldexp(v, 16 - e)
            h = np.rint(scaled)
            slices[i, j] = h
            slices[f + i, j] = np.rint((scaled - h) * _SLICE)
    return slices, exponents


@njit(cache=True)
def exact_combine(both, exponents, column_scale, bias, activation, inv_ln2, ln2,
                  one):  # pragma: no cover - compiled
    """``exact.ExactLinear``'s result from the slices' products ``both`` (2F, H): the two
    slices added, scaled back, the bias added; then the activation (0 none, 1 tanh, 2
    ReLU)."""
    f = exponents.shape[0]
    outputs = both.shape[1]
    out = np.empty((f, outputs))
    for i in range(f):
        e = exponents[i]
        up = _power_of_two(e)
        for c in range(outputs):
            total = both[i, c] + both[f + i, c] * (1.0 / _SLICE)
            total = total * up if up > 0.0 else math.ldexp(total, e)
            out[i, c] = total * column_scale[0, c] + bias[c]
    if activation == 1:
        _exact_tanh(out, inv_ln2, ln2, one)
    elif activation == 2:
        for i in range(f):
            for c in range(outputs):
                out[i, c] = out[i, c] if out[i, c] > 0.0 else 0.0
    return out


@njit(cache=True)
def exact_combine_slices(both, exponents, column_scale, bias, activation, inv_ln2, ln2,
                         one):  # pragma: no cover - compiled
    """A hidden layer's :func:`exact_combine`, then the next layer's :func:`exact_slices`
    of it, in one call."""
    return exact_slices(exact_combine(both, exponents, column_scale, bias, activation,
                                      inv_ln2, ln2, one))


@njit(cache=True)
def _power_of_two(k):  # pragma: no cover - compiled
    """2^k where it is a normal float64 (then ``x * 2^k`` is ``ldexp(x, k)``: both the
    correctly rounded x·2^k), else 0."""
    return math.ldexp(1.0, k) if -1022 <= k <= 1023 else 0.0


@njit(cache=True)
def _exact_tanh(y, inv_ln2, ln2, one):  # pragma: no cover - compiled
    """``exact.tanh`` in place."""
    f, h = y.shape
    for i in range(f):
        for c in range(h):
            v = y[i, c]
            t = abs(v)
            t = t if t < one else one
            z = t * -2.0
            kz = z * inv_ln2
            k = np.rint(kz if kz >= -64.0 else -64.0)
            r = z - k * ln2
            r2 = r * r
            even = (r2 * _PADE_1680 + _PADE_3_28) * r2 + 1.0
            odd = (r2 * _PADE_84 + 0.5) * r
            n = int(k)
            scaled = ((even + odd) * _HALVINGS[-n] if -64 <= n <= 0
                      else math.ldexp(even + odd, n))
            den = even - odd
            y[i, c] = math.copysign((den - scaled) / (den + scaled), v)


@njit(cache=True)
def clip_actions(y, low, high):  # pragma: no cover - compiled
    """``MLPActor.act_batch``'s last step: ``np.clip(y.reshape(-1, 2), low, high)`` as
    float32 (the clip keeps ``v`` unless it is out of range, as numpy's does)."""
    flat = y.reshape(-1, 2)
    out = np.empty(flat.shape, dtype=np.float32)
    for i in range(flat.shape[0]):
        for c in range(2):
            v = flat[i, c]
            lo = np.float64(low[c])
            hi = np.float64(high[c])
            v = lo if v < lo else v
            v = hi if v > hi else v
            out[i, c] = np.float32(v)
    return out
