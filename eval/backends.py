"""How the eval runner's episodes run: one of :data:`~boids_env.eval.pool.BACKENDS`.

``process`` hands them to the isolated worker pool (:mod:`boids_env.eval.pool`), ``ray`` to
Ray tasks with the same isolation (any exception is a failure row, a crashed worker fails only
its task, a task past the timeout is cancelled), ``inline`` runs them one after another in the
calling process. Each outcome goes to ``record(task, ok, row)`` as it arrives.
"""

from __future__ import annotations

import time
import traceback
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from boids_env.eval.pool import available_cores, guarded, run_isolated
from boids_env.extras import import_extra

Record = Callable[[Any, bool, dict[str, Any]], None]
"""Called with ``(task, ok, row)`` for every task: its metrics row, or its failure row."""


def execute(tasks: Sequence[Any], run: Callable[[Any], dict[str, Any]],
            workers: int | None, backend: str, timeout: float | None, record: Record
            ) -> None:
    """Runs ``run(task)`` for every task on ``backend`` (at most ``workers`` at a time) and
    records each outcome; ``timeout`` is seconds per task (None: no limit)."""
    if not tasks:
        return
    if backend == "inline":
        for task in tasks:
            record(task, *_inline(run, task))
    elif backend == "ray":
        _execute_ray(tasks, run, workers, timeout, record)
    else:
        run_isolated(tasks, run, record, workers=min(workers or available_cores(),
                                                     len(tasks)), timeout=timeout)


def _inline(run: Callable[[Any], dict[str, Any]], task: Any) -> tuple[bool, dict[str, Any]]:
    try:
        return True, run(task)
    except KeyboardInterrupt:
        raise  # in this process a policy's KeyboardInterrupt cannot be told from Ctrl-C
    except BaseException as exc:  # SystemExit of a policy included
        return False, {"reason": "exception", "error": f"{type(exc).__name__}: {exc}",
                       "traceback": traceback.format_exc()}


def _execute_ray(tasks: Sequence[Any], run: Callable[[Any], dict[str, Any]],
                 workers: int | None, timeout: float | None, record: Record) -> None:
    """Ray tasks with the process backend's isolation: any exception is a failure row, a
    crashed worker fails only its task (no retries), and at most ``workers`` tasks are in
    flight so each is timed from when it starts running."""
    ray = import_extra("ray", "backend='ray' needs: pip install -e '.[ray]'")
    started = not ray.is_initialized()
    if started:
        ray.init(include_dashboard=False, log_to_driver=False)
    remote = ray.remote(max_retries=0)(guarded)
    limit = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    queue: deque[Any] = deque(tasks)
    running: dict[Any, tuple[Any, float]] = {}
    try:
        while queue or running:
            while queue and len(running) < limit:
                task = queue.popleft()
                running[remote.remote(run, task)] = (task, time.monotonic())
            wait_for = None
            if timeout is not None:
                first = min(start for _, start in running.values())
                wait_for = max(0.0, first + timeout - time.monotonic())
            ready, _ = ray.wait(list(running), num_returns=1, timeout=wait_for)
            for ref in ready:
                record(running.pop(ref)[0], *_ray_outcome(ray, ref))
            _ray_timeouts(ray, running, timeout, record)
    except KeyboardInterrupt:
        _ray_drain(ray, running, record)
        raise
    finally:
        if started:
            ray.shutdown()


def _ray_timeouts(ray: Any, running: dict[Any, tuple[Any, float]], timeout: float | None,
                  record: Record) -> None:
    if timeout is None:
        return
    now = time.monotonic()
    for ref, (task, start) in list(running.items()):
        if now - start >= timeout:
            ray.cancel(ref, force=True)
            del running[ref]
            record(task, False, {"reason": "timeout", "error": (
                f"the episode ran longer than the episode timeout ({timeout:g} s); its Ray "
                f"task was cancelled")})


def _ray_drain(ray: Any, running: dict[Any, tuple[Any, float]], record: Record) -> None:
    """After Ctrl-C: records the tasks already finished and cancels the others."""
    if running:
        ready, _ = ray.wait(list(running), num_returns=len(running), timeout=0)
        for ref in ready:
            record(running.pop(ref)[0], *_ray_outcome(ray, ref))
    for ref in running:
        ray.cancel(ref, force=True)


def _ray_outcome(ray: Any, ref: Any) -> tuple[bool, dict[str, Any]]:
    try:
        ok, row = ray.get(ref)
    except Exception as exc:  # the worker crashed or the task was lost
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        return False, {"reason": "worker died", "error": f"{type(exc).__name__}: {first}"}
    row.pop("fatal", None)
    return ok, row
