"""Runs every (policy, case, seed) episode of a suite, in parallel, resumably, isolating
failures.

Each finished episode is appended at once to ``episodes.jsonl`` in the output folder, so an
interrupted run loses nothing it finished: rerunning skips every episode already there (and
reruns one whose trajectory file is missing or unreadable). Cases that are the same
configuration (the study's cases 2, 4 and 8) run once per seed and are reused. Every episode
runs in a worker process of its own (:mod:`boids_env.eval.pool`): an episode that raises
(anything, ``SystemExit`` included), kills its worker or runs past the episode timeout is
written to ``errors.jsonl`` with the reason, and the others go on. At the end (and on Ctrl-C)
the tidy table, one row per (policy, case, seed), is written to ``results.parquet`` and
``results.csv``. Every file is written atomically; the folder belongs to one evaluation
(:mod:`boids_env.eval.folder`).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import pickle
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from boids_env.eval import folder
from boids_env.eval.backends import execute
from boids_env.eval.cases import Case, Suite
from boids_env.eval.pool import BACKENDS, DEFAULT_EPISODE_TIMEOUT
from boids_env.eval.progress import bar as progress_bar
from boids_env.files import append_line, atomic_path, write_json
from boids_env.untrusted import MAX_MODEL_BYTES, check_file

EPISODES = "episodes.jsonl"
ERRORS = "errors.jsonl"
TRAJECTORIES = "trajectories"
MAX_WORKERS = 1024


@dataclass(frozen=True)
class PolicySpec:
    """A policy to evaluate: a spec for :func:`~boids_env.policies.registry.load_policy` and
    a preset."""

    spec: str
    preset: str = "paper"
    name: str | None = None
    """Label in the tables and figures (default: derived from the spec)."""
    trust: bool = False
    """A model zip may load through SB3's own load, which runs code stored in the file
    (``load_policy(trust=True)``, ``--trust-model``)."""

    @classmethod
    def parse(cls, spec: str, preset: str = "paper", trust: bool = False) -> PolicySpec:
        """``reynolds@boids_ros`` or any spec of ``load_policy`` with a default preset."""
        from boids_env.policies.registry import split_preset

        return cls(*split_preset(spec, preset), trust=trust)

    @property
    def label(self) -> str:
        if self.name is not None:
            return self.name
        from boids_env.policies.registry import SIGHT_SWITCHED, switch_parts

        parts = None if self.spec in SIGHT_SWITCHED else switch_parts(self.spec)
        if parts:
            return "+".join(p.stem for p in parts)
        base = Path(self.spec).stem if self.spec.endswith(".zip") else self.spec
        return f"{base}[{self.preset}]" if self.spec == "reynolds" else base

    @functools.cached_property
    def fingerprint(self) -> str:
        """Changes when the policy does (a model file's content is hashed, once; a zip
        without a numpy actor acts through torch when trusted, from its weights in numpy
        otherwise)."""
        from boids_env.policies.registry import MODELS, switch_parts

        paths = switch_parts(self.spec) or (MODELS.get(self.spec, Path(self.spec)),)
        if all(p.suffix == ".zip" and p.is_file() for p in paths):
            from boids_env.policies.sb3_policy import has_numpy_actor

            digests = []
            for path in paths:
                check_file(path, "policy model", MAX_MODEL_BYTES)  # not a device, not huge
                with open(path, "rb") as fh:
                    digests.append(hashlib.file_digest(fh, "sha256").hexdigest()[:16])
            trusted = self.trust and not all(has_numpy_actor(p) for p in paths)
            return f"{self.spec}#{'+'.join(digests)}" + ("#trusted" if trusted else "")
        return f"{self.spec}|{self.preset}"


def _check_model_fits(policy: PolicySpec, suite: Suite) -> None:
    """A model's weights loaded and its observation size checked against every case here,
    once, rather than found failing in every episode. Not for a trusted zip: loading it runs
    what its pickles hold, which stays in the workers."""
    from boids_env.eval.episode import check_fits, env_fields_for, warn_outside_card
    from boids_env.policies.registry import MODELS, load_policy, switch_parts

    if policy.trust or not (policy.spec.endswith(".zip") or policy.spec in MODELS
                            or switch_parts(policy.spec)):
        return
    loaded = load_policy(policy.spec, preset=policy.preset, trust=policy.trust)
    check_fits(loaded, [case.env for case in suite.cases])
    if getattr(loaded, "card", None) is not None:  # cases outside its card: one line
        from boids_env.config import EnvConfig

        warn_outside_card(loaded, {case.name: EnvConfig.from_kwargs(
            **env_fields_for(loaded, case.env)) for case in suite.cases}, name=policy.label)


def distinct_policies(policies: Sequence[PolicySpec]) -> list[PolicySpec]:
    """The policies with distinct labels: a spec given twice is a ``ValueError``; model files
    of the same name in different folders are labelled by their path."""
    if not policies:
        raise ValueError("policies must name at least one policy")
    seen: set[tuple[str, str]] = set()
    for p in policies:
        if not isinstance(p, PolicySpec):
            raise TypeError(f"policies must be PolicySpec objects, got {p!r}")
        ident = (p.spec, p.preset if p.spec == "reynolds" else "")
        if ident in seen:
            raise ValueError(f"policy {p.spec!r} is given twice")
        seen.add(ident)
    labels = [p.label for p in policies]
    return [p if labels.count(p.label) == 1 or p.name is not None
            else dataclasses.replace(p, name=p.spec) for p in policies]


@dataclass(frozen=True)
class Task:
    """One episode to run."""

    policy: PolicySpec
    case: Case
    seed: int
    trajectory: str | None = None
    """File to write the episode's trajectory to (None: none)."""

    @property
    def key(self) -> str:
        raw = json.dumps([self.policy.fingerprint, self.case.config_key, self.seed])
        return hashlib.sha256(raw.encode()).hexdigest()[:20]


_POLICY_CACHE: dict[tuple[str, str, bool, str], Any] = {}


def run_task(task: Task) -> dict[str, Any]:
    """Runs one episode (in a worker) and returns its metrics row (without case columns)."""
    from boids_env.environment import BoidsEnv
    from boids_env.eval.episode import env_fields_for, run_episode
    from boids_env.policies.registry import load_policy

    cache_key = (task.policy.spec, task.policy.preset, task.policy.trust,
                 json.dumps(task.case.policy, sort_keys=True))
    policy = _POLICY_CACHE.get(cache_key)
    if policy is None:
        policy = load_policy(task.policy.spec, preset=task.policy.preset,
                             trust=task.policy.trust, **task.case.policy)
        _POLICY_CACHE[cache_key] = policy
    env = BoidsEnv(**env_fields_for(policy, task.case.env))
    try:
        result = run_episode(env, policy, task.seed, record=True)
    finally:
        env.close()
    metrics = dict(result.metrics)
    metrics["wall_time"] = result.wall_time
    metrics["key"] = task.key
    if task.trajectory is not None and result.recording is not None:
        path = Path(task.trajectory)
        path.parent.mkdir(parents=True, exist_ok=True)
        result.recording.to_parquet(path)
        metrics["trajectory"] = path.name
    return metrics


_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def slug(text: str, limit: int = 60) -> str:
    """A filesystem-safe, readable form of ``text`` (ASCII letters, digits, ``._-``; at most
    ``limit`` characters, a short hash standing for what was cut)."""
    out = _UNSAFE.sub("_", str(text)).strip("._") or "x"
    if len(out) > limit:
        out = out[: limit - 9] + "-" + hashlib.sha256(str(text).encode()).hexdigest()[:8]
    return out


def unique_stems(keys: Sequence[tuple[str, ...]], prefix: str = "",
                 taken: Sequence[str] = ()) -> dict[tuple[str, ...], str]:
    """A distinct file stem per key (a tuple of names, e.g. (policy, group)): ``prefix`` and
    the names' :func:`slug` joined by ``_``. Names that differ only in what the slug drops
    (``speed=0.3``, ``speed 0.3``) would share a file, as would a key and a ``taken`` stem:
    each such key gets a short hash of its own names added (``p_1_g_1-3f2a9c01``), so no
    figure or table of one name ever overwrites another's."""
    keys = list(dict.fromkeys(tuple(str(n) for n in k) for k in keys))
    plain = {k: prefix + "_".join(slug(n) for n in k) for k in keys}
    uses: dict[str, int] = {}
    for stem in [*plain.values(), *taken]:
        uses[stem] = uses.get(stem, 0) + 1
    return {k: stem if uses[stem] == 1 else
            f"{stem}-{hashlib.sha256(json.dumps(k).encode()).hexdigest()[:8]}"
            for k, stem in plain.items()}


def trajectory_name(policy: PolicySpec, case: Case, seed: int) -> str:
    """``POLICY__CASE__seedN.parquet``, readable and filesystem-safe."""
    return f"{slug(policy.label)}__{slug(case.name)}__seed{seed}.parquet"


def plan(policies: Sequence[PolicySpec], suite: Suite, trajectory_dir: str | None = None,
         all_trajectories: bool = False) -> list[Task]:
    """The episodes to run: one per (policy, distinct configuration, seed). Trajectories go
    to ``trajectory_dir`` for every episode with ``all_trajectories``, else for the first
    seed of each case (the report's trajectory figures), named by policy, case and seed."""
    tasks, seen = [], set()
    for policy in policies:
        for case in suite.cases:
            for seed in suite.seeds:
                task = Task(policy, case, seed)
                if task.key not in seen:
                    seen.add(task.key)
                    tasks.append(task)
    if trajectory_dir is None:
        return tasks
    names = [trajectory_name(t.policy, t.case, t.seed) for t in tasks]
    out = []
    for task, name in zip(tasks, names, strict=True):
        if not (all_trajectories or task.seed == suite.seeds[0]):
            out.append(task)
            continue
        if names.count(name) > 1:  # two labels or case names that slug alike
            name = name.replace(".parquet", f"__{task.key[:8]}.parquet")
        out.append(dataclasses.replace(task, trajectory=str(Path(trajectory_dir) / name)))
    return out


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    """Rows (JSON objects) of a JSON-lines file; a torn or foreign line is skipped."""
    if not path.exists():
        return []
    rows = []
    for line in path.read_bytes().decode("utf-8", errors="replace").splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(row, dict):
            rows.append(row)
    return rows


def _trajectory_ok(path: Path) -> bool:
    import pyarrow.parquet as pq

    try:
        pq.ParquetFile(path).metadata  # noqa: B018 - reading the footer is the check
    except Exception:  # missing, truncated or not Parquet
        return False
    return True


def _finished(out: Path, tasks: Sequence[Task]) -> dict[str, dict[str, Any]]:
    """Rows of ``episodes.jsonl`` for the planned tasks, keeping only those whose trajectory
    (when the task keeps one) is there and readable; the others are rerun."""
    rows = {r["key"]: r for r in read_jsonl(out / EPISODES) if isinstance(r.get("key"), str)}
    done = {}
    for task in tasks:
        row = rows.get(task.key)
        if row is None:
            continue
        if task.trajectory is not None:
            name = row.get("trajectory")
            if not isinstance(name, str) or not _trajectory_ok(out / TRAJECTORIES / name):
                continue
        done[task.key] = row
    return done


def identity(suite: Suite, policies: Sequence[PolicySpec]) -> dict[str, Any]:
    """What makes two evaluations the same (the seeds aside: more seeds resume): the cases,
    the policies with their fingerprints, and the content of every file a case reads (a walk,
    a map and its image, a shapes file), so an edited file is never resumed as the old one."""
    described = suite_to_dict(suite, policies)
    described.pop("seeds")
    for entry, policy in zip(described["policies"], policies, strict=True):
        entry["fingerprint"] = policy.fingerprint
    inputs = input_digests(suite)
    if inputs:  # absent without files: folders of file-free suites keep their identity
        described["inputs"] = inputs
    return described


WORLD_CHANGES = "world_changes"
"""The manifest's entry of what each policy changes in the world of its episodes."""


def suite_world_changes(suite: Suite, policies: Sequence[PolicySpec]
                        ) -> dict[str, dict[str, dict[str, dict[str, list[Any]]]]]:
    """Per policy label and case, what running the policy changes in the case's world
    (:func:`~boids_env.eval.episode.world_changes`): only policies and cases with a change."""
    from boids_env.eval.episode import world_changes

    out: dict[str, dict[str, dict[str, dict[str, list[Any]]]]] = {}
    for policy in policies:
        for case in suite.cases:
            changes = world_changes(_fields_holder(policy, case), case.env)
            if changes["changed"] or changes["untrained"]:
                out.setdefault(policy.label, {})[case.name] = {
                    k: v for k, v in changes.items() if v}
    return out


def _fields_holder(policy: PolicySpec, case: Case) -> Any:
    """What :func:`~boids_env.eval.episode.env_fields_for` reads of the policy a worker builds
    for ``case``: a model's env fields from its metadata (nothing of it is loaded), else the
    policy itself (Reynolds parameters, a ``module:object``'s own fields)."""
    from types import SimpleNamespace

    from boids_env.policies.registry import load_policy, model_path

    path = model_path(policy.spec)
    if path.suffix == ".zip":
        from boids_env.policies.sb3_policy import read_meta

        return SimpleNamespace(env_fields=dict(read_meta(path).get("env_fields") or {}))
    return load_policy(policy.spec, preset=policy.preset, trust=policy.trust, **case.policy)


def input_digests(suite: Suite) -> dict[str, str]:
    """The SHA-256 of every file the suite's cases read, by resolved path."""
    from boids_env.config import EnvConfig
    from boids_env.files import file_digest

    files = {path for case in suite.cases
             for path in EnvConfig().replace(**case.env).input_files()}
    return {str(path): file_digest(path) for path in sorted(files)}


def _check_arguments(backend: str, workers: int | None, episode_timeout: float | None
                     ) -> None:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or not 1 <= workers <= MAX_WORKERS):
        raise ValueError(f"workers must be an integer in [1, {MAX_WORKERS}], got {workers!r}")
    if episode_timeout is not None and (
            isinstance(episode_timeout, bool) or not isinstance(episode_timeout, int | float)
            or not math.isfinite(episode_timeout) or episode_timeout <= 0):
        raise ValueError(f"episode_timeout must be a positive number of seconds or None (no "
                         f"limit), got {episode_timeout!r}")


def run_suite(policies: Sequence[PolicySpec], suite: Suite, out: str | Path, *,
              workers: int | None = None, backend: str = "process",
              keep_trajectories: bool = False, progress: bool = True,
              runner: Callable[[Task], dict[str, Any]] | None = None,
              episode_timeout: float | None = DEFAULT_EPISODE_TIMEOUT,
              overwrite: bool = False) -> pd.DataFrame:
    """Runs the suite for every policy and returns the tidy results table.

    Every argument is checked before anything is written. Failed episodes are in
    ``out/errors.jsonl`` (and :func:`failures`) and missing from the table.

    Args:
        policies: the policies to evaluate.
        suite: cases × seeds.
        out: output folder; episodes already in its ``episodes.jsonl`` are not rerun. A
            folder holding another evaluation (other cases or policies) is refused.
        workers: parallel worker processes (default: the number of cores; for ``ray`` the
            cluster's CPUs), at most one per episode.
        backend: see :data:`BACKENDS`; ``ray`` needs the ``ray`` extra (``ray.init()`` is
            called if Ray is not initialised, and shut down at the end).
        keep_trajectories: write every episode's trajectory to
            ``out/trajectories/POLICY__CASE__seedN.parquet`` (otherwise only the first seed's
            of each case).
        progress: show a progress bar (tqdm), on a terminal.
        runner: the function running one task (tests inject failures with it); it must be
            picklable (a module-level function) unless ``backend="inline"``.
        episode_timeout: seconds an episode may run before its worker is killed and the
            episode recorded as failed (None: no limit; ``inline`` cannot enforce it).
        overwrite: replace an earlier evaluation in ``out`` (only what it wrote is removed).

    Raises:
        KeyboardInterrupt: after Ctrl-C, once the finished episodes are recorded, every
            worker is stopped and the results table is written.
    """
    policies, run = _checked(policies, suite, runner, backend, workers, episode_timeout)
    out = Path(out)
    folder.check_target(out)
    tasks = plan(policies, suite, str(out / TRAJECTORIES), keep_trajectories)

    folder.claim(out, identity(suite, policies), overwrite=overwrite)
    # what a policy changes in the world of its episodes, never silent (the report shows it)
    folder.record_entry(out, WORLD_CHANGES, suite_world_changes(suite, policies))
    done = _finished(out, tasks)
    todo = [t for t in tasks if t.key not in done]
    (out / ERRORS).unlink(missing_ok=True)
    errors: list[dict[str, Any]] = []
    cases_of = _cases_of(tasks, suite)
    bar = progress_bar(len(tasks), desc="episodes", unit="ep", initial=len(tasks) - len(todo),
                       enabled=progress)

    def record(task: Task, ok: bool, row: dict[str, Any]) -> None:
        line = _episode_line(task, row) if ok else None
        if line is not None:
            append_line(out / EPISODES, line)
            done[task.key] = json.loads(line)
        else:
            row = _failure_row(task, ok, row, cases_of[task.key])
            append_line(out / ERRORS, json.dumps(row, default=str))
            errors.append(row)
        bar.update(1)

    try:
        execute(todo, run, workers, backend, episode_timeout, record)
    finally:
        bar.close()
        for err in errors:
            print(f"episode failed: {err['policy']} · {err['case']} · seed {err['seed']}: "
                  f"{err['error']}", file=sys.stderr)
        # what episodes.jsonl holds, re-read: a Ctrl-C landing between a row's append and
        # its entry in ``done`` must not leave the table one row short of the file
        missing = [t for t in tasks if t.key not in done]
        table = results_table(tasks, {**done, **_finished(out, missing)}, suite)
        _write_results(out, table, suite, policies)
    return table


def _checked(policies: Sequence[PolicySpec], suite: Suite,
             runner: Callable[[Task], dict[str, Any]] | None, backend: str,
             workers: int | None, episode_timeout: float | None
             ) -> tuple[list[PolicySpec], Callable[[Task], dict[str, Any]]]:
    """:func:`run_suite`'s arguments checked before anything is written: the distinct
    policies (each spec and model refused here, not found failing in every episode) and the
    function that runs one task."""
    _check_arguments(backend, workers, episode_timeout)
    if not isinstance(suite, Suite):
        raise TypeError(f"suite must be a Suite, got {type(suite).__name__}")
    policies = distinct_policies(policies)
    if runner is None:  # a bad spec is refused here, not found failing in every episode
        from boids_env.policies.registry import check_policy_spec

        for policy in policies:
            check_policy_spec(policy.spec, policy.preset, trust=policy.trust)
            _check_model_fits(policy, suite)
    run = runner or run_task
    if backend == "process":
        try:
            pickle.dumps(run)
        except Exception as exc:
            raise TypeError(f"runner must be picklable (a module-level function) for "
                            f"backend='process', or use backend='inline': {exc}") from None
    return policies, run


def _failure_row(task: Task, ok: bool, row: Any, cases: list[str]) -> dict[str, Any]:
    """The ``errors.jsonl`` row of a failed episode; ``ok`` with a row that is not a JSON
    object of metrics (a custom runner's mistake) is a failure too."""
    if ok:
        row = {"reason": "exception", "error": f"the runner returned "
               f"{type(row).__name__} that is not a JSON object of metrics"}
    return {"key": task.key, "policy": task.policy.label, "case": task.case.name,
            "cases": cases, "seed": task.seed,
            **{k: v for k, v in row.items() if k != "fatal"}}


def _episode_line(task: Task, row: Any) -> str | None:
    """The ``episodes.jsonl`` line of a finished episode (its key set), or None when the row
    is not a JSON object (a custom runner's mistake)."""
    if not isinstance(row, dict):
        return None
    try:
        return json.dumps({**row, "key": task.key}, default=_plain)
    except (TypeError, ValueError):
        return None


def _plain(value: Any) -> Any:
    """numpy scalars and arrays as plain numbers and lists (json.dumps' fallback)."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _cases_of(tasks: Sequence[Task], suite: Suite) -> dict[str, list[str]]:
    """Every case each task stands for (cases of the same configuration share a task)."""
    return {t.key: [c.name for c in suite.cases if c.config_key == t.case.config_key]
            for t in tasks}


def _write_results(out: Path, table: pd.DataFrame, suite: Suite,
                   policies: Sequence[PolicySpec]) -> None:
    import pyarrow as pa

    from boids_env.parquet import write_table

    write_table(pa.Table.from_pandas(table, preserve_index=False), out / "results.parquet")
    to_csv(table, out / "results.csv")
    write_json(out / "suite.json", suite_to_dict(suite, policies))


def failures(out: str | Path) -> list[dict[str, Any]]:
    """The failed episodes of the last run into ``out`` (rows of ``errors.jsonl``)."""
    return read_jsonl(Path(out) / ERRORS)


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
    """CSV with the per-follower count lists as JSON strings, written atomically."""
    flat = table.copy()
    for col in flat.columns:
        if col.startswith("count_"):
            flat[col] = flat[col].map(json.dumps)
    with atomic_path(path) as tmp:
        flat.to_csv(tmp, index=False)


def suite_to_dict(suite: Suite, policies: Sequence[PolicySpec]) -> dict[str, Any]:
    return {"name": suite.name, "seeds": list(suite.seeds),
            "per_follower": list(suite.per_follower),
            "followers_analysed": suite.followers_analysed,
            "policies": [{"spec": p.spec, "preset": p.preset, "label": p.label}
                         for p in policies],
            "cases": [{"name": c.name, "group": c.group, "factor": c.factor, "level": c.level,
                       "env": c.env, "policy": c.policy} for c in suite.cases]}

