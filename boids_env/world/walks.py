"""Recorded walks: a CSV of ``t, x, y`` (s, m), the common format of pedestrian datasets,
read and checked as a file from elsewhere (``leader="trajectory"``)."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

from boids_env.untrusted import file_identity, quote_path, read_text

FloatArray = npt.NDArray[np.float64]

WALKS = {"doorway_walk": Path(__file__).parent / "data" / "doorway_walk.csv"}
"""Walks shipped with the package, by name (recorded with the pedestrian model: see the
docs, how-to/people)."""
WALK_MAX_BYTES = 10_000_000
"""A walk file larger than this (10 MB) is refused."""
WALK_MAX_ROWS = 200_000
"""A walk with more samples than this is refused."""
WALK_MAX_COORDINATE = 1000.0
"""Coordinates (m) and times (s) beyond ±this are refused."""


def max_walk_speed(times: FloatArray, points: FloatArray) -> float:
    """The fastest a walk moves between two rows (m/s)."""
    if len(times) < 2:
        return 0.0
    steps = np.diff(points, axis=0)
    return float((np.hypot(steps[:, 0], steps[:, 1]) / np.diff(times)).max())


def walk_file(path: str | Path) -> Path:
    """The file of walk ``path`` (a shipped walk's by name, :data:`WALKS`), resolved."""
    return WALKS.get(str(path), Path(path)).resolve()


def read_walk(path: str | Path) -> tuple[FloatArray, FloatArray]:
    """A walk file's ``(times (M,), points (M, 2))``: a CSV with columns ``t, x, y`` (s, m),
    an optional header line, one sample per row (or a shipped walk by name, :data:`WALKS`).

    The file is untrusted: at most :data:`WALK_MAX_BYTES` and :data:`WALK_MAX_ROWS` rows, finite
    numbers within ±:data:`WALK_MAX_COORDINATE`, times >= 0 and strictly increasing, at least
    two rows; anything else raises ``ValueError`` naming the file and the row.
    """
    return _read_walk(*file_identity(WALKS.get(str(path), Path(path)), "leader_trajectory"))


@functools.lru_cache(maxsize=16)
def _read_walk(path: str, size: int, mtime: int) -> tuple[FloatArray, FloatArray]:
    text = read_text(path, "leader_trajectory", WALK_MAX_BYTES)
    path = quote_path(path)
    rows: list[tuple[float, float, float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        cells = [c.strip() for c in line.split(",")]
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if not rows and number == _first_line(text) and not _numeric(cells[0]):
            if [c.lower() for c in cells] != ["t", "x", "y"]:
                # the file's content is never quoted: the path may name any file
                raise ValueError(f"leader_trajectory {path}: row {number}: the header must be "
                                 f"'t,x,y' (a CSV of t, x, y in s and m)")
            continue
        rows.append(_row(path, number, cells, rows[-1][0] if rows else None))
        if len(rows) > WALK_MAX_ROWS:
            raise ValueError(f"leader_trajectory {path}: more than {WALK_MAX_ROWS} rows")
    if len(rows) < 2:
        raise ValueError(f"leader_trajectory {path}: a walk needs at least two rows of t,x,y, "
                         f"got {len(rows)}")
    data = np.array(rows, dtype=float)
    times, points = data[:, 0].copy(), data[:, 1:].copy()
    times.setflags(write=False)
    points.setflags(write=False)
    return times, points


def _first_line(text: str) -> int:
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip() and not line.lstrip().startswith("#"):
            return number
    return 0


def _numeric(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _row(path: str, number: int, cells: list[str],
         previous: float | None) -> tuple[float, float, float]:
    """One checked sample ``(t, x, y)`` of row ``number``."""
    if len(cells) != 3:
        raise ValueError(f"leader_trajectory {path}: row {number}: expected 3 values t,x,y, "
                         f"got {len(cells)}")
    try:
        t, x, y = (float(c) for c in cells)
    except ValueError:
        bad = next(n for n, c in zip("txy", cells, strict=True) if not _numeric(c))
        raise ValueError(f"leader_trajectory {path}: row {number}: t,x,y must be numbers, "
                         f"{bad} is not") from None
    if not all(math.isfinite(v) and abs(v) <= WALK_MAX_COORDINATE for v in (t, x, y)):
        raise ValueError(f"leader_trajectory {path}: row {number}: values must be finite and "
                         f"within ±{WALK_MAX_COORDINATE:g}, got {t:g}, {x:g}, {y:g}")
    if t < 0:
        raise ValueError(f"leader_trajectory {path}: row {number}: t must be >= 0 s (the "
                         f"episode's clock), got {t:g}")
    if previous is not None and t <= previous:
        raise ValueError(f"leader_trajectory {path}: row {number}: t must increase, got "
                         f"{t:g} after {previous:g}")
    return t, x, y
