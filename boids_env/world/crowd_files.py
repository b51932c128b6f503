"""Pedestrian-dataset files read as files from elsewhere (``crowd_file``): the ETH/UCY
``frame ped x y`` text and TrajNet++'s JSON lines, checked row by row and turned into one
track per pedestrian (times in s, points in m).

- **ETH/UCY** (the preprocessed files of the leave-one-out benchmarks): whitespace-separated
  ``frame ped x y`` (metres), one sample a line, typically every 10th video frame at 2.5 Hz;
  blank lines and ``#`` comments are skipped.
- **TrajNet++** (ndJSON): one JSON object a line, ``{"scene": {...}}`` (its ``fps``, when
  given, must be ``crowd_rate``) or ``{"track": {"f": frame, "p": ped, "x": m, "y": m}}``
  (other keys of a track are ignored).

A sample's time is ``(frame − the file's first frame) / (frame_step · rate)`` seconds. The file
is untrusted: at most :data:`CROWD_MAX_BYTES`, :data:`CROWD_MAX_ROWS` samples and
:data:`CROWD_MAX_PEDESTRIANS` pedestrians, frames integers in [0, :data:`CROWD_MAX_FRAME`],
coordinates finite within ±:data:`CROWD_MAX_COORDINATE`, no pedestrian twice in one frame;
anything else raises ``ValueError`` naming the file, the line and the allowed range (the
file's content is never quoted: the path may name any file). JSON is parsed by
:func:`json.loads` line by line, nothing is evaluated.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.untrusted import MAX_DEPTH, check_depth, file_identity, quote_path, read_text

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

CROWD_FORMATS = ("auto", "eth_ucy", "trajnet")
"""``crowd_format`` values: ``auto`` reads a file whose first data line starts with ``{`` as
TrajNet++, any other as ETH/UCY."""
CROWD_MAX_BYTES = 20_000_000
"""A crowd file larger than this (20 MB) is refused."""
CROWD_MAX_ROWS = 500_000
"""A crowd file with more samples than this is refused."""
CROWD_MAX_PEDESTRIANS = 500
"""A crowd file with more pedestrians than this is refused (``crowd``'s own bound)."""
CROWD_MAX_COORDINATE = 1000.0
"""Coordinates (m) beyond ±this are refused."""
CROWD_MAX_FRAME = 10**9
"""Frame numbers beyond this are refused."""
CROWD_MAX_LINE = 10_000
"""A line longer than this (characters) is refused."""


@dataclass(frozen=True)
class Tracks:
    """The pedestrians of a crowd file, one track each, in increasing order of their ids.

    ``times`` (M,) s and ``points`` (M, 2) m hold every track's samples one track after the
    other, each in increasing time; track k is ``times[start[k]:start[k + 1]]``."""

    ids: IntArray
    """(P,) the file's pedestrian ids."""
    start: IntArray
    """(P + 1,) where each track begins in ``times`` and ``points`` (the last: M)."""
    times: FloatArray
    """(M,) sample times (s) from the file's first frame."""
    points: FloatArray
    """(M, 2) sample positions (m) in the file's frame."""

    @property
    def count(self) -> int:
        """The number of pedestrians P."""
        return len(self.ids)

    def max_speeds(self) -> FloatArray:
        """(P,) the fastest each pedestrian moves between two of its samples (m/s; 0 for
        one standing or seen once)."""
        steps = np.diff(self.points, axis=0)
        speed = np.hypot(steps[:, 0], steps[:, 1]) / np.maximum(np.diff(self.times), 1e-12)
        same = np.ones(len(speed), dtype=bool)
        same[self.start[1:-1] - 1] = False  # the step from one track to the next
        out = np.zeros(self.count)
        if len(speed):
            owner = np.searchsorted(self.start, np.arange(len(speed)), side="right") - 1
            np.maximum.at(out, owner[same], speed[same])
        return out


def read_crowd(path: str | Path, fmt: str = "auto", frame_step: float = 10.0,
               rate: float = 2.5) -> Tracks:
    """The tracks of crowd file ``path`` in format ``fmt`` (:data:`CROWD_FORMATS`), a sample
    every ``frame_step`` frame numbers at ``rate`` samples per second (see the module)."""
    return _read_crowd(*file_identity(path, "crowd_file"), fmt, float(frame_step),
                       float(rate))


@functools.lru_cache(maxsize=8)
def _read_crowd(path: str, size: int, mtime: int, fmt: str, frame_step: float,
                rate: float) -> Tracks:
    text = read_text(path, "crowd_file", CROWD_MAX_BYTES)
    where = f"crowd_file {quote_path(path)}"
    if fmt == "auto":
        first = next((line.strip() for line in text.splitlines()
                      if line.strip() and not line.lstrip().startswith("#")), "")
        fmt = "trajnet" if first.startswith("{") else "eth_ucy"
    rows: list[tuple[int, int, float, float, int]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        if len(line) > CROWD_MAX_LINE:
            raise ValueError(f"{where}: line {number}: longer than {CROWD_MAX_LINE:,} "
                             f"characters")
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        row = (_eth_row(where, number, stripped) if fmt == "eth_ucy"
               else _trajnet_row(where, number, stripped, rate))
        if row is not None:
            rows.append((*row, number))
            if len(rows) > CROWD_MAX_ROWS:
                raise ValueError(f"{where}: more than {CROWD_MAX_ROWS:,} samples")
    if not rows:
        raise ValueError(f"{where}: no samples (a {fmt} file of frame, ped, x, y rows)")
    return _tracks(where, rows, frame_step * rate)


def _eth_row(where: str, number: int, line: str) -> tuple[int, int, float, float]:
    """One ETH/UCY sample ``(frame, ped, x, y)`` of line ``number``."""
    cells = line.split()
    if len(cells) != 4:
        raise ValueError(f"{where}: line {number}: expected 4 values 'frame ped x y' "
                         f"separated by whitespace, got {len(cells)}")
    values = []
    for name, cell in zip(("frame", "ped", "x", "y"), cells, strict=True):
        try:
            values.append(float(cell))
        except ValueError:
            raise ValueError(f"{where}: line {number}: {name} must be a number") from None
    return _checked(where, number, *values)


def _trajnet_row(where: str, number: int, line: str,
                 rate: float) -> tuple[int, int, float, float] | None:
    """One TrajNet++ sample ``(frame, ped, x, y)`` of line ``number`` (None: a scene)."""
    try:
        data = check_depth(json.loads(line), f"{where}: line {number}")
    except RecursionError:
        raise ValueError(f"{where}: line {number}: nested more than {MAX_DEPTH} levels "
                         f"deep") from None
    except ValueError as exc:
        if str(exc).startswith(where):
            raise
        raise ValueError(f"{where}: line {number}: not valid JSON") from None
    if not isinstance(data, dict) or len(data) != 1 or not ({"scene", "track"} & set(data)):
        raise ValueError(f"{where}: line {number}: expected one object "
                         f'{{"scene": {{...}}}} or {{"track": {{"f", "p", "x", "y"}}}}')
    if "scene" in data:
        scene = data["scene"]
        if not isinstance(scene, dict):
            raise ValueError(f"{where}: line {number}: a scene must be an object")
        fps = scene.get("fps")
        if fps is not None and (not _real(fps) or not math.isclose(float(fps), rate)):
            raise ValueError(f"{where}: line {number}: the scene's fps must be crowd_rate "
                             f"({rate:g} samples/s); give crowd_rate=<the file's fps>")
        return None
    track = data["track"]
    if not isinstance(track, dict) or not all(k in track for k in "fpxy"):
        raise ValueError(f"{where}: line {number}: a track must be an object with keys "
                         f"f, p, x, y")
    for key, name in zip("fpxy", ("frame (f)", "ped (p)", "x", "y"), strict=True):
        if not _real(track[key]):
            raise ValueError(f"{where}: line {number}: {name} must be a number")
    return _checked(where, number, *(float(track[k]) for k in "fpxy"))


def _real(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _checked(where: str, number: int, frame: float, ped: float, x: float,
             y: float) -> tuple[int, int, float, float]:
    """``(frame, ped, x, y)`` once each is in its range (frame and ped whole numbers)."""
    for name, value in (("frame", frame), ("ped", ped)):
        if not (math.isfinite(value) and value == round(value)
                and 0 <= value <= CROWD_MAX_FRAME):
            raise ValueError(f"{where}: line {number}: {name} must be a whole number in "
                             f"[0, {CROWD_MAX_FRAME}], got {value:g}")
    for name, value in (("x", x), ("y", y)):
        if not (math.isfinite(value) and abs(value) <= CROWD_MAX_COORDINATE):
            raise ValueError(f"{where}: line {number}: {name} must be finite and within "
                             f"±{CROWD_MAX_COORDINATE:g} m, got {value:g}")
    return int(frame), int(ped), x, y


def _tracks(where: str, rows: list[tuple[int, int, float, float, int]],
            frames_per_second: float) -> Tracks:
    """The rows grouped by pedestrian (ids increasing), each in increasing frame."""
    data = np.array([r[:2] for r in rows], dtype=np.int64)
    lines = np.array([r[4] for r in rows], dtype=np.int64)
    order = np.lexsort((data[:, 0], data[:, 1]))  # by ped, then frame
    frames, peds = data[order, 0], data[order, 1]
    twice = np.flatnonzero((np.diff(frames) == 0) & (np.diff(peds) == 0))
    if len(twice):
        a, b = sorted((lines[order][twice[0]], lines[order][twice[0] + 1]))
        raise ValueError(f"{where}: line {b}: pedestrian {peds[twice[0]]} is in frame "
                         f"{frames[twice[0]]} twice (also line {a})")
    ids, start = np.unique(peds, return_index=True)
    if len(ids) > CROWD_MAX_PEDESTRIANS:
        raise ValueError(f"{where}: {len(ids):,} pedestrians, more than the "
                         f"{CROWD_MAX_PEDESTRIANS} allowed")
    points = np.array([r[2:4] for r in rows], dtype=float)[order]
    times = (frames - frames.min()).astype(float) / frames_per_second
    for array in (times, points):
        array.setflags(write=False)
    bounds = np.append(start, len(frames)).astype(np.int64)
    return Tracks(ids.astype(np.int64), bounds, times, points)
