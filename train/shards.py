"""The env copies of a training, stepped in this process or in worker processes.

Nothing here imports torch or Stable-Baselines3: a worker process (``_worker``) imports this
module to unpickle its :class:`CopySpec` list and step its shard. Started by ``boids train``
(whose ``__main__``, the one module the forkserver preloads, imports no torch either), a
worker of ``ppo_safe``'s copies held 182 MiB instead of 379 MiB, and building and resetting
the copies in two processes took 1.7-2.1 s instead of 3.6-4.3 s, against the worker
importing the learner's modules (2 cores). The VecEnv over the shards is
:class:`boids_env.train.vec_env.FlockVecEnv`.
"""

from __future__ import annotations

import multiprocessing as mp
import traceback
from collections.abc import Sequence
from dataclasses import dataclass, field
from multiprocessing import shared_memory
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import kernels
from boids_env.batch import EnvBatch
from boids_env.environment import BoidsEnv

EPISODE_INFO = "flock_episode"
"""Info key, on the first slot of a copy whose episode just ended: that episode's V_*,
group size and leader speed (for logging training metrics)."""


@dataclass(frozen=True)
class CopySpec:
    """One env copy: its group size, fixed env fields and per-episode sampled options."""

    robots: int = 13
    leader_speeds: tuple[float, ...] = (0.55,)
    """Each episode's leader speed is drawn uniformly from these (m/s)."""
    paths: tuple[str, ...] = ("square",)
    """Each episode's leader path is drawn uniformly from these; none (``()``): the path of
    ``env_fields`` (a scene's own)."""
    env_fields: dict[str, Any] = field(default_factory=dict)
    """Other EnvConfig fields by flat name (e.g. ``max_cycles``)."""
    choices: dict[str, tuple[Any, ...]] = field(default_factory=dict)
    """More reset options drawn uniformly per episode, by name (``path_rotation``,
    ``path_mirror``, ``obs_noise``, …), drawn in sorted name order after speed and path."""

    def draw(self, rng: np.random.Generator) -> dict[str, Any]:
        """One episode's reset options."""
        options = {"leader_speed": float(self.leader_speeds[rng.integers(len(self.leader_speeds))])}
        if self.paths:
            options["path"] = str(self.paths[rng.integers(len(self.paths))])
        for name in sorted(self.choices):
            values = self.choices[name]
            value = values[rng.integers(len(values))]
            options[name] = value.item() if isinstance(value, np.generic) else value
        return options

    def make(self) -> BoidsEnv:
        return BoidsEnv(robots=self.robots, **self.env_fields)


class Shard:
    """Copies stepped together, in this process or in a worker; arrays in, arrays out."""

    def __init__(self, specs: Sequence[CopySpec]) -> None:
        # Training steps its copies for millions of steps, so the compiled kernels' load
        # (about half a second) is repaid at once; left to the lazy load, a process would
        # switch over mid-rollout after some 400 steps of the numpy reference (same bits).
        kernels.load()
        self.specs = list(specs)
        self.envs = [spec.make() for spec in self.specs]
        self.batch = EnvBatch(self.envs)
        self.sizes = self.batch.sizes
        self.rngs = [np.random.default_rng(0) for _ in self.envs]
        self.obs_size = self.envs[0].observation_space(self.envs[0].possible_agents[0]).shape[0]
        # What each copy's episode so far is made of (its reset's seed and options, then the
        # actions of every step since), so :meth:`state` can describe it as plain data and
        # :meth:`restore` rebuild it bit for bit by replaying it. One array a step for the
        # whole shard (no per-copy work on the hot path); the rows before the oldest episode's
        # start are dropped when a copy resets.
        self._episodes: list[tuple[int, dict[str, Any]] | None] = [None] * len(self.envs)
        self._history: list[npt.NDArray[np.float32]] = []
        self._steps = 0
        """Steps of the shard since ``_history[0]``."""
        self._started = [0] * len(self.envs)
        """The step (counted as ``_steps``) each copy's episode started at."""

    def seed(self, seed_sequences: Sequence[np.random.SeedSequence]) -> None:
        self.rngs = [np.random.default_rng(s) for s in seed_sequences]

    def _reset_copy(self, i: int) -> npt.NDArray[np.float32]:
        spec, rng, env = self.specs[i], self.rngs[i], self.envs[i]
        options = spec.draw(rng)
        seed = int(rng.integers(2**31 - 1))
        self._episodes[i] = (seed, options)
        self._started[i] = self._steps
        return env.reset_arrays(seed=seed, options=options)

    def reset(self) -> npt.NDArray[np.float32]:
        self._history, self._steps = [], 0
        return np.concatenate([self._reset_copy(i) for i in range(len(self.envs))])

    def step(self, actions: npt.NDArray[np.float32]) -> tuple[
            npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.bool_],
            list[dict[str, Any]]]:
        """Steps every copy in one call (:class:`boids_env.batch.EnvBatch`, no per-agent
        dicts) and resets the copies whose episode ended."""
        result = self.batch.step_arrays(actions)
        self._history.append(np.array(actions, dtype=np.float32))
        self._steps += 1
        obs = result.observations
        rewards = result.rewards.astype(np.float32)
        dones = np.zeros(len(actions), dtype=bool)
        infos: list[dict[str, Any]] = [{} for _ in range(len(actions))]
        for i, env in enumerate(self.envs):
            start, stop = self.batch.bounds[i], self.batch.bounds[i + 1]
            if result.truncated[i]:
                m = env.episode_metrics()
                infos[start][EPISODE_INFO] = {
                    "V_sep": m["V_sep"], "V_coh": m["V_coh"], "V_align": m["V_align"],
                    "robots": self.specs[i].robots,
                    "leader_speed": env.episode_config.scenario.leader_speed}
                for k in range(start, stop):
                    infos[k]["terminal_observation"] = obs[k].copy()
                    infos[k]["TimeLimit.truncated"] = True
                dones[start:stop] = True
                obs[start:stop] = self._reset_copy(i)
        if result.truncated.any():
            self._forget()
        return obs, rewards, dones, infos

    def _forget(self) -> None:
        """Drops the history no copy's episode needs (the rows before the oldest start)."""
        drop = min(self._started)
        if drop:
            del self._history[:drop]
            self._steps -= drop
            self._started = [s - drop for s in self._started]

    def state(self) -> list[dict[str, Any]]:
        """Each copy's episode as plain data: the reset's seed and options, the actions of
        its steps so far (F, 2) per step, and the copy's random stream (whose next draws make
        its next episode); :meth:`restore` rebuilds the shard from it bit for bit."""
        out = []
        for i, episode in enumerate(self._episodes):
            if episode is None:
                raise RuntimeError("the env copies have not been reset: no episode to save")
            start, stop = self.batch.bounds[i], self.batch.bounds[i + 1]
            rows = self._history[self._started[i]:]
            actions = (np.stack([r[start:stop] for r in rows]) if rows
                       else np.zeros((0, stop - start, 2), np.float32))
            out.append({"seed": episode[0], "options": episode[1], "actions": actions,
                        "rng": self.rngs[i].bit_generator.state})
        return out

    def restore(self, states: Sequence[dict[str, Any]]) -> npt.NDArray[np.float32]:
        """The copies rebuilt from :meth:`state`'s data: each reset with its seed and options
        and stepped with its actions (each copy alone, as bit-identical as stepped in the
        batch), its random stream set; returns the observations the last step gave."""
        if len(states) != len(self.envs):
            raise ValueError(f"the saved env state holds {len(states)} copies, this shard "
                             f"{len(self.envs)}")
        obs, longest = [], max(len(s["actions"]) for s in states)
        self._history = [np.zeros((self.batch.rows, 2), np.float32) for _ in range(longest)]
        self._steps = longest
        for i, (env, saved) in enumerate(zip(self.envs, states, strict=True)):
            seed, options = int(saved["seed"]), dict(saved["options"])
            actions = np.asarray(saved["actions"], dtype=np.float32)
            copy_obs = env.reset_arrays(seed=seed, options=options)
            for action in actions:
                copy_obs = env.step_arrays(action).observations
            self.rngs[i].bit_generator.state = saved["rng"]
            self._episodes[i] = (seed, options)
            self._started[i] = longest - len(actions)
            start, stop = self.batch.bounds[i], self.batch.bounds[i + 1]
            for row, action in zip(self._history[self._started[i]:], actions, strict=True):
                row[start:stop] = action
            obs.append(copy_obs)
        self.batch._fused = None  # its constants are rebuilt from the copies' new episodes
        return np.concatenate(obs)

    def call(self, copy: int, method: str, *args: Any, **kwargs: Any) -> Any:
        return getattr(self.envs[copy], method)(*args, **kwargs)

    def get(self, copy: int, attr: str) -> Any:
        return getattr(self.envs[copy], attr)

    def set(self, copy: int, attr: str, value: Any) -> None:
        setattr(self.envs[copy], attr, value)

    def close(self) -> None:
        for env in self.envs:
            env.close()


class SharedArrays:
    """The per-step arrays of one worker's slots in one shared-memory block, so a step moves
    no observation through a pipe: actions (in), observations, rewards and dones (out)."""

    def __init__(self, slots: int, obs_size: int, name: str | None = None) -> None:
        sizes = [slots * 2 * 4, slots * obs_size * 4, slots * 4, slots]
        self.shm = shared_memory.SharedMemory(name=name, create=name is None,
                                              size=max(1, sum(sizes)))
        offsets = np.cumsum([0, *sizes])
        buf = self.shm.buf
        self.actions = np.ndarray((slots, 2), np.float32, buf, offsets[0])
        self.obs = np.ndarray((slots, obs_size), np.float32, buf, offsets[1])
        self.rewards = np.ndarray((slots,), np.float32, buf, offsets[2])
        self.dones = np.ndarray((slots,), np.bool_, buf, offsets[3])

    def close(self, unlink: bool = False) -> None:
        del self.actions, self.obs, self.rewards, self.dones
        self.shm.close()
        if unlink:
            self.shm.unlink()


def _worker(conn: Any, specs: Sequence[CopySpec], shm_name: str, obs_size: int
            ) -> None:  # pragma: no cover - runs in a subprocess
    shard = Shard(specs)
    arrays = SharedArrays(sum(shard.sizes), obs_size, shm_name)
    parent = mp.parent_process()
    try:
        while True:
            # Leave when the parent dies (SIGKILL leaves no orphan workers behind).
            while not conn.poll(0.5):
                if parent is not None and not parent.is_alive():
                    return
            cmd, args = conn.recv()
            if cmd == "close":
                conn.send(None)
                return
            try:
                if cmd == "step":
                    obs, rew, done, infos = shard.step(arrays.actions.copy())
                    arrays.obs[:], arrays.rewards[:], arrays.dones[:] = obs, rew, done
                    conn.send(("ok", [(k, info) for k, info in enumerate(infos) if info]))
                elif cmd == "reset":
                    arrays.obs[:] = shard.reset()
                    conn.send(("ok", None))
                else:
                    conn.send(("ok", getattr(shard, cmd)(*args)))
            except Exception:
                conn.send(("error", traceback.format_exc()))
    except (EOFError, OSError, KeyboardInterrupt):
        pass
    finally:
        shard.close()
        arrays.close()


class RemoteShard:
    """A :class:`Shard` in a worker process: commands through a pipe, arrays through shared
    memory."""

    def __init__(self, specs: Sequence[CopySpec], obs_size: int, ctx: Any) -> None:
        self.sizes = [spec.robots - 1 for spec in specs]
        self.arrays = SharedArrays(sum(self.sizes), obs_size)
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_worker, daemon=True,
                                   args=(child, list(specs), self.arrays.shm.name, obs_size))
        self.process.start()
        child.close()

    def send(self, cmd: str, *args: Any) -> None:
        self.conn.send((cmd, args))

    def receive(self) -> Any:
        try:
            status, value = self.conn.recv()
        except (EOFError, OSError) as exc:
            raise RuntimeError(f"an env worker process (pid {self.process.pid}) died: "
                               f"{exc!r}") from exc
        if status == "error":
            raise RuntimeError(f"an env worker process failed:\n{value}")
        return value

    def start_step(self, actions: npt.NDArray[np.float32]) -> None:
        self.arrays.actions[:] = actions
        self.send("step")

    def finish_step(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32],
                                   npt.NDArray[np.bool_], list[dict[str, Any]]]:
        sparse = self.receive()
        infos: list[dict[str, Any]] = [{} for _ in range(len(self.arrays.rewards))]
        for k, info in sparse:
            infos[k] = info
        a = self.arrays
        return a.obs.copy(), a.rewards.copy(), a.dones.copy(), infos

    def reset(self) -> npt.NDArray[np.float32]:
        self.send("reset")
        self.receive()
        return self.arrays.obs.copy()

    def __getattr__(self, cmd: str) -> Any:
        if cmd.startswith("_") or cmd in {"conn", "process", "sizes", "arrays"}:
            raise AttributeError(cmd)

        def remote(*args: Any) -> Any:
            self.send(cmd, *args)
            return self.receive()
        return remote

    def close(self) -> None:
        try:
            self.conn.send(("close", ()))
            self.conn.poll(5) and self.conn.recv()
        except (BrokenPipeError, EOFError, OSError):
            pass
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
        self.arrays.close(unlink=True)
