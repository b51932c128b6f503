"""Progress bars of the long steps (an evaluation's episodes, a video's frames, training):
tqdm on a terminal only. Piped into a log file, a bar's carriage-return redraws would fill it
with hundreds of half lines, so there the bars are left out and the commands' own summary
lines tell what happened."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import IO, Any, Protocol, TypeVar

T = TypeVar("T")


class Bar(Protocol):
    """What the callers use of a tqdm bar."""

    def update(self, n: int = 1) -> Any: ...

    def close(self) -> None: ...


class _NoBar:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def on_terminal(stream: IO[str] | None = None) -> bool:
    """Whether ``stream`` (default: standard error, where the bars go) is a terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream is not None and stream.isatty())
    except (AttributeError, ValueError, OSError):  # no isatty, or a closed stream
        return False


def bar(total: int, *, desc: str, unit: str, initial: int = 0, enabled: bool = True,
        leave: bool = True) -> Bar:
    """A tqdm bar when ``enabled``, standard error is a terminal and tqdm is installed; else
    one that shows nothing. ``leave``: keep the finished bar on screen."""
    if not (enabled and on_terminal()):
        return _NoBar()
    try:
        from tqdm import tqdm
    except ImportError:  # the extras that show bars (render, eval, train) install tqdm
        return _NoBar()
    return tqdm(total=total, initial=initial, desc=desc, unit=unit, leave=leave)


def iterate(items: Iterable[T], total: int, *, desc: str, unit: str, enabled: bool = True
            ) -> Iterator[T]:
    """``items`` with a bar (see :func:`bar`) that advances as they are consumed and goes
    away when they are exhausted."""
    shown = bar(total, desc=desc, unit=unit, enabled=enabled, leave=False)
    try:
        for item in items:
            yield item
            shown.update(1)
    finally:
        shown.close()
