"""Range checks of the config dataclasses: a ``ValueError`` naming the field, the value and
the allowed range (STYLE rule 3)."""

from __future__ import annotations

import math
import numbers
from typing import Any


def number(name: str, value: Any, lo: float, hi: float, *, lo_open: bool = False,
           hi_open: bool = False, unit: str = "") -> float:
    """Checks that ``value`` is a real number in the given interval and returns it as float."""
    left, right = "(" if lo_open else "[", ")" if hi_open else "]"
    allowed = f"{left}{lo}, {hi}{right}{(' ' + unit) if unit else ''}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a number in {allowed}, got {value!r}")
    v = float(value)
    below = v <= lo if lo_open else v < lo
    above = v >= hi if hi_open else v > hi
    if not math.isfinite(v) or below or above:
        raise ValueError(f"{name} must be in {allowed}, got {value!r}")
    return v


def integer(name: str, value: Any, lo: int, hi: int) -> int:
    """Checks that ``value`` is an integer (numpy integers accepted) in [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    if not lo <= int(value) <= hi:
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value!r}")
    return int(value)


def flag(name: str, value: Any) -> bool:
    """Checks that ``value`` is True or False."""
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return value


def set_field(obj: object, name: str, value: Any) -> None:
    """Sets a field of a frozen dataclass (in its ``__post_init__``)."""
    object.__setattr__(obj, name, value)
