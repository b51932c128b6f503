"""Isolated worker processes for the eval runner: one item at a time per worker, so every
failure is pinned on the item that caused it.

What it guarantees (the runner's tests check each):

- any failure of an item becomes a failure row for that item only: an exception of any kind
  (``SystemExit`` and ``KeyboardInterrupt`` raised by a policy included), a worker that dies
  (``os._exit``, a signal, a segfault: only the item it held is marked), or an item running
  longer than ``timeout`` (its worker is killed and replaced);
- Ctrl-C (``KeyboardInterrupt`` in the calling process): results already sent are still
  handed to ``on_result``, every worker is killed and reaped, and the interrupt propagates,
  within a fraction of a second whatever the workers are doing. Workers ignore SIGINT (a
  terminal sends it to the whole process group), so only the calling process decides;
- workers exit by themselves within about a second when the calling process dies, even by
  SIGKILL: each holds the read end of a pipe whose write end only the caller holds, and a
  thread of the worker exits the process when that pipe reports end-of-file.

Workers start from a forkserver (where the platform has one) that preloads the env, so a
replacement worker is ready in milliseconds; otherwise they are spawned.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any

BACKENDS = ("process", "ray", "inline")
"""How the eval runner runs episodes: ``process``, isolated local worker processes (this
module); ``ray``, Ray tasks (a cluster or a local one); ``inline``, in the calling process
one after another (debugging: exceptions are recorded, but a crash, a hang or ``os._exit``
takes the run down)."""
DEFAULT_EPISODE_TIMEOUT = 600.0
"""Seconds an episode may run before it is stopped and recorded as failed (the study's
episode takes about 0.3 s; 1000 robots with the Reynolds policy about 8 s)."""

Outcome = tuple[bool, dict[str, Any]]
"""``(True, row)`` for a finished item, ``(False, failure)`` otherwise; a failure has
``reason`` (``exception``, ``worker died`` or ``timeout``) and ``error`` (a sentence)."""

PRELOAD = ("boids_env.eval.runner", "boids_env.environment", "boids_env.eval.episode",
           "boids_env.policies.registry")
"""Modules the forkserver imports once, so each worker starts without importing them."""
STARTUP_TIMEOUT = 120.0
"""Seconds a new worker may take to start and report ready."""
READY = "ready"
STOP_GRACE = 2.0
"""Seconds an idle worker gets to exit after being told to, before it is killed."""


def available_cores() -> int:
    """The cores this process may run on (its affinity set where the OS has one: a process
    pinned to 4 of 16 cores, or a container's share, counts 4), for sizing worker pools."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def guarded(fn: Callable[[Any], dict[str, Any]], item: Any) -> Outcome:
    """``fn(item)`` as an :data:`Outcome`: any exception, ``SystemExit`` and
    ``KeyboardInterrupt`` included, becomes a failure row with its traceback (``fatal`` is
    True for those that are not ``Exception``: the process was asked to stop)."""
    try:
        return True, fn(item)
    except BaseException as exc:  # isolating every failure is the point
        return False, {"reason": "exception", "error": f"{type(exc).__name__}: {exc}",
                       "traceback": traceback.format_exc(),
                       "fatal": not isinstance(exc, Exception)}


def exit_description(code: int | None) -> str:
    """A worker's exit code in words (``killed by SIGKILL``, ``exit code 3``)."""
    if code is None:
        return "exit status unknown"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _exit_with_parent(alive: Connection) -> None:
    """Worker thread: returns from ``recv`` only when the caller's end of ``alive`` is closed
    (the caller exited or died), then ends the worker at once."""
    try:
        alive.recv()
    except BaseException:  # end-of-file is the signal waited for
        pass
    os._exit(3)


def _worker(conn: Connection, alive: Connection, fn: Callable[[Any], dict[str, Any]]) -> None:
    """A worker's loop: receive an item, send its outcome, until told to stop (None)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_with_parent, args=(alive,), daemon=True).start()
    try:
        conn.send(READY)
    except OSError:  # the caller is gone already (interrupted while this one started)
        return
    while True:
        try:
            item = conn.recv()
        except (EOFError, OSError):
            return
        if item is None:
            return
        ok, row = guarded(fn, item)
        fatal = bool(row.get("fatal", False))
        try:
            conn.send((ok, row))
        except Exception as exc:  # e.g. a row that cannot be pickled
            conn.send((False, {"reason": "exception", "fatal": fatal,
                               "error": f"the episode's result could not be sent back: "
                                        f"{type(exc).__name__}: {exc}"}))
        if fatal:
            # SystemExit / KeyboardInterrupt / another BaseException: the policy asked the
            # process to stop. Honour it after reporting; the caller retires this worker (it
            # saw "fatal") and a fresh one takes the next item.
            os._exit(0)


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """SIGINT blocked in this thread while a worker (and, the first time, the forkserver)
    starts. A started process inherits the mask, so a Ctrl-C during its interpreter's
    start-up or the forkserver's preload stays pending there instead of killing it mid-import
    ('Fatal Python error: init_import_site'); the forkserver and the workers then ignore
    SIGINT, which discards it. Here the pending interrupt is delivered when the mask is
    restored: the caller gets its KeyboardInterrupt right after the start.

    The resource tracker is started first: starting it unblocks SIGINT on the way out
    (:mod:`multiprocessing.resource_tracker` blocks it around its own start), which would
    open the window again for the forkserver started next."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def context() -> Any:
    """The multiprocessing context of the workers: forkserver (preloading :data:`PRELOAD`)
    where available, else spawn. Never fork: the caller may hold threads (torch, tqdm)."""
    if "forkserver" in mp.get_all_start_methods():
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(list(PRELOAD))
        return ctx
    return mp.get_context("spawn")


@dataclass
class _Slot:
    """One worker process and the item it holds (None: idle)."""

    process: Any
    conn: Connection
    alive: Connection
    item: Any = None
    started: float = 0.0

    @classmethod
    def start(cls, ctx: Any, fn: Callable[[Any], dict[str, Any]]) -> _Slot:
        ours, theirs = ctx.Pipe(duplex=True)
        alive_r, alive_w = ctx.Pipe(duplex=False)
        process = ctx.Process(target=_worker, args=(theirs, alive_r, fn),
                              name="boids-eval-worker")
        with _sigint_blocked():
            process.start()
        theirs.close()
        alive_r.close()
        return cls(process, ours, alive_w)

    def ready(self) -> None:
        """Waits for the worker's ready message; ``ChildProcessError`` if it dies first (it
        could not start: e.g. the main module cannot be imported, as from ``python -``)."""
        wait([self.conn, self.process.sentinel], timeout=STARTUP_TIMEOUT)
        try:
            if self.conn.poll() and self.conn.recv() == READY:
                return
        except (EOFError, OSError):
            pass
        self.kill()
        raise ChildProcessError(
            f"an eval worker process could not start "
            f"({exit_description(self.process.exitcode)}; its error is printed above)")

    def assign(self, item: Any) -> bool:
        """Sends ``item``; False if the worker is gone."""
        try:
            self.conn.send(item)
        except (OSError, EOFError):
            return False
        self.item, self.started = item, time.monotonic()
        return True

    def take(self) -> Any:
        item, self.item = self.item, None
        return item

    def kill(self) -> None:
        if self.process.is_alive():
            self.process.kill()
        self.process.join(5)

    def stop(self) -> None:
        """Ends the worker: politely when idle, by SIGKILL when busy or slow; reaps it."""
        if self.item is None and self.process.is_alive():
            try:
                self.conn.send(None)
            except (OSError, EOFError):
                pass
            self.process.join(STOP_GRACE)
        self.kill()
        for conn in (self.conn, self.alive):
            conn.close()
        if self.process.exitcode is not None:  # else it is stuck in the kernel: leave it
            self.process.close()


OnResult = Callable[[Any, bool, dict[str, Any]], None]


def run_isolated(items: Sequence[Any], fn: Callable[[Any], dict[str, Any]],
                 on_result: OnResult, *, workers: int, timeout: float | None = None) -> None:
    """Runs ``fn`` on every item in worker processes, calling ``on_result(item, ok, row)`` in
    this process as each outcome arrives (see :data:`Outcome`).

    Args:
        items: picklable work items.
        fn: a picklable (module-level) function of one item returning a picklable dict.
        on_result: called for every item exactly once, unless interrupted.
        workers: worker processes (at most one per item).
        timeout: seconds an item may run before its worker is killed (None: no limit).
    """
    ctx = context()
    queue = deque(items)
    slots: list[_Slot] = []
    try:
        while queue or any(s.item is not None for s in slots):
            _assign(ctx, fn, slots, queue, workers, on_result)
            _collect(slots, timeout, on_result)
    except KeyboardInterrupt:
        _drain(slots, on_result)
        raise
    finally:
        for slot in slots:
            slot.stop()


def _assign(ctx: Any, fn: Callable[[Any], dict[str, Any]], slots: list[_Slot],
            queue: deque[Any], workers: int, on_result: OnResult) -> None:
    for slot in [s for s in slots if s.item is None and not s.process.is_alive()]:
        slots.remove(slot)
        slot.stop()
    busy = sum(s.item is not None for s in slots)
    new = [_Slot.start(ctx, fn) for _ in range(min(workers, busy + len(queue)) - len(slots))]
    slots += new
    for slot in new:  # started together, awaited together
        slot.ready()
    for slot in slots:
        if slot.item is None and queue:
            item = queue.popleft()
            if not slot.assign(item):
                # The worker died before it got the item: the item is not to blame, but
                # marking it (rather than retrying) bounds the work if workers cannot start.
                slot.process.join(1)
                on_result(item, False, {"reason": "worker died", "error": (
                    f"worker process died before the episode started "
                    f"({exit_description(slot.process.exitcode)})")})


def _collect(slots: list[_Slot], timeout: float | None, on_result: OnResult) -> None:
    busy = [s for s in slots if s.item is not None]
    if not busy:
        return
    wait_for = None
    if timeout is not None:
        wait_for = max(0.0, min(s.started for s in busy) + timeout - time.monotonic())
    wait([s.conn for s in busy] + [s.process.sentinel for s in busy], timeout=wait_for)
    now = time.monotonic()
    for slot in busy:
        ended = False
        if slot.conn.poll():
            try:
                ok, row = slot.conn.recv()
            except (EOFError, OSError):
                ended = True  # the worker is gone or going: handled below
            else:
                fatal = bool(row.pop("fatal", False))
                on_result(slot.take(), ok, row)
                if fatal:  # the worker exits after such a failure: never give it more
                    slots.remove(slot)
                    slot.stop()
                continue
        if ended or not slot.process.is_alive():
            slot.process.join(1)
            on_result(slot.take(), False, {"reason": "worker died", "error": (
                f"worker process died during the episode "
                f"({exit_description(slot.process.exitcode)})")})
            slots.remove(slot)
            slot.stop()
        elif timeout is not None and now - slot.started >= timeout:
            slot.kill()
            on_result(slot.take(), False, {"reason": "timeout", "error": (
                f"the episode ran longer than the episode timeout ({timeout:g} s); its "
                f"worker was killed")})
            slots.remove(slot)
            slot.stop()


def _drain(slots: list[_Slot], on_result: OnResult) -> None:
    """After Ctrl-C: hands over the outcomes already sent, without waiting for more."""
    for slot in slots:
        if slot.item is None:
            continue
        try:
            if slot.conn.poll(0):
                ok, row = slot.conn.recv()
                row.pop("fatal", None)
                on_result(slot.take(), ok, row)
        except (EOFError, OSError):
            continue
