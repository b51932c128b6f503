"""The policies' numba kernels, loaded by :func:`boids_env.policies.kernels.compiled` once the
core's kernels are (never at ``import boids_env.policies``); each rounds exactly as its numpy
reference (the rules of :mod:`boids_env._compiled`; the pairs:
:data:`boids_env.policies.kernels.KERNELS`).

- The Reynolds policy's rule forces (:func:`boids_env.policies.reynolds.reynolds_forces`).
- :mod:`boids_env.policies.exact`'s elementwise parts in loops, for a learned actor
  (:class:`boids_env.policies.mlp_actor.MLPActor`): the integer slices before the products
  (which stay numpy's BLAS calls: exact in any order, see that module) and the sums,
  scalings, bias and tanh after them, the same + - * / in the same order; then the clip to the
  action space."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


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
