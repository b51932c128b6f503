"""Runs every (policy, case, seed) episode of a suite, in parallel, resumably.

Each finished episode is appended at once to ``episodes.jsonl`` in the output folder, so an
interrupted run loses nothing: rerunning skips every episode already there. Cases that are the
same configuration (the study's cases 2, 4 and 8) run once per seed and are reused. A crashing
episode is written to ``errors.jsonl`` and reported; the others go on. At the end the tidy
table, one row per (policy, case, seed), is written to ``results.parquet`` and
``results.csv``.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import traceback
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from boids_env.eval.suites import Case, Suite

EPISODES = "episodes.jsonl"
ERRORS = "errors.jsonl"
BACKENDS = ("process", "ray")
V_COLUMNS = ("V_sep", "V_coh", "V_align", "V_align_unwrapped")
COUNT_COLUMNS = ("count_sep", "count_coh", "count_align", "count_align_unwrapped")


@dataclass(frozen=True)
class PolicySpec:
    """A policy to evaluate: a spec for :func:`~boids_env.policies.registry.load_policy` and
    a preset."""

    spec: str
    preset: str = "paper"

    @classmethod
    def parse(cls, spec: str, preset: str = "paper") -> PolicySpec:
        """``reynolds@boids_ros`` or any spec of ``load_policy`` with a default preset."""
        from boids_env.policies.registry import split_preset

        return cls(*split_preset(spec, preset))

    @property
    def label(self) -> str:
        base = Path(self.spec).stem if self.spec.endswith(".zip") else self.spec
        return f"{base}[{self.preset}]" if self.spec == "reynolds" else base

    @functools.cached_property
    def fingerprint(self) -> str:
        """Changes when the policy does (a model file's content is hashed, once)."""
        if self.spec.endswith(".zip") and Path(self.spec).is_file():
            digest = hashlib.sha256(Path(self.spec).read_bytes()).hexdigest()[:16]
            return f"{self.spec}#{digest}"
        return f"{self.spec}|{self.preset}"


@dataclass(frozen=True)
class Task:
    """One episode to run."""

    policy: PolicySpec
    case: Case
    seed: int
    trajectory_dir: str | None = None

    @property
    def key(self) -> str:
        raw = json.dumps([self.policy.fingerprint, self.case.config_key, self.seed])
        return hashlib.sha256(raw.encode()).hexdigest()[:20]


_POLICY_CACHE: dict[tuple[str, str, str], Any] = {}


def run_task(task: Task) -> dict[str, Any]:
    """Runs one episode (in a worker) and returns its metrics row (without case columns)."""
    from boids_env.environment import BoidsEnv
    from boids_env.eval.episode import env_fields_for, run_episode
    from boids_env.policies.registry import load_policy

    cache_key = (task.policy.spec, task.policy.preset, json.dumps(task.case.policy,
                                                                   sort_keys=True))
    policy = _POLICY_CACHE.get(cache_key)
    if policy is None:
        policy = load_policy(task.policy.spec, preset=task.policy.preset, **task.case.policy)
        _POLICY_CACHE[cache_key] = policy
    env = BoidsEnv(**env_fields_for(policy, task.case.env))
    try:
        result = run_episode(env, policy, task.seed, record=True)
    finally:
        env.close()
    metrics = dict(result.metrics)
    metrics["wall_time"] = result.wall_time
    metrics["key"] = task.key
    if task.trajectory_dir is not None and result.recording is not None:
        path = Path(task.trajectory_dir) / f"{task.key}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        result.recording.to_parquet(path)
        metrics["trajectory"] = path.name
    return metrics


def _safe_run(task: Task, run: Callable[[Task], dict[str, Any]] = run_task
              ) -> tuple[bool, dict[str, Any]]:
    try:
        return True, run(task)
    except Exception as exc:  # reported; the other episodes go on
        return False, {"key": task.key, "error": f"{type(exc).__name__}: {exc}",
                       "traceback": traceback.format_exc()}


def plan(policies: Sequence[PolicySpec], suite: Suite, trajectory_dir: str | None = None,
         all_trajectories: bool = False) -> list[Task]:
    """The episodes to run: one per (policy, distinct configuration, seed). Trajectories go
    to ``trajectory_dir`` for every episode with ``all_trajectories``, else for the first
    seed of each case (the report's trajectory figures)."""
    tasks, seen = [], set()
    for policy in policies:
        for case in suite.cases:
            for seed in suite.seeds:
                keep = all_trajectories or seed == suite.seeds[0]
                task = Task(policy, case, seed, trajectory_dir if keep else None)
                if task.key not in seen:
                    seen.add(task.key)
                    tasks.append(task)
    return tasks


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    """Rows of a JSON-lines file; a truncated last line (an interrupted write) is skipped."""
    if not path.exists():
        return []
    rows = []
    for line in path.read_text().splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return rows


def run_suite(policies: Sequence[PolicySpec], suite: Suite, out: str | Path, *,
              workers: int | None = None, backend: str = "process",
              keep_trajectories: bool = False, progress: bool = True,
              runner: Callable[[Task], dict[str, Any]] | None = None) -> pd.DataFrame:
    """Runs the suite for every policy and returns the tidy results table.

    Args:
        policies: the policies to evaluate.
        suite: cases × seeds.
        out: output folder; episodes already in its ``episodes.jsonl`` are not rerun.
        workers: parallel processes (default: the number of cores); 1 runs in this process.
        backend: ``process`` (a local process pool) or ``ray`` (``ray.init()`` must reach a
            cluster or starts a local one; needs the ``ray`` extra).
        keep_trajectories: write every episode's trajectory to
            ``out/trajectories/KEY.parquet`` (otherwise only the first seed's of each case).
        progress: show a progress bar (tqdm).
        runner: the function running one task (tests inject failures with it).
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    workers = (os.cpu_count() or 1) if workers is None else workers
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = plan(policies, suite, str(out / "trajectories"), keep_trajectories)
    done = {row["key"]: row for row in read_jsonl(out / EPISODES)}
    todo = [t for t in tasks if t.key not in done]
    if (out / ERRORS).exists():
        (out / ERRORS).unlink()
    run = runner or run_task
    errors: list[dict[str, Any]] = []

    def record(ok: bool, row: dict[str, Any]) -> None:
        target = EPISODES if ok else ERRORS
        with (out / target).open("a") as fh:
            fh.write(json.dumps(row) + "\n")
        if ok:
            done[row["key"]] = row
        else:
            errors.append(row)

    bar = _progress(len(tasks), len(tasks) - len(todo), progress)
    for ok, row in _execute(todo, run, workers, backend):
        record(ok, row)
        bar.update(1)
    bar.close()
    for err in errors:
        print(f"episode {err['key']} failed: {err['error']}")
    table = results_table(tasks, done, suite)
    table.to_parquet(out / "results.parquet", index=False)
    to_csv(table, out / "results.csv")
    (out / "suite.json").write_text(json.dumps(suite_to_dict(suite, policies), indent=2))
    return table


def _execute(tasks: Sequence[Task], run: Callable[[Task], dict[str, Any]], workers: int,
             backend: str) -> Iterable[tuple[bool, dict[str, Any]]]:
    if not tasks:
        return
    if backend == "ray":
        yield from _execute_ray(tasks)
        return
    safe = functools.partial(_safe_run, run=run)
    if workers == 1 or len(tasks) == 1:
        for task in tasks:
            yield safe(task)
        return
    import multiprocessing as mp

    ctx = mp.get_context("forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(tasks)), mp_context=ctx) as pool:
        pending = {pool.submit(safe, t): t for t in tasks}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                task = pending.pop(fut)
                try:
                    yield fut.result()
                except Exception as exc:
                    yield False, {"key": task.key, "error": f"{type(exc).__name__}: {exc}"}


def _execute_ray(tasks: Sequence[Task]) -> Iterable[tuple[bool, dict[str, Any]]]:
    try:
        import ray
    except ImportError as exc:
        raise ImportError("backend='ray' needs: pip install 'boids-env[ray]'") from exc
    if not ray.is_initialized():
        ray.init(ignore_reinit_error=True, include_dashboard=False, log_to_driver=False)
    remote = ray.remote(_safe_run)
    pending = [remote.remote(t) for t in tasks]
    while pending:
        finished, pending = ray.wait(pending, num_returns=1)
        yield ray.get(finished[0])


def results_table(tasks: Sequence[Task], done: dict[str, dict[str, Any]], suite: Suite
                  ) -> pd.DataFrame:
    """One row per (policy, case, seed) whose episode finished; shared configurations appear
    under every case they stand for."""
    rows = []
    for policy in dict.fromkeys(t.policy for t in tasks):
        for case in suite.cases:
            for seed in suite.seeds:
                key = Task(policy, case, seed).key
                if key not in done:
                    continue
                row = {"policy": policy.label, "policy_spec": policy.spec,
                       "preset": policy.preset, "suite": suite.name, "case": case.name,
                       "group": case.group, "factor": case.factor, "level": case.level,
                       "seed": seed}
                row.update({k: v for k, v in done[key].items() if k != "traceback"})
                rows.append(row)
    return pd.DataFrame(rows)


def to_csv(table: pd.DataFrame, path: Path) -> None:
    """CSV with the per-follower count lists as JSON strings."""
    flat = table.copy()
    for col in flat.columns:
        if col.startswith("count_"):
            flat[col] = flat[col].map(json.dumps)
    flat.to_csv(path, index=False)


def suite_to_dict(suite: Suite, policies: Sequence[PolicySpec]) -> dict[str, Any]:
    return {"name": suite.name, "seeds": list(suite.seeds),
            "per_follower": list(suite.per_follower),
            "followers_analysed": suite.followers_analysed,
            "policies": [{"spec": p.spec, "preset": p.preset, "label": p.label}
                         for p in policies],
            "cases": [{"name": c.name, "group": c.group, "factor": c.factor, "level": c.level,
                       "env": c.env, "policy": c.policy} for c in suite.cases]}


def _progress(total: int, initial: int, enabled: bool) -> Any:
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is in the eval extra
        enabled = False
    if not enabled:
        class _Null:
            def update(self, n: int) -> None: ...
            def close(self) -> None: ...
        return _Null()
    return tqdm(total=total, initial=initial, desc="episodes", unit="ep")
