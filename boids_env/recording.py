"""Episode trajectories as arrays, to and from Parquet.

A :class:`Recording` holds the state at reset (sample 0) and after every control step: time,
per-robot position, velocity and commanded velocity, the leader first. Its :meth:`metrics`
are :func:`boids_env.metrics.episode_metrics` of the samples after each step, so they equal
the live env's numbers.

Parquet layout: one row per (step, robot) with columns ``step, time, robot, x, y, vx, vy,
cmd_vx, cmd_vy``; for robots with a heading also ``heading`` (rad), ``angular_velocity``
(rad/s) and the native command ``cmd_v`` (m/s), ``cmd_w`` (rad/s); the resolved config (JSON)
is in the schema metadata under ``boids_env``.

Files carry Parquet's page checksums and a digest of their schema and metadata, verified on
reading (:mod:`boids_env.parquet`): a file damaged on disk or in transfer is refused by name,
never read back as other numbers.

With a crowd (``crowd = P``) the pedestrians follow the robots as rows ``robot = N … N+P-1``
(their command columns hold their velocity).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from boids_env import metrics
from boids_env.config import EnvConfig
from boids_env.parquet import read_table, write_table

if TYPE_CHECKING:
    from boids_env.environment import BoidsEnv

FloatArray = npt.NDArray[np.float64]
COLUMNS = ("step", "time", "robot", "x", "y", "vx", "vy", "cmd_vx", "cmd_vy")
HEADING_COLUMNS = ("heading", "angular_velocity", "cmd_v", "cmd_w")
"""Columns of robots with a heading (all four or none)."""


@dataclass
class Recording:
    """One episode's samples: arrays of shape (T+1, N, 2) with sample 0 the reset state."""

    config: EnvConfig
    time: FloatArray
    positions: FloatArray
    velocities: FloatArray
    commanded: FloatArray
    extra: dict[str, Any] = field(default_factory=dict)
    """Free-form metadata (policy, seed, ...), stored with the file."""
    leader_path: FloatArray | None = None
    """The leader's scripted path as a polyline (M, 2) (None when unknown or external), for
    its path deviation."""
    forces: dict[str, FloatArray] | None = None
    """Per-follower vectors behind each sample's command, by name, each (T+1, N-1, 2): the
    Reynolds policy's weighted rule forces (N; the leader term in m), zero at reset; None
    when the policy exposes none. Drawn as arrows in videos and ROS bag markers."""
    headings: FloatArray | None = None
    """(T+1, N) headings (rad, in [−π, π]) of robots that have one; None otherwise."""
    angular_velocities: FloatArray | None = None
    """(T+1, N) turn rates (rad/s) of robots with a heading; None otherwise."""
    native: FloatArray | None = None
    """(T+1, N, 2) commands as the robots' drivers took them, (v, ω) (what ``cmd_vel``
    carries for a robot with a heading; zero at reset); None for holonomic robots."""

    pedestrians: FloatArray | None = None
    """The crowd's positions (T+1, P, 2) (None without a crowd)."""
    pedestrian_velocities: FloatArray | None = None
    """The crowd's velocities (T+1, P, 2) (None without a crowd)."""

    def metrics(self) -> dict[str, Any]:
        """The episode's V_*, extra flock and safety metrics, from the samples after each
        step (and the proxemics when a person leads or a crowd walks)."""
        cfg = self.config
        sc = cfg.scenario
        crowd = None if self.pedestrians is None else self.pedestrians[1:]
        return metrics.episode_metrics(self.positions[1:], self.velocities[1:],
                                       self.commanded[1:], cfg.metrics, cfg.world.dt,
                                       cfg.world.robot_radius, cfg.scene, self.leader_path,
                                       person_radius=sc.leader_radius, pedestrians=crowd,
                                       pedestrian_radius=sc.person_radius,
                                       headings=None if self.headings is None
                                       else self.headings[1:])

    def to_parquet(self, path: str | Path) -> None:
        """Writes the tidy table with the config in the schema metadata, atomically: a
        temporary file beside ``path`` is renamed over it when complete, so an existing file
        survives a failed write (a full disk, Ctrl-C)."""
        import pyarrow as pa

        if Path(path).is_dir():
            raise IsADirectoryError(f"cannot write a recording to {path}: it is a folder")
        pos, vel, cmd = self.positions, self.velocities, self.commanded
        if self.pedestrians is not None and self.pedestrian_velocities is not None:
            pos = np.concatenate([pos, self.pedestrians], axis=1)
            vel = np.concatenate([vel, self.pedestrian_velocities], axis=1)
            cmd = np.concatenate([cmd, self.pedestrian_velocities], axis=1)
        steps, n = pos.shape[:2]
        robots = self.positions.shape[1]
        cols = {
            "step": np.repeat(np.arange(steps), n),
            "time": np.repeat(self.time, n),
            "robot": np.tile(np.arange(n), steps),
            "x": pos[..., 0].ravel(), "y": pos[..., 1].ravel(),
            "vx": vel[..., 0].ravel(), "vy": vel[..., 1].ravel(),
            "cmd_vx": cmd[..., 0].ravel(), "cmd_vy": cmd[..., 1].ravel(),
        }
        if self.headings is not None:
            assert self.angular_velocities is not None and self.native is not None
            cols.update(heading=self.headings.ravel(),
                        angular_velocity=self.angular_velocities.ravel(),
                        cmd_v=self.native[..., 0].ravel(), cmd_w=self.native[..., 1].ravel())
        for name, vec in (self.forces or {}).items():
            full = np.full((steps, n, 2), np.nan)  # the leader's and pedestrians' rows: NaN
            full[:, 1:robots] = vec
            cols[f"force_{name}_x"] = full[..., 0].ravel()
            cols[f"force_{name}_y"] = full[..., 1].ravel()
        table = pa.table(cols)
        meta = {"config": self.config.to_dict(), "extra": self.extra,
                "leader_path": None if self.leader_path is None else self.leader_path.tolist()}
        write_table(table.replace_schema_metadata({"boids_env": json.dumps(meta)}), path)

    @classmethod
    def from_parquet(cls, path: str | Path) -> Recording:
        """Reads a file written by :meth:`to_parquet`.

        Raises ``FileNotFoundError`` for a missing file and a ``ValueError`` naming the file
        and the problem for anything that is not exactly one recording: a folder (a dataset
        of several files), an empty or unreadable file, a damaged one (a page or the metadata
        failing its checksum), missing columns, bad metadata, a config that disagrees with the
        data, duplicated, missing, negative or out-of-range step and robot indices, non-finite
        values. Indices are bounded by the number of rows before anything is allocated from
        them.
        """
        path = Path(path)
        if path.is_dir():
            raise ValueError(f"{path} is a folder, not a recording file (one recording is one "
                             f"Parquet file written by Recording.to_parquet)")
        if not path.exists():
            raise FileNotFoundError(f"recording not found: {path}")
        try:
            table = read_table(path)
        except ValueError as exc:
            raise ValueError(f"cannot read recording {path}: {exc}") from exc
        missing = [c for c in COLUMNS if c not in table.column_names]
        raw = (table.schema.metadata or {}).get(b"boids_env")
        if missing or raw is None:
            raise ValueError(f"{path} is not a boids-env recording (missing columns {missing} "
                             f"or metadata)")
        config, extra, leader_path = _read_meta(path, raw)
        data = _read_columns(path, table)
        steps, n, order = _sample_grid(path, data)
        robots, crowd = config.scenario.robots, config.scenario.crowd
        if robots + crowd != n:
            said = f"robots={robots}" + (f" and crowd={crowd}" if crowd else "")
            raise ValueError(f"{path}: its config says {said} but the data hold {n} "
                             f"{'bodies' if crowd else 'robots'}")
        time = data["time"][order].reshape(steps, n)
        if np.any(time != time[:, :1]):
            step = int(np.nonzero(np.any(time != time[:, :1], axis=1))[0][0])
            raise ValueError(f"{path}: the robots of step {step} have different times")

        def pair(a: str, b: str) -> FloatArray:
            return np.stack([data[a][order], data[b][order]], axis=1).reshape(steps, n, 2)

        names = _force_names(path, table.column_names)
        data.update(_force_columns(path, table, names))
        forces = {name: pair(f"force_{name}_x", f"force_{name}_y")[:, 1:robots].copy()
                  for name in names} or None
        pos, vel, cmd = pair("x", "y"), pair("vx", "vy"), pair("cmd_vx", "cmd_vy")
        crowd_pos = pos[:, robots:].copy() if crowd else None
        crowd_vel = vel[:, robots:].copy() if crowd else None
        heading = _heading_columns(path, table, order, steps, n) if not crowd else (
            None, None, None)
        return cls(config, time[:, 0].copy(), pos[:, :robots].copy(), vel[:, :robots].copy(),
                   cmd[:, :robots].copy(), extra, leader_path, forces, *heading,
                   pedestrians=crowd_pos, pedestrian_velocities=crowd_vel)


def _heading_columns(path: Path, table: Any, order: npt.NDArray[np.intp], steps: int, n: int
                     ) -> tuple[FloatArray | None, FloatArray | None, FloatArray | None]:
    """(headings, angular velocities, native commands) of a recording with the heading
    columns, as (T+1, N) and (T+1, N, 2) arrays; Nones without them; ``ValueError`` for some
    but not all of them or for non-finite values."""
    present = [c for c in HEADING_COLUMNS if c in table.column_names]
    if not present:
        return None, None, None
    if len(present) != len(HEADING_COLUMNS):
        raise ValueError(f"{path}: a recording with headings has the columns "
                         f"{list(HEADING_COLUMNS)}; this one has only {present}")
    cols = {}
    for name in HEADING_COLUMNS:
        values = table.column(name).to_numpy(zero_copy_only=False)
        if values.dtype.kind not in "fiu" or not np.all(np.isfinite(values)):
            raise ValueError(f"{path}: column {name!r} must hold finite numbers")
        cols[name] = values.astype(np.float64)[order].reshape(steps, n)
    return (cols["heading"], cols["angular_velocity"],
            np.stack([cols["cmd_v"], cols["cmd_w"]], axis=-1))


def _read_meta(path: Path, raw: bytes) -> tuple[EnvConfig, dict[str, Any], FloatArray | None]:
    """The config, extra and leader path of a recording's metadata; ``ValueError`` naming the
    file otherwise."""
    try:
        meta = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: its boids_env metadata is not valid JSON ({exc})") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("config"), dict):
        raise ValueError(f"{path}: its boids_env metadata has no config table")
    try:
        config = EnvConfig.from_dict(meta["config"])
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path}: its config metadata is invalid: {exc}") from None
    extra = meta.get("extra", {})
    if not isinstance(extra, dict):
        raise ValueError(f"{path}: its extra metadata must be a table, got {extra!r}")
    raw_path = meta.get("leader_path")
    if raw_path is None:
        return config, extra, None
    try:
        leader_path = np.asarray(raw_path, dtype=float).reshape(-1, 2)
    except (ValueError, TypeError):
        leader_path = None
    if leader_path is None or not np.all(np.isfinite(leader_path)):
        raise ValueError(f"{path}: its leader_path metadata must be a list of finite (x, y) "
                         f"points")
    return config, extra, leader_path


def _read_columns(path: Path, table: Any) -> dict[str, npt.NDArray[Any]]:
    """The recording's columns as numpy arrays: integer step and robot, finite floats."""
    data: dict[str, npt.NDArray[Any]] = {}
    for name in COLUMNS:
        column = table.column(name).to_numpy(zero_copy_only=False)
        if name in ("step", "robot"):
            if column.dtype.kind not in "iu":
                raise ValueError(f"{path}: column {name!r} must hold integers, got "
                                 f"{column.dtype}")
        else:
            if column.dtype.kind not in "fiu":
                raise ValueError(f"{path}: column {name!r} must hold numbers, got "
                                 f"{column.dtype}")
            column = column.astype(np.float64)
            if not np.all(np.isfinite(column)):
                raise ValueError(f"{path}: column {name!r} holds non-finite values")
        data[name] = column
    if not len(data["step"]):
        raise ValueError(f"{path} holds no samples (an empty recording)")
    return data


def _force_names(path: Path, columns: list[str]) -> list[str]:
    """The rule names of the ``force_<name>_x`` / ``force_<name>_y`` column pairs."""
    forces = [c for c in columns if c.startswith("force_")]
    names = [c[len("force_"):-2] for c in forces if c.endswith("_x")]
    paired = {f"force_{n}_{axis}" for n in names for axis in "xy"}
    if set(forces) != paired:
        odd = sorted(set(forces) ^ paired)
        raise ValueError(f"{path}: force columns must come in _x/_y pairs; {odd} lack their "
                         f"other half")
    return names


def _force_columns(path: Path, table: Any, names: list[str]) -> dict[str, npt.NDArray[Any]]:
    """The force columns as float arrays (NaN in the leader's rows)."""
    out = {}
    for name in (f"force_{n}_{axis}" for n in names for axis in "xy"):
        column = table.column(name).to_numpy()
        if column.dtype.kind not in "fiu":
            raise ValueError(f"{path}: column {name!r} must hold numbers, got {column.dtype}")
        out[name] = column.astype(np.float64)
    return out


def _sample_grid(path: Path, data: dict[str, npt.NDArray[Any]]
                 ) -> tuple[int, int, npt.NDArray[np.intp]]:
    """(steps, robots, row order) of a complete (step, robot) grid: every step 0..T-1 holds
    every robot 0..N-1 exactly once; ``ValueError`` naming what is wrong otherwise."""
    step, robot = data["step"].astype(np.int64), data["robot"].astype(np.int64)
    rows = len(step)
    for name, values in (("step", step), ("robot", robot)):
        if values.min() < 0:
            raise ValueError(f"{path}: {name} indices must be >= 0, got {int(values.min())}")
        # a complete grid of R rows has indices below R: a larger one is refused before it
        # sizes anything (a robot index of 2**40 asked for 8 TiB)
        if values.max() >= rows:
            raise ValueError(f"{path}: {name} index {int(values.max())} is beyond the file's "
                             f"{rows} rows (each step holds every robot once)")
    n, steps = int(robot.max()) + 1, int(step.max()) + 1
    order = np.lexsort((robot, step))
    pairs = np.stack([step[order], robot[order]], axis=1)
    same = np.all(pairs[1:] == pairs[:-1], axis=1)
    if np.any(same):
        s, r = pairs[1:][same][0]
        raise ValueError(f"{path}: {int(same.sum())} duplicated (step, robot) rows, e.g. step "
                         f"{s} robot {r} (several recordings in one file?)")
    if len(step) != steps * n:
        have_robots = np.bincount(robot, minlength=n)
        short = np.nonzero(have_robots < steps)[0][:5].tolist()
        raise ValueError(f"{path}: incomplete samples: {len(step)} rows for steps 0..{steps - 1}"
                         f" × robots 0..{n - 1} ({steps * n} expected); robots {short} lack "
                         f"some steps")
    return steps, n, order

class Recorder:
    """Collects an env's samples: call :meth:`capture` after reset and after every step."""

    def __init__(self) -> None:
        self._time: list[float] = []
        self._pos: list[FloatArray] = []
        self._vel: list[FloatArray] = []
        self._cmd: list[FloatArray] = []
        self._forces: list[dict[str, FloatArray]] = []
        self._crowd: list[tuple[FloatArray, FloatArray]] = []
        self._heading: list[tuple[FloatArray, FloatArray, FloatArray]] = []

    def capture(self, env: BoidsEnv) -> None:
        world = env._require_world()
        self._time.append(world.time)
        self._pos.append(world.positions.copy())
        self._vel.append(world.velocities.copy())
        self._cmd.append(world.commanded.copy())
        if world.p:
            self._crowd.append((world.pedestrian_positions.copy(),
                                world.pedestrian_velocities.copy()))
        self._forces.append({k: np.array(v, dtype=float) for k, v in env.overlays.items()})
        if world.native is not None:
            headings, turns = world.headings, world.angular_velocities
            # native commands are a drive with a heading's, which reports both
            assert headings is not None and turns is not None
            self._heading.append((headings, turns, world.native.copy()))

    def recording(self, env: BoidsEnv, **extra: Any) -> Recording:
        path = env.leader.reference_path()
        crowd = (np.array([c[0] for c in self._crowd]), np.array([c[1] for c in self._crowd])
                 ) if self._crowd else (None, None)
        angles: FloatArray | None = None
        turns: FloatArray | None = None
        native: FloatArray | None = None
        if self._heading:
            angles, turns, native = (np.array(part) for part in zip(*self._heading, strict=True))
        return Recording(env.episode_config, np.array(self._time), np.array(self._pos),
                         np.array(self._vel), np.array(self._cmd), dict(extra),
                         None if path is None else np.asarray(path, dtype=float),
                         self._stacked_forces(), angles, turns, native, pedestrians=crowd[0],
                         pedestrian_velocities=crowd[1])

    def _stacked_forces(self) -> dict[str, FloatArray] | None:
        """The captured overlays as (T+1, F, 2) arrays (zero where a sample had none)."""
        names = list(dict.fromkeys(k for f in self._forces for k in f))
        if not names:
            return None
        followers = self._pos[0].shape[0] - 1
        out = {name: np.zeros((len(self._forces), followers, 2)) for name in names}
        for i, sample in enumerate(self._forces):
            for name, vec in sample.items():
                if vec.shape == (followers, 2):
                    out[name][i] = vec
        return out
