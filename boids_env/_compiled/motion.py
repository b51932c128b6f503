"""The speed limit of a step's commands (:func:`boids_env.vectors.clip_speed`) and a unicycle's
turn every physics substep (``Unicycle._substep`` of :mod:`boids_env.world.robots`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


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
