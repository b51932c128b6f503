"""The observations' opt-in blocks: the static slots' turn into the frame, the sensing noise
with the Box's clip (:class:`boids_env.observations.Observer`), and route sensing's sight
lines along each follower's route (:mod:`boids_env.world.route`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def static_block(offsets, valid, frame, turned):  # pragma: no cover - compiled
    """``observations.sensing.static_block`` from ``Scene.nearest_points``'s offsets (P, M, 2) and
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
