"""An eval output folder belongs to one evaluation: the same suite and policies resume in it,
anything else is refused unless the caller overwrites, which removes only what an earlier
evaluation of ours wrote.

``manifest.json`` in the folder records the evaluation's identity (the suite's cases, the
policies and their fingerprints; not the seeds, so adding seeds resumes) and every top-level
file or folder the evaluation wrote. It is written (atomically) before anything else.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from boids_env.files import write_json

MANIFEST = "manifest.json"
KIND = "boids eval"
RUNNER_OUTPUTS = ("episodes.jsonl", "errors.jsonl", "results.parquet", "results.csv",
                  "suite.json", "trajectories")
"""What the runner writes (the report adds its own, recorded when written)."""
LEGACY_OUTPUTS = (*RUNNER_OUTPUTS, "stats_anova.csv", "stats_tukey.csv", "policy_comparison.csv",
                  "verdicts.csv", "report.md", "report.html", "figures")
"""What an eval of a version without manifests wrote (``verdicts_*.csv`` too)."""


def check_target(out: Path) -> None:
    """``ValueError`` if ``out`` exists and is not a folder (before anything is written)."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out must be a folder, but {out} is an existing file")


def read_manifest(out: Path) -> dict[str, Any] | None:
    """The folder's manifest, or None when it has none (or an unreadable one)."""
    try:
        data = json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("kind") == KIND else None


def _normal(identity: dict[str, Any]) -> Any:
    return json.loads(json.dumps(identity, sort_keys=True))


def _describe(identity: dict[str, Any]) -> str:
    labels = [p.get("label", p.get("spec")) for p in identity.get("policies", [])]
    return f"suite {identity.get('name')!r} with policies {labels}"


def _is_legacy(out: Path) -> bool:
    return (out / "episodes.jsonl").is_file() and (out / "suite.json").is_file()


def _ours(out: Path, manifest: dict[str, Any] | None) -> list[Path]:
    """The entries of ``out`` an earlier evaluation of ours wrote."""
    if manifest is not None:
        names = [str(n) for n in manifest.get("files", []) if isinstance(n, str)]
        names.append(MANIFEST)
    elif _is_legacy(out):
        names = [*LEGACY_OUTPUTS, *(p.name for p in out.glob("verdicts_*.csv"))]
    else:
        names = []
    # Names are top-level entries: never follow one out of the folder.
    safe = [n for n in dict.fromkeys(names) if n and "/" not in n and n not in (".", "..")]
    leftovers = [p.name for p in stale_temporaries(out)]
    return [out / n for n in [*safe, *leftovers] if (out / n).exists() or (out / n).is_symlink()]


_TEMPORARY = re.compile(r"^\..+\.tmp-(\d+)-[0-9a-f]+$")


def stale_temporaries(folder: Path) -> list[Path]:
    """Temporary files of atomic writes (``boids_env.files``) in ``folder`` whose writing
    process is gone: what a kill in the middle of a write leaves behind."""
    stale = []
    for path in folder.glob(".*.tmp-*"):
        match = _TEMPORARY.match(path.name)
        if match is None:
            continue
        try:
            os.kill(int(match.group(1)), 0)
        except ProcessLookupError:
            stale.append(path)
        except (PermissionError, OverflowError):
            continue  # alive (another user's) or not a pid: leave it
    return stale


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def claim(out: Path, identity: dict[str, Any], *, overwrite: bool = False) -> bool:
    """Makes ``out`` the folder of the evaluation ``identity``; returns True when it resumes
    an earlier run of the same evaluation.

    A missing or empty folder is taken; a folder of the same evaluation is resumed (unless
    ``overwrite``); anything else raises ``ValueError`` unless ``overwrite``, which first
    removes what an earlier evaluation of ours wrote there (listed in its manifest) and
    nothing else.
    """
    check_target(out)
    manifest = read_manifest(out) if out.is_dir() else None
    same = manifest is not None and _normal(manifest.get("identity", {})) == _normal(identity)
    if same and not overwrite:
        for path in [*stale_temporaries(out), *stale_temporaries(out / "trajectories")]:
            _remove(path)
        return True
    entries = [p for p in out.iterdir()] if out.is_dir() else []
    if entries and not overwrite:
        if manifest is not None:
            why = (f"holds an evaluation of {_describe(manifest.get('identity', {}))}, this "
                   f"run is {_describe(identity)}")
            if _describe(manifest.get("identity", {})) == _describe(identity):
                why += " (same names, but the cases, policy files or presets differ)"
        else:
            shown = sorted(p.name for p in entries)[:5]
            why = f"is not empty and was not written by boids eval (it holds {shown})"
        raise ValueError(f"output folder {out} {why}; pass --overwrite (overwrite=True) to "
                         f"replace our earlier outputs there, or choose another --out")
    for path in _ours(out, manifest):
        _remove(path)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / MANIFEST, {"kind": KIND, "identity": identity,
                                "files": list(RUNNER_OUTPUTS)})
    return False


def record_files(out: Path, names: Iterable[str]) -> None:
    """Adds top-level entries of ``out`` to its manifest (what ``--overwrite`` may remove)."""
    manifest = read_manifest(out)
    if manifest is None:
        return
    files = list(dict.fromkeys([*manifest.get("files", []), *names]))
    if files != manifest.get("files"):
        write_json(out / MANIFEST, {**manifest, "files": files})
