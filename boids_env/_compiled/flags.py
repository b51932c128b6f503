"""Each follower's nearest other robot (the safety flags of :mod:`boids_env.metrics`) and the
env's opt-in safety and cohesion-gap reward rows (:class:`boids_env.rewards.Rewards`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


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
    ``Rewards.safety_terms`` and ``gap_term`` compute them (a flag as 1.0 or 0.0 times its
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
