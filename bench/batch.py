"""Many worlds per process: K copies of 13 robots stepped through one
:class:`~boids_env.batch.EnvBatch` against the same K envs stepped one after another
(``step_arrays`` each), random actions, timed together round by round."""

from __future__ import annotations

import json
import time
from collections.abc import Callable

import numpy as np

from boids_env import parallel_env
from boids_env.batch import EnvBatch

ROBOTS = 13


def batch_loops(copies: int, steps: int
                ) -> tuple[dict[str, Callable[[], int]], tuple[list, list]]:
    """Two loops over the same actions, each returning the copy-steps it made: ``batch``
    (one ``EnvBatch.step_arrays`` per step) and ``separate`` (each env's ``step_arrays``);
    and the two ways' envs."""
    def envs() -> list:
        return [parallel_env(robots=ROBOTS, max_cycles=10**9, startup_time=0.0)
                for _ in range(copies)]

    batch, separate = EnvBatch(envs()), envs()
    followers = ROBOTS - 1
    limit = separate[0].config.world.max_speed
    actions = np.random.default_rng(0).uniform(-limit, limit, (steps, followers * copies, 2))

    def run_batch() -> int:
        batch.reset_arrays(list(range(copies)))
        for k in range(steps):
            batch.step_arrays(actions[k])
        return steps * copies

    def run_separate() -> int:
        for seed, env in enumerate(separate):
            env.reset_arrays(seed=seed)
        for k in range(steps):
            for i, env in enumerate(separate):
                env.step_arrays(actions[k, i * followers:(i + 1) * followers])
        return steps * copies

    return {"batch": run_batch, "separate": run_separate}, (batch.envs, separate)


def batch_rows(sizes: list[int], steps: int, repeats: int, record: Callable[..., None],
               together: Callable[..., tuple[dict, list]],
               paired: Callable[[list, str, str], float]) -> dict[str, float]:
    """A row per K and way (copy-steps/s), and each K's batch/separate rate round by
    round."""
    ratios = {}
    for copies in sizes:
        summary, rounds = together(batch_loops(copies, steps)[0], repeats)
        for kind, rate in summary.items():
            record(f"{kind} {copies}x{ROBOTS}", ROBOTS, ROBOTS - 1, rate)
        ratios[f"batch_over_separate_{copies}x{ROBOTS}"] = paired(rounds, "batch", "separate")
    return ratios


def cpu_rounds(sizes: list[int], steps: int, rounds: int) -> dict[int, dict[str, list[float]]]:
    """CPU time (µs) per copy-step of each way, round by round, for each K."""
    out = {}
    for copies in sizes:
        loops = batch_loops(copies, steps)[0]
        for fn in loops.values():
            fn()  # warm-up
        times: dict[str, list[float]] = {kind: [] for kind in loops}
        for _ in range(rounds):
            for kind, fn in loops.items():
                start = time.process_time()
                done = fn()
                times[kind].append((time.process_time() - start) / done * 1e6)
        out[copies] = times
    return out


if __name__ == "__main__":  # python -m boids_env.bench.batch: one process's JSON line
    from boids_env import kernels

    kernels.load()
    print(json.dumps(cpu_rounds([4, 8, 16], 100, 3)))
