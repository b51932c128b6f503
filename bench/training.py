"""Benchmarks of what users wait for beyond the env itself: training throughput against the
env's raw speed (for 1, 2 and all cores), a learned-policy episode against a Reynolds one, and
the paper suite split into its episodes and its report."""

from __future__ import annotations

import os
import tempfile
import time
from typing import Any

import numpy as np


def raw_env_rate(config: Any, steps: int = 300) -> float:
    """Agent-steps/s of the recipe's env copies stepped in one process with random actions
    (the array API, no learner): the ceiling training is measured against."""
    from boids_env.train.run import copy_specs
    from boids_env.train.shards import Shard

    shard = Shard(copy_specs(config))
    shard.seed(np.random.SeedSequence(config.seed).spawn(len(shard.envs)))
    shard.reset()
    slots = sum(shard.sizes)
    actions = np.random.default_rng(0).uniform(-0.5, 0.5, (20, slots, 2)).astype(np.float32)
    shard.step(actions[0])
    start = time.perf_counter()
    for k in range(steps):
        shard.step(actions[k % 20])
    rate = steps * slots / (time.perf_counter() - start)
    shard.close()
    return rate


def training_rate(config: Any, rollouts: int = 3) -> dict[str, Any]:
    """Follower-steps/s of PPO on ``config`` (after one warm-up rollout), with the learner's
    threads, processes and device the config resolves to."""
    import torch
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecMonitor

    from boids_env.train.ppo import learner_class
    from boids_env.train.run import make_vec_env
    torch.set_num_threads(config.resolved_threads())
    flock = make_vec_env(config)
    venv = VecMonitor(flock)
    try:
        cls = learner_class(config.algorithm)
        model = cls("MlpPolicy", venv, device=config.resolved_device(),
                    **config.algorithm_kwargs())
        # no output: SB3's default logger would leave an empty SB3-<date> folder in /tmp
        model.set_logger(Logger(None, []))
        chunk = config.n_steps * venv.num_envs
        model.learn(chunk)
        start = time.perf_counter()
        model.learn(rollouts * chunk, reset_num_timesteps=False)
        seconds = time.perf_counter() - start
    finally:
        venv.close()
    return {"processes": flock.processes,
            "torch_threads": config.resolved_threads(), "device": config.resolved_device(),
            "copies": config.copies, "follower_steps_per_s": rollouts * chunk / seconds}


def training_scaling(recipe: str = "ppo_safe", cores: list[int] | None = None
                     ) -> list[dict[str, Any]]:
    """Training throughput of ``recipe`` on 1, 2 and all cores, each beside the raw env rate
    of the same copies. A setting of n cores pins its process (and the env workers it
    starts) to n cores and uses the defaults a machine of n cores gets: worker processes
    from ``default_processes`` (copies raised to at least that many) and the learner threads
    ``default_threads`` leaves them.
    Each runs in a fresh process so torch's thread pool starts clean."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    from boids_env.eval.pool import available_cores

    total = available_cores()
    cores = cores or sorted({1, min(2, total), total})
    rows = []
    for n in cores:  # not a Pool: its daemonic workers could not start env workers
        with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
            rows.append(pool.submit(_scaling_row, recipe, n).result())
    return rows


def _scaling_row(recipe: str, cores: int) -> dict[str, Any]:
    from boids_env.train.config import TrainConfig, resolve_recipe
    from boids_env.train.vec_env import default_processes, default_threads

    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:cores])
    config = TrainConfig.from_toml(resolve_recipe(recipe))
    processes = default_processes(max(config.copies, cores), cores)
    config = config.replace(copies=max(config.copies, processes), processes=processes,
                            torch_threads=default_threads(processes, cores), eval_every=0,
                            checkpoint_every=0)
    row = training_rate(config)
    row["cores"] = cores
    row["raw_env_agent_steps_per_s"] = raw_env_rate(config)
    row["ratio"] = row["follower_steps_per_s"] / row["raw_env_agent_steps_per_s"]
    return row


def episode_costs(seeds: int = 3) -> dict[str, float]:
    """Wall seconds of one default-case episode (best of ``seeds``) for the Reynolds policy and
    the shipped learned policy, as ``boids run`` runs them (recording included)."""
    from boids_env.environment import BoidsEnv
    from boids_env.eval.episode import env_fields_for, run_episode
    from boids_env.policies.registry import load_policy

    out = {}
    for spec in ("reynolds", "learned"):
        policy = load_policy(spec)
        env = BoidsEnv(**env_fields_for(policy))
        run_episode(env, policy, 0)
        times = []
        for seed in range(seeds):
            start = time.perf_counter()
            run_episode(env, policy, seed)
            times.append(time.perf_counter() - start)
        out[spec] = min(times)
    out["learned_over_reynolds"] = out["learned"] / out["reynolds"]
    return out


def lab_episode_costs(rounds: int = 3, max_cycles: int | None = None) -> dict[str, Any]:
    """CPU seconds of one ``lab`` episode of the followers for a lab (``learned-scenes``:
    the actor, the safety filter, the wall slots) and of the Reynolds policy, in turn, each
    round the best of two: ``{"rounds": [(reynolds, learned), ...],
    "learned_scenes_over_reynolds": the median of the rounds' quotients}``."""
    import statistics

    from boids_env.environment import BoidsEnv
    from boids_env.eval.episode import env_fields_for, run_episode
    from boids_env.policies.registry import load_policy

    fields = {"scene": "lab", **({"max_cycles": max_cycles} if max_cycles else {})}
    runs = []
    for spec in ("reynolds", "learned-scenes"):
        policy = load_policy(spec)
        env = BoidsEnv(**env_fields_for(policy, fields))
        run_episode(env, policy, 0)  # warm-up: caches, route fields, compiled kernels
        runs.append((env, policy))

    def cost(env: Any, policy: Any, seed: int) -> float:
        start = time.process_time()
        run_episode(env, policy, seed)
        return time.process_time() - start

    rows = [tuple(min(cost(env, policy, seed) for seed in (1, 2)) for env, policy in runs)
            for _ in range(rounds)]
    return {"rounds": rows,
            "learned_scenes_over_reynolds": statistics.median(b / a for a, b in rows)}


def command_costs(repeats: int = 3) -> dict[str, float]:
    """Wall seconds of the whole ``boids run`` command (best of ``repeats``, each a fresh
    process: imports, model load, the episode and its files) for the Reynolds policy and the
    shipped learned policy."""
    import subprocess
    import sys
    import tempfile

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for spec in ("reynolds", "learned"):
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                subprocess.run([sys.executable, "-m", "boids_env.train.cli", "run", "--policy",
                                spec, "--out", f"{tmp}/{spec}", "--overwrite"],
                               check=True, capture_output=True, timeout=600)
                times.append(time.perf_counter() - start)
            out[spec] = min(times)
    out["learned_over_reynolds"] = out["learned"] / out["reynolds"]
    return out


def paper_suite_seconds(workers: int | None = None) -> dict[str, float] | None:
    """Wall seconds of ``boids eval --suite paper`` for the Reynolds policy from scratch in a
    temporary folder, split into the episodes and the report (None without the eval extra)."""
    try:
        from boids_env.eval.report import build_report
        from boids_env.eval.runner import PolicySpec, run_suite
        from boids_env.eval.suites import PAPER
    except ImportError:
        return None
    from boids_env.eval.pool import available_cores

    workers = workers or available_cores()
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        run_suite([PolicySpec("reynolds")], PAPER, tmp, workers=workers, progress=False)
        episodes = time.perf_counter() - start
        build_report(tmp)
        report = time.perf_counter() - start - episodes
    return {"workers": workers, "episodes": episodes, "report": report,
            "total": episodes + report}
