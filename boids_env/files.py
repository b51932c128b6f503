"""Atomic writes: every file (or folder) is written under a temporary name beside its target and
renamed over it only when complete, so a crash, a full disk or Ctrl-C never leaves a torn or
truncated file where a good one was (POSIX ``rename`` is atomic within a file system)."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def _temporary(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yields a temporary path beside ``path`` to write a file or a folder to; when the block
    ends without an exception it replaces ``path`` (an existing file, or folder, of that name
    included), otherwise it is removed and ``path`` is left as it was."""
    target = Path(path)
    tmp = _temporary(target)
    try:
        yield tmp
        if tmp.is_file():
            with open(tmp, "rb") as fh:
                os.fsync(fh.fileno())
        if target.is_dir() and not target.is_symlink():
            old = _temporary(target)
            os.replace(target, old)
            os.replace(tmp, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, target)
    finally:
        if tmp.is_dir() and not tmp.is_symlink():
            shutil.rmtree(tmp, ignore_errors=True)
        elif tmp.exists() or tmp.is_symlink():
            tmp.unlink()


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Writes ``data`` to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    """Writes ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | Path, data: Any) -> Path:
    """Writes ``data`` as indented JSON to ``path`` atomically; returns the path. A float that
    is not finite (a metric that does not apply, e.g. the path deviation of an external
    leader, is NaN) is written as ``null``: NaN is not JSON, and strict readers refuse it."""
    return write_text(path, json.dumps(_finite(data), indent=2, allow_nan=False) + "\n")


def _finite(data: Any) -> Any:
    """``data`` with every non-finite float (NaN, ±inf) in its dicts and lists as None."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {key: _finite(value) for key, value in data.items()}
    if isinstance(data, list | tuple):
        return [_finite(value) for value in data]
    return data


def append_line(path: str | Path, line: str) -> None:
    """Appends one line to a log file (``episodes.jsonl``) in a single ``write`` and flushes it
    to disk. If the file does not end with a newline (an earlier write was torn) one is written
    first, so a torn line never glues onto the next."""
    target = Path(path)
    data = line.rstrip("\n").encode("utf-8") + b"\n"
    with open(target, "ab+") as fh:
        fh.seek(0, os.SEEK_END)
        if fh.tell():
            fh.seek(-1, os.SEEK_END)
            if fh.read(1) != b"\n":
                data = b"\n" + data
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
