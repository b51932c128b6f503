"""Episode trajectories as arrays, to and from Parquet.

A :class:`Recording` holds the state at reset (sample 0) and after every control step: time,
per-robot position, velocity and commanded velocity, the leader first. Its :meth:`metrics`
are :func:`boids_env.metrics.episode_metrics` of the samples after each step, so they equal
the live env's numbers.

Parquet layout: one row per (step, robot) with columns ``step, time, robot, x, y, vx, vy,
cmd_vx, cmd_vy``; the resolved config (JSON) is in the schema metadata under ``boids_env``.
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

if TYPE_CHECKING:
    from boids_env.environment import BoidsEnv

FloatArray = npt.NDArray[np.float64]
COLUMNS = ("step", "time", "robot", "x", "y", "vx", "vy", "cmd_vx", "cmd_vy")


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

    def metrics(self) -> dict[str, Any]:
        """The episode's V_*, extra flock and safety metrics, from the samples after each
        step."""
        cfg = self.config
        return metrics.episode_metrics(self.positions[1:], self.velocities[1:],
                                       self.commanded[1:], cfg.metrics, cfg.world.dt,
                                       cfg.world.robot_radius, cfg.world.arena_half_size,
                                       self.leader_path)

    def to_parquet(self, path: str | Path) -> None:
        """Writes the tidy table with the config in the schema metadata."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        steps, n = self.positions.shape[:2]
        cols = {
            "step": np.repeat(np.arange(steps), n),
            "time": np.repeat(self.time, n),
            "robot": np.tile(np.arange(n), steps),
            "x": self.positions[..., 0].ravel(), "y": self.positions[..., 1].ravel(),
            "vx": self.velocities[..., 0].ravel(), "vy": self.velocities[..., 1].ravel(),
            "cmd_vx": self.commanded[..., 0].ravel(), "cmd_vy": self.commanded[..., 1].ravel(),
        }
        for name, vec in (self.forces or {}).items():
            full = np.full((steps, n, 2), np.nan)  # the leader's rows: NaN
            full[:, 1:] = vec
            cols[f"force_{name}_x"] = full[..., 0].ravel()
            cols[f"force_{name}_y"] = full[..., 1].ravel()
        table = pa.table(cols)
        meta = {"config": self.config.to_dict(), "extra": self.extra,
                "leader_path": None if self.leader_path is None else self.leader_path.tolist()}
        table = table.replace_schema_metadata({"boids_env": json.dumps(meta)})
        pq.write_table(table, str(path))

    @classmethod
    def from_parquet(cls, path: str | Path) -> Recording:
        """Reads a file written by :meth:`to_parquet`; a clear ``ValueError`` otherwise."""
        import pyarrow.parquet as pq

        try:
            table = pq.read_table(str(path))
        except FileNotFoundError:
            raise
        except Exception as exc:
            raise ValueError(f"cannot read recording {path}: not a Parquet file ({exc})") from exc
        missing = [c for c in COLUMNS if c not in table.column_names]
        raw = (table.schema.metadata or {}).get(b"boids_env")
        if missing or raw is None:
            raise ValueError(f"{path} is not a boids-env recording (missing columns {missing} "
                             f"or metadata)")
        meta = json.loads(raw)
        data = {c: table.column(c).to_numpy() for c in COLUMNS}
        n = int(data["robot"].max()) + 1
        steps = len(data["robot"]) // n
        order = np.lexsort((data["robot"], data["step"]))

        def pair(a: str, b: str) -> FloatArray:
            return np.stack([data[a][order], data[b][order]], axis=1).reshape(steps, n, 2)

        path = meta.get("leader_path")
        names = [c[len("force_"):-2] for c in table.column_names
                 if c.startswith("force_") and c.endswith("_x")]
        data.update({c: table.column(c).to_numpy() for c in table.column_names
                     if c.startswith("force_")})
        forces = {name: pair(f"force_{name}_x", f"force_{name}_y")[:, 1:].copy()
                  for name in names} or None
        return cls(EnvConfig.from_dict(meta["config"]), data["time"][order][::n].copy(),
                   pair("x", "y"), pair("vx", "vy"), pair("cmd_vx", "cmd_vy"),
                   meta.get("extra", {}),
                   None if path is None else np.asarray(path, dtype=float).reshape(-1, 2),
                   forces)


class Recorder:
    """Collects an env's samples: call :meth:`capture` after reset and after every step."""

    def __init__(self) -> None:
        self._time: list[float] = []
        self._pos: list[FloatArray] = []
        self._vel: list[FloatArray] = []
        self._cmd: list[FloatArray] = []
        self._forces: list[dict[str, FloatArray]] = []

    def capture(self, env: BoidsEnv) -> None:
        world = env._require_world()
        self._time.append(world.time)
        self._pos.append(world.positions.copy())
        self._vel.append(world.velocities.copy())
        self._cmd.append(world.commanded.copy())
        self._forces.append({k: np.array(v, dtype=float) for k, v in env.overlays.items()})

    def recording(self, env: BoidsEnv, **extra: Any) -> Recording:
        path = env.leader.reference_path()
        return Recording(env.episode_config, np.array(self._time), np.array(self._pos),
                         np.array(self._vel), np.array(self._cmd), dict(extra),
                         None if path is None else np.asarray(path, dtype=float),
                         self._stacked_forces())

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
