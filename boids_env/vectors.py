"""Velocity commands: strict parsing, an overflow-safe speed limit, and 2-D linear maps that
round the same on every CPU (numpy; the speed limit also as a compiled kernel of the same
bits, :mod:`boids_env.kernels`)."""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import kernels

FloatArray = npt.NDArray[np.float64]


def clip_speed(v: FloatArray, limit: float) -> FloatArray:
    """Rows of ``v`` (..., 2) whose speed exceeds ``limit`` scaled down to ``limit`` (others
    unchanged). Huge finite components, whose plain norm overflows to inf, keep their
    direction too: ``(1e155, 0)`` becomes ``(limit, 0)``, not ``(0, 0)``."""
    v = np.asarray(v, dtype=np.float64)
    compiled = kernels.compiled()
    if compiled is not None and v.ndim == 2 and v.shape[1] == 2 and v.flags.c_contiguous:
        status, out = compiled.clip_speed(v, float(limit))  # the same bits in one loop
        if status != 2:  # 2: a speed overflows, handled below
            return out
    return clip_speed_reference(v, limit)


def clip_speed_reference(v: FloatArray, limit: float) -> FloatArray:
    """:func:`clip_speed` in numpy (float64 rows ``v``), which the kernel leaves the rows
    whose speed overflows to."""
    speed = np.sqrt(np.einsum("...d,...d->...", v, v))  # no overflow warning for huge rows
    if not (speed > limit).any():
        return v
    if np.isfinite(speed).all():
        # limit / speed below 1 on the rows over the limit (the scaling), min(1, ...) exactly
        # 1 on the others (and on a zero row: limit / tiny is huge)
        scale = np.minimum(1.0, limit / np.maximum(speed, 1e-300))
        return v * scale[..., None]
    out = v.copy()
    over = speed > limit
    finite = np.isfinite(speed)
    normal = over & finite
    out[normal] *= (limit / speed[normal])[..., None]
    huge = over & ~finite
    rows = v[huge]
    big = np.max(np.abs(rows), axis=-1, keepdims=True)
    unit = rows / big  # components in [-1, 1]: no overflow
    out[huge] = unit / np.hypot(unit[..., 0], unit[..., 1])[..., None] * limit
    return out


def times_matrix(v: npt.ArrayLike, matrix: npt.ArrayLike) -> FloatArray:
    """``v @ matrix`` for rows ``v`` (..., 2) and a (2, 2) ``matrix``, as two elementwise
    products and one add per component. ``@`` goes through BLAS, whose kernel is chosen by CPU
    and may fuse the multiply and the add (one rounding instead of two): a rotated frame then
    differed in the last bit between machines, and a flock's dynamics amplify that."""
    v = np.asarray(v, dtype=np.float64)
    m = np.asarray(matrix, dtype=np.float64)
    compiled = kernels.compiled()
    if (compiled is not None and v.ndim and v.shape[-1] == 2 and m.shape == (2, 2)
            and v.flags.c_contiguous):  # the same products and add in one loop
        return compiled.rotated(v.reshape(-1, 2), m).reshape(v.shape)
    return v[..., 0:1] * m[0] + v[..., 1:2] * m[1]


_PIO2_HI = 1.57079632673412561417e00
"""The first 33 bits of π/2: ``n · _PIO2_HI`` is exact for the quadrant counts used here."""
_PIO2_LO = 6.07710050650619224932e-11
"""π/2 − ``_PIO2_HI``."""
_SIN = [(-1.0) ** k / math.factorial(2 * k + 1) for k in range(1, 10)]
_COS = [(-1.0) ** k / math.factorial(2 * k) for k in range(1, 11)]


def sin_cos(phi: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """(sin φ, cos φ) of angles |φ| < 1e6 rad with additions, multiplications and one
    rounding to an integer only: the same bits on every CPU and C library. numpy's SIMD sin
    and cos and the C library's (``math.sin``) differ in the last bit between machines, and
    a flock's dynamics amplify that. Within 2 ulp of the exact values: the quadrant is taken
    off with π/2 in two parts (Cody and Waite), then Taylor polynomials to degree 19 and 20
    on |r| ≤ π/4 (truncation below 1e-21)."""
    phi = np.asarray(phi, dtype=np.float64)
    n = np.rint(phi * (2.0 / math.pi))
    r = (phi - n * _PIO2_HI) - n * _PIO2_LO
    r2 = r * r
    s = np.full_like(r, _SIN[-1])
    for coefficient in reversed(_SIN[:-1]):
        s = s * r2 + coefficient
    s = r + r * r2 * s
    c = np.full_like(r, _COS[-1])
    for coefficient in reversed(_COS[:-1]):
        c = c * r2 + coefficient
    c = 1.0 + r2 * c
    quadrant = np.mod(n, 4.0)
    sin = np.select([quadrant == 0, quadrant == 1, quadrant == 2], [s, c, -s], -c)
    cos = np.select([quadrant == 0, quadrant == 1, quadrant == 2], [c, -s, -c], s)
    return sin, cos


def as_velocities(value: Any, name: str, shape: tuple[int, ...]) -> FloatArray:
    """``value`` as a new float64 array of ``shape`` if it holds only finite real numbers (numpy
    integer or float arrays, or sequences of ints and floats); bools, strings, complex numbers
    and objects are refused with a ``ValueError`` naming ``name``. Always a copy: a caller
    who edits its array afterwards (an external leader's command) changes nothing here."""
    if isinstance(value, np.ndarray):
        ok = value.dtype.kind in "iuf"
    else:
        flat = np.asarray(value, dtype=object).ravel() if _sequence(value) else [value]
        ok = all(isinstance(x, numbers.Real) and not isinstance(x, bool | np.bool_)
                 for x in flat)
    if not ok:
        raise ValueError(f"{name} must be {shape[-1]} real numbers (vx, vy) in m/s, got "
                         f"{value!r}")
    arr = np.array(value, dtype=np.float64, copy=True)
    if arr.shape != shape:
        raise ValueError(f"{name} must be {shape[-1]} numbers (vx, vy) in m/s, shape {shape}, "
                         f"got shape {arr.shape}: {value!r}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite; got {value!r}")
    return arr


def _sequence(value: Any) -> bool:
    return isinstance(value, list | tuple) or hasattr(value, "__array__")
