"""An output folder that one ``boids run`` owns, so outputs of two runs are never mixed.

- A folder that holds anything is refused unless ``overwrite`` is given.
- With ``overwrite`` only what an earlier run of ours wrote is removed: every run writes a
  manifest (``manifest.json``) listing its outputs, and only the entries it lists are ever
  deleted, so a user's own files in the folder are kept. Outputs of ours that no manifest
  lists (a folder from before manifests existed) are refused, naming them, rather than left
  stale beside the new run's.
- The run writes into a temporary folder beside the target and moves it into place only
  when everything is written: a run that is killed or fails leaves the earlier run's folder
  as it was, never a half-written one (POSIX ``rename`` is atomic within a file system).
- The move itself is crash-safe (:mod:`boids_env.temporaries`): a folder holding only our
  run is swapped for the new one in one system call where the OS can, so ``--out`` is never
  missing; with the user's files beside ours, each of our entries is replaced atomically,
  the manifest last, from a journal that the next run into the same ``--out`` completes if
  the process was killed half-way. What a killed run leaves beside ``--out`` (its temporary
  folder, with a marker proving it ours) is removed by the next run into that ``--out``.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from types import TracebackType
from typing import Any

from boids_env import temporaries
from boids_env.files import write_json

MANIFEST = "manifest.json"
"""The file in a run folder that lists what the run wrote."""
RUN_OUTPUTS = frozenset({"metrics.json", "config.json", "trajectory.parquet", "episode.gif",
                         "episode.mp4", "episode.bag", "episode_mcap", MANIFEST})
"""Every name a ``boids run`` may write (an unlisted one of these is an earlier run's)."""


def _listed(folder: Path) -> set[str]:
    """Names the folder's manifest says an earlier run of ours wrote (empty without one)."""
    import json

    path = folder / MANIFEST
    if not path.is_file():
        return set()
    try:
        data = json.loads(path.read_text())
        files = data["files"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path} is not a boids run manifest ({exc}); delete it or choose "
                         f"another --out") from exc
    if "kind" in data:  # boids eval and boids train own their folders too
        raise FileExistsError(f"--out {folder} belongs to {data['kind']} (its {MANIFEST}); "
                              f"boids run never writes into it, even with --overwrite: choose "
                              f"another --out")
    # a manifest never names anything outside its folder
    return {str(f) for f in files if isinstance(f, str) and "/" not in f and f not in ("",
                                                                                     ".", "..")}


class RunFolder:
    """The output folder of one run, used as a context manager that yields the temporary
    folder to write to::

        with RunFolder("runs/latest", overwrite=True) as folder:
            write_json(folder / "metrics.json", metrics)
        # now runs/latest holds exactly this run's files (plus the user's own) and a manifest

    The checks run at construction, so a refused folder fails before any work is done.

    Args:
        out: the folder the run's outputs end up in.
        overwrite: replace an earlier run's outputs (only those its manifest lists).
        command: what wrote the folder, recorded in the manifest.
    """

    def __init__(self, out: str | Path, *, overwrite: bool = False,
                 command: str = "boids run") -> None:
        self.out = Path(out)
        self.overwrite = overwrite
        self.command = command
        self.tmp: Path | None = None
        self._box: Path | None = None
        self.kept: list[str] = []
        """The user's own entries found in the folder and left in place."""
        self.replaced: list[str] = []
        """An earlier run's entries that were removed."""
        if self.out.parent.is_dir():  # what a killed run into this --out left beside it
            temporaries.clear_stale(self.out.parent, self.out.name, allowed=self._ours_to_move)
        self._check()

    def _ours_to_move(self, name: str) -> bool:
        """Names a commit of ours into ``out`` moves: the folder, and a run's outputs in it."""
        return name == self.out.name or name in RUN_OUTPUTS

    def _check(self) -> tuple[set[str], list[str]]:
        """(entries an earlier run of ours listed, the user's own entries); raises when the
        folder may not be written."""
        out = self.out
        if out.exists() and not out.is_dir():
            raise FileExistsError(f"--out {out} is a file, not a folder")
        entries = sorted(p.name for p in out.iterdir()) if out.is_dir() else []
        if not entries:
            return set(), []
        if not self.overwrite:
            shown = ", ".join(entries[:6]) + (", …" if len(entries) > 6 else "")
            raise FileExistsError(
                f"--out {out} is not empty ({shown}); a run writes to a folder of its own: "
                f"pass --overwrite to replace what an earlier boids run wrote there (your "
                f"own files are kept), or choose another --out")
        listed = _listed(out) & RUN_OUTPUTS  # never anything but our own names
        ours = {e for e in entries if e in listed or e == MANIFEST}
        unlisted = [e for e in entries if e not in ours and e in RUN_OUTPUTS]
        if unlisted:
            raise FileExistsError(
                f"--out {out} holds {', '.join(unlisted)}, outputs of a boids run that no "
                f"{MANIFEST} lists (an older version wrote them); --overwrite only removes "
                f"what a manifest lists: delete them yourself or choose another --out")
        return ours, [e for e in entries if e not in ours]

    def __enter__(self) -> Path:
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self._box = temporaries.create(self.out, "run")
        self.tmp = self._box / "new"
        self.tmp.mkdir()
        return self.tmp

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        assert self._box is not None and self.tmp is not None, \
            "RunFolder used outside a with block"
        try:
            if kind is None:
                self._commit(self._box, self.tmp)
        finally:
            shutil.rmtree(self._box, ignore_errors=True)

    def _commit(self, box: Path, tmp: Path) -> None:
        written = sorted(p.name for p in tmp.iterdir())
        unknown = set(written) - RUN_OUTPUTS
        assert not unknown, f"RUN_OUTPUTS lacks {unknown}: --overwrite could not remove them"
        manifest: dict[str, Any] = {"written_by": self.command, "files": written,
                                    "time": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        write_json(tmp / MANIFEST, manifest)
        ours, foreign = self._check()  # again: the folder may have changed during the run
        out = self.out
        self.replaced = sorted(ours - {MANIFEST})
        self.kept = foreign
        movable = out.resolve() != Path.cwd().resolve() and not out.is_mount()
        if not foreign and movable:
            # nothing of the user's in it: swap the whole folder (never a mixed folder); the
            # working directory or a mount point cannot be moved, so those go entry by entry
            temporaries.replace_folder(box, tmp, out)
            return
        # the user's own files stay: replace our entries one by one, the manifest last
        temporaries.replace_entries(box, tmp, [*written, MANIFEST],
                                    remove=sorted(ours - {MANIFEST}))
