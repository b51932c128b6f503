"""Compiled kernels for the step's work outside the physics, with numpy as the reference.

A step of 19 robots is about a hundred numpy calls on 18-row arrays, each costing about a
microsecond of call overhead whatever it computes. The neighbour search, the observations'
study blocks, the violation flags with their reward terms, each follower's nearest robot for
the safety flags and the speed limit each run as one numba loop instead
(:mod:`boids_env._compiled`), and so do the scene's queries (nearest wall points, wall
flags, sight lines, clearance, ray casts), the safety filter, route sensing's sight lines,
a learned actor's elementwise work, many robots' neighbours on a grid (the KD-tree's bits),
the Reynolds policy's rule forces and a unicycle's turn every physics substep; each rounds
exactly as the numpy code it replaces:
trajectories, rewards and digests stay the same bits (``tests/env/test_kernels.py`` compares
whole episodes of both paths).

The numpy functions stay the reference and the fallback: without numba, with
``BOIDS_KERNELS=0`` in the environment, or inside :func:`reference`, every caller runs them.

Loading the kernels costs a process about half a second of CPU and 100 MiB (numba's import
and its LLVM, though each kernel is compiled only once per machine, ``cache=True``, into
``__pycache__`` beside the source): more than one study episode (``boids run``) saves. So a
process starts on numpy and loads the kernels once it has made :data:`LOAD_AFTER` calls that
could use them (about 2,500 steps); the bits are the same either way, so the switch shows
nowhere but in the speed. ``BOIDS_KERNELS=1`` (or :func:`load`) loads them at once.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator
from types import ModuleType

LOAD_AFTER = 10_000
"""Calls to :func:`compiled` after which a process loads the kernels (a step of the study's
case makes 4, one in a scene with the safety filter and a learned actor about 12): about the
steps whose savings repay the load, measured at 13 to 19 robots."""

_module: ModuleType | None = None
_loaded = False
_forced_off = False
_calls = 0


def compiled() -> ModuleType | None:
    """The kernel module, or None while the numpy reference runs (not loaded yet, no
    numba, ``BOIDS_KERNELS=0``, or inside :func:`reference`)."""
    global _calls
    if _forced_off:
        return None
    if _loaded:
        return _module
    setting = os.environ.get("BOIDS_KERNELS", "")
    if setting == "0":
        return None
    _calls += 1
    if setting != "1" and _calls < LOAD_AFTER:
        return None
    return load()


def loaded() -> ModuleType | None:
    """The kernel module if it is loaded already (and not switched off), else None; unlike
    :func:`compiled` the call is not counted towards :data:`LOAD_AFTER`."""
    return _module if _loaded and not _forced_off else None


def load() -> ModuleType | None:
    """Loads the kernels now (None without numba or with ``BOIDS_KERNELS=0``)."""
    global _module, _loaded
    if not _loaded:
        _loaded = True
        if os.environ.get("BOIDS_KERNELS", "") != "0":
            try:
                from boids_env import _compiled
            except ImportError:  # numba missing, or too old for this numpy: numpy runs
                _compiled = None
            except (RuntimeError, OSError) as err:  # e.g. no writable cache folder
                warnings.warn(f"the compiled kernels could not load ({err}); the numpy "
                              f"reference runs instead (same results, slower; "
                              f"NUMBA_CACHE_DIR names a writable cache folder)",
                              RuntimeWarning, stacklevel=2)
                _compiled = None
            _module = _compiled
    return _module if not _forced_off else None


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
