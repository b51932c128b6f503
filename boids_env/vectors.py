"""Velocity commands: strict parsing, an overflow-safe speed limit, and 2-D linear maps that
round the same on every CPU (pure numpy)."""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def clip_speed(v: FloatArray, limit: float) -> FloatArray:
    """Rows of ``v`` (..., 2) whose speed exceeds ``limit`` scaled down to ``limit`` (others
    unchanged). Huge finite components, whose plain norm overflows to inf, keep their
    direction too: ``(1e155, 0)`` becomes ``(limit, 0)``, not ``(0, 0)``."""
    v = np.asarray(v, dtype=np.float64)
    speed = np.sqrt(np.einsum("...d,...d->...", v, v))
    over = speed > limit
    if not over.any():
        return v
    out = v.copy()
    finite = np.isfinite(speed)
    normal = over & finite
    out[normal] *= (limit / speed[normal])[..., None]
    huge = over & ~finite
    if huge.any():
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
    return v[..., 0:1] * m[0] + v[..., 1:2] * m[1]


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
