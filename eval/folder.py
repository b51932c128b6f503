"""An output folder belongs to one evaluation (``boids eval``) or one training (``boids
train``): the same evaluation (or a training resumed) goes on in it, anything else is refused
unless the caller overwrites, which removes only what an earlier one of ours wrote.

``manifest.json`` in the folder records the owner's identity (for an evaluation the suite's
cases, the policies and their fingerprints, not the seeds, so adding seeds resumes; for a
training its config) and the top-level entries it wrote. It is written (atomically) before
anything else. Only names the command itself writes are ever removed (:class:`Owner`): a
manifest naming anything else (a user's file, ``..``) is not obeyed for those names, and a
user's file or folder that merely looks like one of our temporaries is never touched
(:mod:`boids_env.temporaries`).
"""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from boids_env import temporaries
from boids_env.files import write_json

MANIFEST = "manifest.json"
KIND = "boids eval"
RUNNER_OUTPUTS = ("episodes.jsonl", "errors.jsonl", "results.parquet", "results.csv",
                  "suite.json", "trajectories")
"""What the runner writes (the report adds its own, recorded when written)."""
REPORT_OUTPUTS = ("report.md", "report.html", "figures", "stats_anova.csv", "stats_tukey.csv",
                  "stats_tukey_study.csv", "policy_comparison.csv", "policy_verdicts.csv",
                  "safety.csv", "blocks.csv", "proxemics.csv", "person_trade_offs.csv")
"""What ``boids report`` writes (besides ``verdicts_<policy>.csv``)."""
LEGACY_OUTPUTS = (*RUNNER_OUTPUTS, "stats_anova.csv", "stats_tukey.csv", "policy_comparison.csv",
                  "verdicts.csv", "report.md", "report.html", "figures")
"""What an eval of a version without manifests wrote (``verdicts_*.csv`` too)."""
TRAIN_KIND = "boids train"
TRAIN_OUTPUTS = ("config.json", "model.zip", "best_model.zip", "evaluations.csv",
                 "checkpoints", "tb")
"""What ``boids train`` writes."""


@dataclass(frozen=True)
class Owner:
    """A command that owns its output folder, and the names it may write there."""

    kind: str
    """``boids eval`` or ``boids train``: the manifest's ``kind``."""
    outputs: tuple[str, ...]
    """Every top-level name it writes (listed in the manifest when the folder is claimed)."""
    extra: tuple[str, ...] = ()
    """Other names it may write (recorded when written)."""
    pattern: str | None = None
    """A regular expression for more names it may write (``verdicts_<policy>.csv``)."""
    legacy: Callable[[Path], list[str]] | None = None
    """The names an older version without manifests wrote in a folder (None: never)."""

    def allows(self, name: str) -> bool:
        """Whether ``name`` is a top-level entry this command writes (the only entries an
        overwrite removes)."""
        return (name in self.outputs or name in self.extra or name == MANIFEST
                or (self.pattern is not None and re.fullmatch(self.pattern, name) is not None))


def _legacy_eval(out: Path) -> list[str]:
    if not ((out / "episodes.jsonl").is_file() and (out / "suite.json").is_file()):
        return []
    return [*LEGACY_OUTPUTS, *(p.name for p in out.glob("verdicts_*.csv"))]


def _legacy_train(out: Path) -> list[str]:
    if not ((out / "config.json").is_file()
            and any((out / n).exists() for n in ("model.zip", "checkpoints", "tb"))):
        return []
    return list(TRAIN_OUTPUTS)


EVAL = Owner(KIND, RUNNER_OUTPUTS, REPORT_OUTPUTS, r"verdicts_[A-Za-z0-9._-]+\.csv",
             _legacy_eval)
TRAIN = Owner(TRAIN_KIND, TRAIN_OUTPUTS, legacy=_legacy_train)
SWEEP = Owner("boids train --seeds", ("sweep.json", "seeds.csv", "seeds.md"),
              pattern=r"seed_[0-9]+|\.seed_[0-9]+\.job\.json")
"""A sweep of training seeds: its table and one training folder per seed."""


def check_target(out: Path) -> None:
    """``ValueError`` if ``out`` exists and is not a folder (before anything is written)."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out must be a folder, but {out} is an existing file")


def _read(out: Path) -> dict[str, Any] | None:
    """The folder's manifest as a JSON table, whatever wrote it (None: none, unreadable)."""
    try:
        data = json.loads((out / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def read_manifest(out: Path, owner: Owner = EVAL) -> dict[str, Any] | None:
    """The folder's manifest when ``owner`` wrote it, or None (none, unreadable, another's)."""
    data = _read(out)
    return data if data is not None and data.get("kind") == owner.kind else None


def _normal(identity: dict[str, Any]) -> Any:
    return json.loads(json.dumps(identity, sort_keys=True))


def _describe(identity: dict[str, Any], owner: Owner) -> str:
    if owner is TRAIN:
        return f"a training (algorithm {identity.get('algorithm')!r}, seed {identity.get('seed')})"
    labels = [p.get("label", p.get("spec")) for p in identity.get("policies", [])]
    return f"suite {identity.get('name')!r} with policies {labels}"


def _ours(out: Path, manifest: dict[str, Any] | None, owner: Owner) -> list[Path]:
    """The entries of ``out`` an earlier run of ``owner`` wrote: those its manifest lists
    (or an older version's known outputs) that are names ``owner`` writes, and nothing else."""
    if manifest is not None:
        names = [str(n) for n in manifest.get("files", []) if isinstance(n, str)]
        names.append(MANIFEST)
    else:
        names = owner.legacy(out) if owner.legacy is not None else []
    safe = [n for n in dict.fromkeys(names) if owner.allows(n)]
    return [out / n for n in safe if (out / n).exists() or (out / n).is_symlink()]


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def clear_temporaries(out: Path, owner: Owner = EVAL) -> None:
    """Removes what killed writes of ours left in ``out`` (and its ``trajectories/``),
    completing a folder swap cut short."""
    temporaries.clear_stale(out, allowed=owner.allows)
    if owner is EVAL and (out / "trajectories").is_dir():
        temporaries.clear_stale(out / "trajectories")


def _refusal(owner: Owner, manifest: dict[str, Any] | None, identity: dict[str, Any],
             entries: list[Path]) -> str:
    if manifest is None:
        shown = sorted(p.name for p in entries)[:5]
        return f"is not empty and was not written by {owner.kind} (it holds {shown})"
    if _normal(manifest.get("identity", {})) == _normal(identity):  # a training, not resumed
        return ("holds a training of this config; pass --resume CHECKPOINT.zip to continue it "
                "there")
    held = _describe(manifest.get("identity", {}), owner)
    why = f"holds {held}, this run is {_describe(identity, owner)}"
    if held == _describe(identity, owner):
        why += (" (same names, but the cases, policy files, presets or the content of the "
                "files the cases read differ)"
                if owner is EVAL else " (its other settings differ)")
    held_inputs = manifest.get("identity", {}).get("inputs") or {}
    inputs = identity.get("inputs") or {}
    if isinstance(held_inputs, dict) and isinstance(inputs, dict):
        edited = sorted(p for p in held_inputs.keys() & inputs.keys()
                        if held_inputs[p] != inputs[p])
        if edited:
            why += f"; edited since: {edited[:3]}"
    return why


def claim(out: Path, identity: dict[str, Any], *, overwrite: bool = False,
          owner: Owner = EVAL, resume: bool = True) -> bool:
    """Makes ``out`` the folder of the run ``identity`` of ``owner``; returns True when it
    goes on with an earlier run of the same identity there.

    A missing or empty folder is taken; a folder of the same identity is resumed when
    ``resume`` (unless ``overwrite``); anything else raises ``ValueError`` unless
    ``overwrite``, which first removes what an earlier run of ours wrote there (listed in its
    manifest, and only names ``owner`` writes) and nothing else. A folder that another command
    owns (its manifest says so) is refused even with ``overwrite``. Abandoned temporaries of
    ours are removed once the folder is taken.
    """
    check_target(out)
    found = _read(out) if out.is_dir() else None
    if found is not None and "kind" in found and found.get("kind") != owner.kind:
        raise ValueError(f"output folder {out} belongs to {found.get('kind')} (its {MANIFEST}); "
                         f"{owner.kind} never writes into it, even with --overwrite: choose "
                         f"another --out")
    manifest = read_manifest(out, owner) if out.is_dir() else None
    same = manifest is not None and _normal(manifest.get("identity", {})) == _normal(identity)
    if same and resume and not overwrite:
        clear_temporaries(out, owner)
        return True
    abandoned = set(temporaries.stale(out)) if out.is_dir() else set()
    entries = [p for p in out.iterdir() if p not in abandoned] if out.is_dir() else []
    if entries and not overwrite:
        raise ValueError(f"output folder {out} {_refusal(owner, manifest, identity, entries)}"
                         f"; pass --overwrite (overwrite=True) to replace our earlier outputs "
                         f"there, or choose another --out")
    if out.is_dir():
        clear_temporaries(out, owner)
    for path in _ours(out, manifest, owner):
        _remove(path)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / MANIFEST, {"kind": owner.kind, "identity": identity,
                                "files": list(owner.outputs)})
    return False


def record_files(out: Path, names: Iterable[str], owner: Owner = EVAL) -> None:
    """Adds top-level entries of ``out`` to its manifest (what ``--overwrite`` may remove):
    only names ``owner`` writes."""
    manifest = read_manifest(out, owner)
    if manifest is None:
        return
    files = list(dict.fromkeys([*manifest.get("files", []), *filter(owner.allows, names)]))
    if files != manifest.get("files"):
        write_json(out / MANIFEST, {**manifest, "files": files})


def record_entry(out: Path, key: str, value: Any, owner: Owner = EVAL) -> None:
    """Sets ``key`` of the folder's manifest to ``value`` (a JSON value; ``kind``,
    ``identity`` and ``files`` are the folder's own and never set here)."""
    if key in ("kind", "identity", "files"):
        raise ValueError(f"manifest entry {key!r} is the folder's own")
    manifest = read_manifest(out, owner)
    if manifest is not None and manifest.get(key) != value:
        write_json(out / MANIFEST, {**manifest, key: value})
