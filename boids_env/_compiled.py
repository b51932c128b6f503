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
               scale, counts, terms):  # pragma: no cover - compiled
    """``metrics.violation_flags`` of one step, added to ``counts`` (3, F) and scaled into
    ``terms[:3]`` (−weight · dt · flag, as ``np.multiply(scale, flags)``). ``angle`` (N,) is
    numpy's ``arctan2`` of the commands (rad)."""
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
        for row in range(3):
            counts[row, i] += flags[row]
            terms[row, i] = scale[row] * (1.0 if flags[row] else 0.0)


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
