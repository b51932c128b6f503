"""The study's after-physics kernels: the neighbour search below ``KD_TREE_MIN_ROBOTS``
robots, the observations' study blocks, the violation flags with their reward terms, the
frame rotation, and all of them for K copies in one call (:func:`batch_after`, driven by
:mod:`boids_env.fused`). :func:`batch_after` calls the others, so they share this file
(see the package's docstring on the cache)."""

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
def rotated(v, m):  # pragma: no cover - compiled
    """``vectors.times_matrix(v, m)``: rows (M, 2) into the frame of the (2, 2) ``m``."""
    out = np.empty_like(v)
    for i in range(v.shape[0]):
        out[i, 0] = v[i, 0] * m[0, 0] + v[i, 1] * m[1, 0]
        out[i, 1] = v[i, 0] * m[0, 1] + v[i, 1] * m[1, 1]
    return out


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
            pos = rotated(pos, frame)
            vel = rotated(vel, frame)
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
