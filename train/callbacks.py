"""SB3 callbacks that log the study's violation metrics during training."""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

from boids_env.environment import BoidsEnv
from boids_env.eval.episode import run_episode
from boids_env.files import atomic_path
from boids_env.policies.sb3_policy import SB3Policy, write_meta
from boids_env.train.vec_env import EPISODE_INFO

V_KEYS = ("V_sep", "V_coh", "V_align")
SAFETY = ("touching_fraction", "contacts_follower", "contacts_leader", "wall_fraction",
          "mean_nn_distance")


def ended_infos(step: dict[str, Any]) -> list[dict[str, Any]]:
    """The infos of the slots whose episode ended at this step of a rollout (SB3's callback
    locals): the only ones that carry an episode's data (``flock_episode``, VecMonitor's
    ``episode``), read without walking every slot's empty info each step."""
    infos = step.get("infos", ())
    dones = step.get("dones")
    if dones is None:
        return list(infos)
    return [infos[i] for i in np.flatnonzero(dones)]


class TrainingMetricsCallback(BaseCallback):
    """Logs the V_* of every finished training episode (``flock/train_*``, means since the
    last log dump), from the ``flock_episode`` info of :class:`~train.vec_env.FlockVecEnv`."""

    def __init__(self) -> None:
        super().__init__()
        self._episodes: list[dict[str, float]] = []

    def _on_step(self) -> bool:
        for info in ended_infos(self.locals):
            if EPISODE_INFO in info:
                self._episodes.append(info[EPISODE_INFO])
        return True

    def _on_rollout_end(self) -> None:
        if not self._episodes:
            return
        for key in V_KEYS:
            self.logger.record(f"flock/train_{key}", float(np.mean([e[key] for e in
                                                                     self._episodes])))
        self.logger.record("flock/train_total", float(np.mean(
            [sum(e[k] for k in V_KEYS) for e in self._episodes])))
        self._episodes = []


class TrainingSummary(BaseCallback):
    """Prints one line every ``every`` follower-steps and one when training ends, so a run
    without TensorBoard still shows how it goes: the mean reward per follower-step since the
    last line (0 is no violation; the study's reward is −(violations)·dt) and, for the training
    episodes that finished meanwhile, their mean return per follower and V_*. Reads the
    step's rewards and infos only: the training itself is unchanged."""

    def __init__(self, every: int, total: int, write: Callable[[str], Any] = print) -> None:
        super().__init__()
        self.every = max(int(every), 1)
        self.total = int(total)
        self.write = write
        self._rewards: list[float] = []
        self._returns: list[float] = []
        self._episodes: list[dict[str, float]] = []
        self._next = self.every

    def _on_training_start(self) -> None:
        self._next = (self.num_timesteps // self.every + 1) * self.every  # a resume goes on

    def _on_step(self) -> bool:
        self._rewards.append(float(np.mean(self.locals["rewards"])))
        for info in ended_infos(self.locals):
            if EPISODE_INFO in info:
                self._episodes.append(info[EPISODE_INFO])
            if "episode" in info:  # VecMonitor: one follower slot's episode return
                self._returns.append(float(info["episode"]["r"]))
        if self.num_timesteps >= self._next:
            self._next = (self.num_timesteps // self.every + 1) * self.every
            self._report()
        return True

    def _on_training_end(self) -> None:
        if self._rewards:
            self._report()

    def _report(self) -> None:
        line = (f"boids train: {self.num_timesteps:,}/{self.total:,} follower-steps "
                f"({min(self.num_timesteps / self.total, 1.0):.0%}): mean reward per "
                f"follower-step {np.mean(self._rewards):.4f}")
        if self._episodes:
            means = {k: np.mean([e[k] for e in self._episodes]) for k in V_KEYS}
            line += (f"; {len(self._episodes)} training episode(s) ended: return per follower "
                     f"{np.mean(self._returns):.2f}, " if self._returns else
                     f"; {len(self._episodes)} training episode(s) ended: ")
            line += ", ".join(f"{k} {v:.3f}" for k, v in means.items())
        else:
            line += "; no training episode has ended since the last line"
        self.write(line)
        self._rewards, self._returns, self._episodes = [], [], []


class FlockEvalCallback(BaseCallback):
    """Every ``every`` timesteps, runs deterministic evaluation episodes of the current model
    on the study's default case, logs ``eval/V_*``, ``eval/total`` (the study's three summed),
    the safety metrics and ``eval/cost`` (−return / T, the training reward's own score: the
    total for the study's reward, plus the safety terms for ``reward="safe"``) to TensorBoard,
    appends them to ``evaluations.csv`` and saves ``best_model.zip`` when the cost improves.
    """

    def __init__(self, out: str | Path, every: int, seeds: Sequence[int],
                 env_fields: dict[str, Any], save_best: Any = None) -> None:
        super().__init__()
        self.out = Path(out)
        self.every = every
        self.seeds = tuple(seeds)
        self.env_fields = dict(env_fields)
        self.save_best = save_best
        self.best = float("inf")
        self.last: int | None = None
        """The timesteps of the latest evaluation (None: none yet)."""
        self._next = every

    def _on_training_start(self) -> None:
        # A resumed run starts at its checkpoint's timesteps: the next evaluation is the next
        # multiple of ``every`` after them, not one per step until the schedule catches up.
        if self.every:
            self._next = (self.num_timesteps // self.every + 1) * self.every

    def resume_at(self, timesteps: int, best: float | None = None) -> None:
        """A resume from ``timesteps`` in this folder: the rows of ``evaluations.csv`` after
        them go (the resumed run evaluates those timesteps again, so none is written twice;
        a row torn by a kill goes too), and the best cost so far is ``best`` (a rollout
        boundary's, exact) or else that of the rows kept (to their six decimals), so
        ``best_model.zip`` is replaced when an uninterrupted run would replace it."""
        if best is not None:
            self.best = best
        path = self.out / "evaluations.csv"
        if not path.is_file():
            return
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
        if not lines:
            return
        header = lines[0].split(",")
        kept = [lines[0]]
        for line in lines[1:]:
            row = line.split(",")
            try:
                steps, cost = int(row[0]), float(row[header.index("cost")])
            except (ValueError, IndexError):
                continue
            if len(row) == len(header) and steps <= timesteps:
                kept.append(line)
                if best is None:
                    self.best = min(self.best, cost)
        if len(kept) != len(lines):
            with atomic_path(path) as tmp:
                # the csv module's line ends, as the rows were written
                tmp.write_text("".join(f"{line}\r\n" for line in kept), encoding="utf-8",
                               newline="")

    def _on_step(self) -> bool:
        if self.every and self.num_timesteps >= self._next:
            self._next += self.every
            self.evaluate()
        return True

    def evaluate(self) -> dict[str, float]:
        """Runs the evaluation episodes now and records their mean V_*."""
        env = BoidsEnv(**self.env_fields)
        policy = SB3Policy(self.model, self.env_fields)  # the env fields it trains with
        episodes = [run_episode(env, policy, seed, record=True) for seed in self.seeds]
        env.close()
        self.last = self.num_timesteps
        runs = [e.metrics for e in episodes]
        result = {k: float(np.mean([m[k] for m in runs])) for k in (*V_KEYS, *SAFETY)}
        result["total"] = sum(result[k] for k in V_KEYS)
        result["cost"] = float(np.mean([-e.reward_total / e.metrics["duration"]
                                        for e in episodes]))
        for key, value in result.items():
            self.logger.record(f"eval/{key}", value)
        path = self.out / "evaluations.csv"
        new = not path.exists()
        with path.open("a", newline="") as fh:
            writer = csv.writer(fh)
            if new:
                writer.writerow(["timesteps", *result])
            writer.writerow([self.num_timesteps, *(f"{v:.6f}" for v in result.values())])
        if result["cost"] < self.best:
            self.best = result["cost"]
            if self.save_best is not None:
                self.save_best(self.out / "best_model.zip")
        if self.verbose:
            print(f"eval at {self.num_timesteps}: " + ", ".join(
                f"{k} {v:.3f}" for k, v in result.items()))
        return result


class Checkpoints(CheckpointCallback):
    """SB3's checkpoints, each model zip tagged with the run's ``boids.json`` metadata so it
    loads as a policy (``boids run --policy .../checkpoints/model_..._steps.zip``) and, for
    PPO, carrying the rollout boundary it resumes from bit for bit
    (:mod:`boids_env.train.boundary`; ``identity``: the training's, as its digest).

    A checkpoint falls every ``every_calls`` VecEnv steps counted from the training's start
    (its follower-steps a multiple of ``every_calls`` × slots), so a resumed run writes the
    checkpoints an uninterrupted one does."""

    def __init__(self, every_calls: int, save_path: str | Path, meta: dict[str, Any],
                 identity: str = "", extra: Callable[[], dict[str, Any]] | None = None
                 ) -> None:
        super().__init__(save_freq=max(every_calls, 1), save_path=str(save_path),
                         name_prefix="model")
        self.meta = meta
        self.identity = identity
        self.extra = extra
        """What else a boundary keeps (JSON), asked at the rollout's start."""
        self._boundary: bytes | None = None

    @property
    def _every(self) -> int:
        return self.save_freq * self.training_env.num_envs

    def _on_rollout_start(self) -> None:
        from boids_env.train import boundary

        self._boundary = None
        if not boundary.applies(self.model):
            return
        coming = self.model.n_steps * self.training_env.num_envs
        now = self.model.num_timesteps
        if now // self._every != (now + coming) // self._every:
            # a checkpoint falls in this rollout: keep the state it resumes from
            self._boundary = boundary.capture(self.model, self.training_env, self.identity,
                                              self.extra() if self.extra else {})

    def _on_step(self) -> bool:
        if self.num_timesteps % self._every == 0:
            # SB3's own save writes the zip in place; here it is written whole or not at all
            with atomic_path(self._checkpoint_path(extension="zip")) as tmp:
                self.model.save(tmp)
                write_meta(tmp, self.meta, self.model)
                if self._boundary is not None:
                    from boids_env.train import boundary

                    boundary.write(tmp, self._boundary)
        return True
