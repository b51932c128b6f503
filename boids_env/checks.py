"""Range checks of the config dataclasses: a ``ValueError`` naming the field, the value and
the allowed range (STYLE rule 3); and :func:`from_fields`, a dataclass of a table whose every
key must be one of its fields."""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, fields
from typing import Any, ClassVar, Protocol, TypeVar


class _Dataclass(Protocol):
    """Any dataclass (what typeshed's private ``DataclassInstance`` says, without importing
    a module no distribution installs)."""

    __dataclass_fields__: ClassVar[dict[str, Any]]


T = TypeVar("T", bound=_Dataclass)


@dataclass(frozen=True)
class Check:
    """One range check as it was called: the documentation's source of every field's range
    and unit (the reference pages record the checks a config's validation makes, so they
    cannot drift from it)."""

    name: str
    kind: str
    """``number``, ``integer`` or ``flag``."""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    unit: str = ""

    @property
    def allowed(self) -> str:
        """The allowed values as the error message states them (``(0.0, 1.0]``)."""
        if self.kind == "flag":
            return "True or False"
        left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
        return f"{left}{self.lo}, {self.hi}{right}"


_RECORD: ContextVar[list[Check] | None] = ContextVar("boids_env_checks", default=None)


@contextmanager
def recorded() -> Iterator[list[Check]]:
    """Records every check made inside the block, in call order, into the yielded list
    (``with recorded() as checks: WorldConfig()``)."""
    checks: list[Check] = []
    token = _RECORD.set(checks)
    try:
        yield checks
    finally:
        _RECORD.reset(token)


def _note(check: Check) -> None:
    log = _RECORD.get()
    if log is not None:
        log.append(check)


def number(name: str, value: Any, lo: float, hi: float, *, lo_open: bool = False,
           hi_open: bool = False, unit: str = "") -> float:
    """Checks that ``value`` is a real number in the given interval and returns it as float."""
    _note(Check(name, "number", lo, hi, lo_open, hi_open, unit))
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
    _note(Check(name, "integer", lo, hi))
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    if not lo <= int(value) <= hi:
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value!r}")
    return int(value)


def flag(name: str, value: Any) -> bool:
    """Checks that ``value`` is True or False."""
    _note(Check(name, "flag"))
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return value


def from_fields(cls: type[T], data: Mapping[str, Any], what: str,
                shown: Callable[[list[str]], str] = repr) -> T:
    """The dataclass ``cls`` of a table of its fields, which checks their values; a key that
    is no field is refused by name (``what``: the table in the message, ``"training
    config"``; ``shown``: how the unknown keys are quoted)."""
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"unknown {what} field(s) {shown(unknown)}; known: {sorted(known)}")
    return cls(**data)


def set_field(obj: object, name: str, value: Any) -> None:
    """Sets a field of a frozen dataclass (in its ``__post_init__``)."""
    object.__setattr__(obj, name, value)
