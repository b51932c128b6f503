"""Temporary folders beside a target that are provably ours, and the moves that put their
content in place.

Everything a boids command writes before it is complete (an atomic write's file, a run's
output folder) lives in a folder ``.NAME.TAG-PID-HEX/`` beside its target ``NAME``, whose first
content is a marker file, :data:`MARKER`, naming the program, host, process and target. A later
command that finds such a folder removes it only when it can prove it ours and abandoned: a
real folder (not a link) holding a marker that is a small regular file with our JSON, written
on this host by a process that no longer runs. A user's file or folder that merely has a
similar name holds no marker and is never touched; nor is one of a process still running.

Moving the content into place is crash-safe. Swapping a folder for another is one system call
where the OS can exchange two names (Linux ``renameat2(RENAME_EXCHANGE)``), so the target is
never missing. Elsewhere, and for a folder that also holds the user's own files (replaced entry
by entry, each entry atomically), a journal written into the temporary folder first lists the
moves; a process killed half-way leaves the journal, and the next command that clears stale
temporaries beside that target completes the moves (:func:`clear_stale`) before removing it.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import os
import re
import shutil
import socket
import sys
import uuid
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

MARKER = ".boids-temporary"
"""The marker file inside every temporary folder of ours."""
JOURNAL = ".boids-moves"
"""The list of moves a commit is making (present only while it makes them)."""
PROGRAM = "boids-env"
_NAME = re.compile(r"^\.(?P<target>.+)\.(?P<tag>[a-z]+)-(?P<pid>\d+)-[0-9a-f]{8}$")
_MARKER_BYTES = 4096
"""A marker is a few hundred bytes; anything larger is not ours (and is never read whole)."""


def create(target: Path, tag: str) -> Path:
    """A new temporary folder beside ``target`` (tag: what it is for, lowercase letters),
    its marker written before anything else."""
    if not re.fullmatch(r"[a-z]+", tag):
        raise ValueError(f"tag must be lowercase letters, got {tag!r}")
    folder = target.parent / f".{target.name}.{tag}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    folder.mkdir()
    marker = {"written_by": PROGRAM, "host": socket.gethostname(), "pid": os.getpid(),
              "target": target.name, "tag": tag}
    (folder / MARKER).write_text(json.dumps(marker))
    return folder


def _marker(folder: Path) -> dict[str, Any] | None:
    """The folder's marker when it is one of ours, else None."""
    path = folder / MARKER
    try:
        if not path.is_file() or path.is_symlink() or path.stat().st_size > _MARKER_BYTES:
            return None
        data = json.loads(path.read_bytes())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("written_by") == PROGRAM else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True  # another user's process, or not a pid we can ask about: keep
    return True


def stale(folder: Path, target: str | None = None) -> list[Path]:
    """Abandoned temporary folders of ours in ``folder`` (only those of ``target`` when
    given), oldest name order."""
    found = []
    try:
        entries = sorted(folder.iterdir()) if folder.is_dir() else []
    except OSError:
        return []
    for path in entries:
        match = _NAME.match(path.name)
        if match is None or (target is not None and match["target"] != target):
            continue
        if path.is_symlink() or not path.is_dir():
            continue
        marker = _marker(path)
        if (marker is None or marker.get("pid") != int(match["pid"])
                or marker.get("target") != match["target"] or marker.get("tag") != match["tag"]
                or marker.get("host") != socket.gethostname()):
            continue
        if not _alive(int(match["pid"])):
            found.append(path)
    return found


def clear_stale(folder: Path, target: str | None = None,
                allowed: Callable[[str], bool] | None = None) -> list[Path]:
    """Removes the abandoned temporary folders of ours in ``folder`` (of ``target`` only,
    when given); returns those removed. One whose commit was cut short (it holds a journal)
    is first completed, when ``allowed`` accepts its target and every name it moves (the
    names the caller's command writes); otherwise it is left as it is, since it may hold the
    only copy of an output."""
    removed = []
    for path in stale(folder, target):
        if (path / JOURNAL).exists():
            if allowed is None or not _journal_allowed(path, allowed):
                continue
            _finish(path)
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path)
    return removed


def _journal_allowed(box: Path, allowed: Callable[[str], bool]) -> bool:
    """Whether the target and every entry the journal of ``box`` names are ``allowed``."""
    marker = _marker(box)
    try:
        moves = json.loads((box / JOURNAL).read_text())
    except (OSError, ValueError):
        return False
    if marker is None or not isinstance(moves, dict):
        return False
    names = [*_names(moves.get("names")), *_names(moves.get("remove"))]
    return allowed(str(marker.get("target"))) and ("swap" in moves or all(map(allowed, names)))


def exchange(a: Path, b: Path) -> bool:
    """Swaps the names ``a`` and ``b`` (two existing entries in one file system) in one
    atomic system call; False, with nothing changed, where the OS or file system cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return False  # a C library without renameat2 (glibc < 2.28, musl)
    at_fdcwd, rename_exchange = -100, 2
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.EPERM):
        return False  # this file system cannot exchange: the caller journals instead
    raise OSError(code, os.strerror(code), str(a), None, str(b))


def replace_folder(box: Path, new: Path, target: Path) -> None:
    """Puts the complete folder ``new`` (inside the temporary folder ``box``) at ``target``;
    an existing ``target`` ends in ``box`` (removed with it). The target is never missing
    where the names can be exchanged; elsewhere a kill between the two renames is completed
    by the next :func:`clear_stale`."""
    if not (target.exists() or target.is_symlink()):
        os.rename(new, target)
        return
    if exchange(new, target):
        return
    _write_journal(box, {"swap": new.name})
    _finish(box)


def replace_entries(box: Path, new: Path, names: Sequence[str],
                    remove: Sequence[str] = ()) -> None:
    """Moves the entries ``names`` of the folder ``new`` (inside ``box``) into ``box``'s
    target folder in that order, each file replacing its namesake atomically (a folder once
    the old one is set aside), after moving its entries ``remove`` out of the way (into
    ``box``). Other entries of the target are left alone. A kill half-way is completed by the
    next :func:`clear_stale`."""
    _write_journal(box, {"from": new.name, "names": list(names),
                         "remove": [n for n in remove if n not in names]})
    _finish(box)


def _write_journal(box: Path, moves: dict[str, Any]) -> None:
    part = box / f"{JOURNAL}.part"
    with open(part, "w") as fh:
        json.dump(moves, fh)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(part, box / JOURNAL)


def _finish(box: Path) -> None:
    """Makes (again: every step can be repeated) the moves of ``box``'s journal, if any."""
    marker = _marker(box)
    try:
        moves = json.loads((box / JOURNAL).read_text())
    except (OSError, ValueError):
        return
    if marker is None or not isinstance(moves, dict):
        return
    target = box.parent / str(marker.get("target"))
    old = box / "old"
    old.mkdir(exist_ok=True)
    if "swap" in moves:
        new = box / str(moves["swap"])
        if new.exists():
            _set_aside(target, old)
            os.rename(new, target)
        return
    new = box / str(moves.get("from"))
    for name in _names(moves.get("remove")):
        _set_aside(target / name, old)
    for name in _names(moves.get("names")):
        src, dst = new / name, target / name
        if not (src.exists() or src.is_symlink()):
            continue  # moved already
        # a folder cannot replace its namesake in one rename: the old one goes first (a kill
        # in between is completed from the journal; an exchange could not be repeated)
        if src.is_dir() or (dst.is_dir() and not dst.is_symlink()):
            _set_aside(dst, old)
        os.replace(src, dst)


def _set_aside(path: Path, old: Path) -> None:
    """Moves ``path`` (if there) into the folder ``old``, to be removed with it."""
    with contextlib.suppress(FileNotFoundError):
        os.rename(path, old / f"{path.name}.{uuid.uuid4().hex[:8]}")


def _names(value: Any) -> list[str]:
    """Entry names of a journal list (plain names only: a journal never moves anything
    outside its folders)."""
    if not isinstance(value, list):
        return []
    return [v for v in value if isinstance(v, str) and v not in ("", ".", "..") and "/" not in v]
