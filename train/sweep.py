"""Several training seeds of one recipe: ``boids train --config R --seeds 0 1 2``.

Each seed trains in a folder of its own, ``OUT/seed_<n>``, exactly as ``boids train --seed n
--out OUT/seed_<n>`` would (the same folder rules, checkpoints, ``evaluations.csv``), as a
separate process here (``backend="process"``) or as a Ray task (``backend="ray"``: the
cluster ``RAY_ADDRESS`` names, else a local one; ``OUT`` must then be on a file system every
node sees). A seed whose ``model.zip`` is there is done; a killed seed goes on from its last
checkpoint (or starts again without one), so rerunning a killed sweep trains only what is
missing. When every seed is done, each final model is evaluated on the study's default case
(seeds :data:`EVAL_SEEDS`) and ``OUT/seeds.csv`` (one row per seed) and ``OUT/seeds.md``
(the interquartile mean over seeds and its 95 % percentile-bootstrap interval, per metric)
are written.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from boids_env.eval import folder
from boids_env.eval.stats import bootstrap_ci, iqm
from boids_env.extras import import_extra
from boids_env.files import atomic_path, write_json, write_text
from boids_env.train.config import TrainConfig

BACKENDS = ("process", "ray")
EVAL_SEEDS = (100, 101, 102, 103, 104)
"""Seeds of the default-case episodes each seed's final model is judged on."""
METRICS = ("V_sep", "V_coh", "V_align", "total", "touching_fraction", "wall_fraction",
           "min_distance")
"""The seeds table's columns (``total`` = V_sep + V_coh + V_align)."""
MAX_SEEDS = 64
_CHECKPOINT = re.compile(r"^model_(\d+)_steps\.zip$")


@dataclass(frozen=True)
class SeedJob:
    """One seed's training: the run's config with its seed, its folder, and the checkpoint it
    goes on from (None: from scratch)."""

    config: dict[str, Any]
    out: str
    resume: str | None = None
    overwrite: bool = False


def check_seeds(seeds: Sequence[int]) -> tuple[int, ...]:
    """Distinct non-negative seeds, at most :data:`MAX_SEEDS`; ``ValueError`` otherwise."""
    values = tuple(seeds)
    if not values or len(values) > MAX_SEEDS:
        raise ValueError(f"--seeds takes 1 to {MAX_SEEDS} seeds, got {len(values)}")
    if any(isinstance(s, bool) or not isinstance(s, int) or not 0 <= s < 2**32 for s in values):
        raise ValueError(f"--seeds must be integers in [0, 2^32), got {list(values)}")
    if len(set(values)) != len(values):
        raise ValueError(f"--seeds must be distinct, got {list(values)}")
    return values


def latest_checkpoint(seed_out: Path) -> Path | None:
    """The checkpoint of most timesteps in ``seed_out/checkpoints`` (None without one)."""
    found = []
    for path in (seed_out / "checkpoints").glob("model_*_steps.zip"):
        match = _CHECKPOINT.match(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return max(found)[1] if found else None


def plan(config: TrainConfig, seeds: Sequence[int], out: Path, overwrite: bool = False,
         resume: str | None = None) -> tuple[list[SeedJob], list[int]]:
    """The jobs still to run and the seeds already done (``model.zip`` present). A seed goes
    on from its own last checkpoint, else from ``resume`` (a model every seed fine-tunes,
    e.g. the shipped one), else starts from scratch."""
    jobs, done = [], []
    for seed in seeds:
        seed_out = out / f"seed_{seed}"
        cfg = config.replace(seed=seed)
        if not overwrite and (seed_out / "model.zip").is_file():
            done.append(seed)
            continue
        last = None if overwrite else latest_checkpoint(seed_out)
        start = str(last) if last is not None else resume
        jobs.append(SeedJob(cfg.to_dict(), str(seed_out), start, overwrite))
    return jobs, done


def run_job(job: SeedJob) -> str:
    """Trains one seed (in this process); returns its ``model.zip``."""
    from boids_env.train.run import train

    config = TrainConfig.from_dict(job.config)
    return str(train(config, job.out, resume=job.resume, overwrite=job.overwrite))


def sweep_identity(config: TrainConfig) -> dict[str, Any]:
    """What makes two sweeps the same: the config without its seed and the fields a resume
    may change (a sweep rerun with more timesteps, other processes or threads goes on)."""
    from boids_env.train.run import RESUME_FREE

    return {k: v for k, v in config.to_dict().items()
            if k != "seed" and k not in RESUME_FREE}


def run_sweep(config: TrainConfig, seeds: Sequence[int], out: str | Path, *,
              backend: str = "process", workers: int | None = None,
              overwrite: bool = False, resume: str | Path | None = None) -> Path:
    """Trains every seed of ``config`` not trained yet and writes the seeds table; returns
    ``OUT/seeds.csv``. ``workers``: seeds trained at once (default: every seed); ``resume``:
    a model zip every seed fine-tunes (a seed with checkpoints of its own goes on from its
    last one instead)."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    seeds = check_seeds(seeds)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    if resume is not None and not Path(resume).is_file():
        raise FileNotFoundError(f"checkpoint to resume not found: {resume}")
    out = Path(out)
    folder.claim(out, {"sweep": sweep_identity(config)}, overwrite=overwrite,
                 owner=folder.SWEEP)
    write_json(out / "sweep.json", {"config": config.to_dict(), "seeds": list(seeds),
                                    "backend": backend})
    jobs, done = plan(config, seeds, out, overwrite,
                      None if resume is None else str(Path(resume).resolve()))
    if done:
        print(f"boids train: seeds {done} already trained in {out}; skipped")
    for job in jobs:
        if job.resume:
            print(f"boids train: seed {job.config['seed']} goes on from {job.resume}")
    if jobs:
        (_run_ray if backend == "ray" else _run_processes)(jobs, workers or len(jobs))
    return write_seeds_table(out, seeds)


def _run_processes(jobs: Sequence[SeedJob], workers: int) -> None:
    """Each job in a process of its own (``python -m boids_env.train.sweep JOB.json``), at
    most ``workers`` at a time; ``RuntimeError`` naming the seeds that failed."""
    pending, running, failed = list(jobs), [], []
    while pending or running:
        while pending and len(running) < workers:
            job = pending.pop(0)
            Path(job.out).parent.mkdir(parents=True, exist_ok=True)
            spec = Path(job.out).parent / f".seed_{job.config['seed']}.job.json"
            with atomic_path(spec) as tmp:
                Path(tmp).write_text(json.dumps(job.__dict__))
            running.append((job, spec, subprocess.Popen(
                [sys.executable, "-m", "boids_env.train.sweep", str(spec)])))
        job, spec, proc = running.pop(0)
        if proc.wait() != 0:
            failed.append(job.config["seed"])
        spec.unlink(missing_ok=True)
    if failed:
        raise RuntimeError(f"training failed for seeds {failed} (their output above); rerun "
                           f"the same command to go on from their last checkpoints")


def _run_ray(jobs: Sequence[SeedJob], workers: int) -> None:
    ray = import_extra("ray", "backend='ray' needs: pip install -e '.[ray]'")
    started = not ray.is_initialized()
    if started:
        ray.init(address=os.environ.get("RAY_ADDRESS") or None, include_dashboard=False,
                 log_to_driver=True)
    try:
        cpus = max(1, TrainConfig.from_dict(jobs[0].config).processes or 1)
        remote = ray.remote(num_cpus=cpus, max_retries=0)(run_job)
        refs = {}
        pending = list(jobs)
        failed = []
        while pending or refs:
            while pending and len(refs) < workers:
                job = pending.pop(0)
                refs[remote.remote(job)] = job
            ready, _ = ray.wait(list(refs), num_returns=1)
            for ref in ready:
                job = refs.pop(ref)
                try:
                    ray.get(ref)
                except Exception as exc:  # the task's own error, as Ray wraps it
                    print(f"boids train: seed {job.config['seed']} failed: {exc}",
                          file=sys.stderr)
                    failed.append(job.config["seed"])
        if failed:
            raise RuntimeError(f"training failed for seeds {failed}; rerun the same command "
                               f"to go on from their last checkpoints")
    finally:
        if started:
            ray.shutdown()


def evaluate_model(model: Path, env_fields: dict[str, Any],
                   seeds: Sequence[int] = EVAL_SEEDS) -> dict[str, float]:
    """Mean metrics of a model's deterministic episodes on the study's default case."""
    from boids_env.environment import BoidsEnv
    from boids_env.eval.episode import env_fields_for, run_episode
    from boids_env.policies.sb3_policy import load_model_policy

    policy = load_model_policy(model)
    rows = []
    for seed in seeds:
        env = BoidsEnv(**env_fields_for(policy, env_fields))
        rows.append(run_episode(env, policy, seed).metrics)
        env.close()
    out = {k: float(np.mean([r[k] for r in rows])) for k in METRICS if k != "total"}
    out["total"] = out["V_sep"] + out["V_coh"] + out["V_align"]
    return out


def write_seeds_table(out: Path, seeds: Sequence[int]) -> Path:
    """``seeds.csv`` (a row per seed: its final model on the default case) and ``seeds.md``
    (per metric: interquartile mean over seeds, 95 % bootstrap interval, range)."""
    rows = []
    for seed in seeds:
        seed_out = out / f"seed_{seed}"
        env_fields = TrainConfig.from_dict(json.loads((seed_out / "config.json").read_text())
                                           ).env_fields
        rows.append({"seed": seed, **evaluate_model(seed_out / "model.zip", env_fields)})
    table = pd.DataFrame(rows, columns=["seed", *METRICS])
    with atomic_path(out / "seeds.csv") as tmp:
        table.to_csv(tmp, index=False)
    lines = [f"# Seeds of {out.name}: final models on the study's default case",
             "", f"Seeds {list(seeds)}; each model's mean over episodes seeded "
             f"{list(EVAL_SEEDS)}. IQM: interquartile mean over seeds; CI: 95 % percentile "
             "bootstrap of the mean over seeds.", "",
             "| metric | IQM | 95 % CI | min | max |", "|---|---|---|---|---|"]
    for metric in METRICS:
        values = table[metric].to_numpy(dtype=float)
        lo, hi = bootstrap_ci(values)
        lines.append(f"| {metric} | {iqm(values):.4f} | [{lo:.4f}, {hi:.4f}] | "
                     f"{values.min():.4f} | {values.max():.4f} |")
    lines += ["", "| seed | " + " | ".join(METRICS) + " |",
              "|---" * (len(METRICS) + 1) + "|"]
    lines += ["| " + " | ".join([str(int(r["seed"]))] + [f"{r[m]:.4f}" for m in METRICS])
              + " |" for r in rows]
    write_text(out / "seeds.md", "\n".join(lines) + "\n")
    folder.record_files(out, ["seeds.csv", "seeds.md", "sweep.json"], folder.SWEEP)
    return out / "seeds.csv"


def main(argv: Sequence[str] | None = None) -> int:
    """Runs one seed's job file (the process backend's worker)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m boids_env.train.sweep JOB.json", file=sys.stderr)
        return 2
    job = SeedJob(**json.loads(Path(args[0]).read_text()))
    run_job(job)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
