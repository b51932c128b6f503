"""The safety filter (:func:`boids_env.world.safety.filter_commands`): each follower's barrier
constraints of walls and robots and the nearest allowed command, declining (status 1) where
the KD-tree's order or bound would decide."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

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
