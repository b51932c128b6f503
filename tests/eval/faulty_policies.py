"""Policies that fail on purpose, for the eval runner's isolation tests. The worker processes
import them as ``faulty_policies:NAME`` specs (this folder is on ``sys.path`` under pytest,
and on ``PYTHONPATH`` for the command-line tests).

Each fails only in the episode of seed 1 (at its first step), so a test can check that
exactly that episode is marked failed while the seeds 0 and 2 beside it finish.
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np

FAILING_SEED = 1


class _Zero:
    """Commands zero velocity; subclasses fail in :meth:`fail` on the failing seed."""

    def __init__(self) -> None:
        self.seed: int | None = None

    def reset(self, seed: int | None = None) -> None:
        self.seed = seed

    def act(self, observations):
        if self.seed == FAILING_SEED:
            self.fail()
        return {agent: np.zeros(2, dtype=np.float32) for agent in observations}

    def fail(self) -> None:
        raise NotImplementedError


class RaisesSystemExit(_Zero):
    def fail(self) -> None:
        raise SystemExit(3)


class RaisesKeyboardInterrupt(_Zero):
    def fail(self) -> None:
        raise KeyboardInterrupt


class RaisesBaseException(_Zero):
    def fail(self) -> None:
        raise BaseException("a policy raised BaseException")


class ExitsProcess(_Zero):
    def fail(self) -> None:
        os._exit(7)


class KillsItself(_Zero):
    def fail(self) -> None:
        os.kill(os.getpid(), signal.SIGKILL)


class Hangs(_Zero):
    def fail(self) -> None:
        time.sleep(3600)


class Slow(_Zero):
    """Never fails; takes 0.05 s per step (an episode of 20 steps: about 1 s)."""

    def act(self, observations):
        time.sleep(0.05)
        return {agent: np.zeros(2, dtype=np.float32) for agent in observations}


def _refuse_to_unpickle() -> None:
    raise RuntimeError("this runner cannot be rebuilt in a worker process")


class UnstartableRunner:
    """A runner (task -> row) that pickles here but fails while a worker unpickles it, so the
    worker dies before it is ready."""

    def __reduce__(self):
        return _refuse_to_unpickle, ()

    def __call__(self, task):
        return {}


def SlowReynolds():
    """The study's Reynolds policy, 0.01 s slower per step: the same episodes (its results
    are the plain policy's), slow enough for a test to kill a run between two of them."""
    from boids_env.policies.registry import load_policy

    policy = load_policy("reynolds")
    for name in ("act", "act_batch"):
        method = getattr(policy, name)

        def slowed(*args, _method=method, **kwargs):
            time.sleep(0.01)
            return _method(*args, **kwargs)

        setattr(policy, name, slowed)
    return policy
