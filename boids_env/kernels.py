"""Compiled kernels for the step's work outside the physics, with numpy as the reference.

A step of 19 robots is about a hundred numpy calls on 18-row arrays, each costing about a
microsecond of call overhead whatever it computes. The neighbour search, the observations'
study blocks, the violation flags with their reward terms and the speed limit each run as one
numba loop instead (:mod:`boids_env._compiled`), and round exactly as the numpy code they
replace: trajectories, rewards and digests stay the same bits (``tests/env/test_kernels.py``
compares whole episodes of both paths).

The numpy functions stay the reference and the fallback: without numba, with
``BOIDS_KERNELS=0`` in the environment, or inside :func:`reference`, every caller runs them.
numba is imported on the first step (not at ``import boids_env``), and each kernel is compiled
once per machine (``cache=True``) into ``__pycache__`` beside the source.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from types import ModuleType

_module: ModuleType | None = None
_loaded = False
_forced_off = False


def compiled() -> ModuleType | None:
    """The kernel module, or None when the numpy reference must run (no numba,
    ``BOIDS_KERNELS=0``, or inside :func:`reference`)."""
    global _module, _loaded
    if _forced_off:
        return None
    if not _loaded:
        _loaded = True
        if os.environ.get("BOIDS_KERNELS", "1") != "0":
            try:
                from boids_env import _compiled
            except ImportError:  # numba missing or broken on this platform: numpy runs
                _compiled = None
            _module = _compiled
    return _module


@contextlib.contextmanager
def reference() -> Iterator[None]:
    """Runs the numpy reference instead of the kernels inside the block (tests, A/B
    timing)."""
    global _forced_off
    before = _forced_off
    _forced_off = True
    try:
        yield
    finally:
        _forced_off = before
