"""Atomic writes: every file (or folder) is written under a temporary name beside its target and
renamed over it only when complete, so a crash, a full disk or Ctrl-C never leaves a torn or
truncated file where a good one was (POSIX ``rename`` is atomic within a file system).

The temporary lives in a folder of ours beside the target (:mod:`boids_env.temporaries`: a
marker inside proves it ours), so what a killed write leaves is found and removed by a later
command, and a user's file of a similar name never is."""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import shutil
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from boids_env import temporaries
from boids_env.untrusted import check_zip_entry


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yields a temporary path beside ``path`` (of the same name, in a temporary folder of
    ours) to write a file or a folder to; when the block ends without an exception it replaces
    ``path`` (an existing file, or folder, of that name included), otherwise it is removed and
    ``path`` is left as it was."""
    target = Path(path)
    box = temporaries.create(target, "tmp")
    tmp = box / target.name
    try:
        yield tmp
        if tmp.is_file():
            with open(tmp, "rb") as fh:
                os.fsync(fh.fileno())
        if target.is_dir() and not target.is_symlink():
            temporaries.replace_folder(box, tmp, target)
        else:
            os.replace(tmp, target)
    finally:
        shutil.rmtree(box, ignore_errors=True)


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


def read_zip_entry(archive: zipfile.ZipFile, name: str, limit: int) -> bytes:
    """The bytes of the entry ``name`` of ``archive``, read only if it holds at most ``limit``
    bytes uncompressed and inflates at most :data:`~boids_env.untrusted.MAX_RATIO` times its
    compressed size (:func:`~boids_env.untrusted.check_zip_entry`): a zip bomb (a small entry
    that inflates to gigabytes) is refused with a ``ValueError`` naming the entry before it is
    inflated, not after memory runs out.

    Both the size the archive declares and the bytes actually inflated are checked (read in
    chunks, stopping one byte past the allowance). ``KeyError`` when there is no such entry."""
    info = archive.getinfo(name)
    allowed = check_zip_entry(info, limit)
    data = bytearray()
    with archive.open(info) as fh:
        while len(data) <= allowed:
            chunk = fh.read(min(1 << 20, allowed + 1 - len(data)))
            if not chunk:
                break
            data += chunk
    if len(data) > allowed:
        raise ValueError(f"its entry {name} inflates beyond the {allowed:,} bytes allowed")
    return bytes(data)


def file_digest(path: str | Path) -> str:
    """The SHA-256 of a file's content (hex), read in blocks."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
