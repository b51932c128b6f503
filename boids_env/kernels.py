"""Compiled kernels for the step's work outside the physics, with numpy as the reference.

A step of 19 robots is about a hundred numpy calls on 18-row arrays, each costing about a
microsecond of call overhead whatever it computes. The neighbour search, the observations'
study blocks, the violation flags with their reward terms, each follower's nearest robot for
the safety flags and the speed limit each run as one numba loop instead (the package
:mod:`boids_env._compiled`), and so do the scene's queries (nearest wall points, wall flags,
sight lines, clearance, ray casts), the safety filter, route sensing's sight lines, many
robots' neighbours on a grid (the KD-tree's bits) and a unicycle's turn every physics
substep; the policies' kernels (a learned actor's elementwise work, the Reynolds rule forces)
live with the policies (:mod:`boids_env.policies.kernels`). Each rounds exactly as the numpy
code it replaces: trajectories, rewards and digests stay the same bits. :data:`KERNELS` pairs
every kernel with that code, and ``tests/env/test_kernels.py`` walks the table (and compares
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
import importlib
import os
import warnings
from collections.abc import Iterator
from types import ModuleType
from typing import Any, NamedTuple

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
            module: ModuleType | None = None
            try:
                from boids_env import _compiled

                module = _compiled
            except ImportError:  # numba missing, or too old for this numpy: numpy runs
                pass
            except (RuntimeError, OSError) as err:  # e.g. no writable cache folder
                warnings.warn(f"the compiled kernels could not load ({err}); the numpy "
                              f"reference runs instead (same results, slower; "
                              f"NUMBA_CACHE_DIR names a writable cache folder)",
                              RuntimeWarning, stacklevel=2)
            _module = module
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


class Twin(NamedTuple):
    """Where a kernel's numpy twin is: what calls the kernel and what it replaces."""

    caller: str
    """``module:qualname`` of the function that runs the kernel when it is loaded and its
    numpy code otherwise (inside :func:`reference`): called alike, it gives the same bits
    either way (what the table's test compares)."""
    references: tuple[str, ...]
    """``module:qualname`` of the numpy functions the kernel ports (the caller itself where
    its numpy code is inline)."""
    why: str = ""
    """Where ``references`` is empty: why no numpy function is the kernel's twin."""


_OBSERVER = "boids_env.observations:Observer.__call__"
_SCENE = "boids_env.world.scene:Scene."
KERNELS: dict[str, Twin] = {
    # boids_env._compiled.study: the study's step
    "study.nearest": Twin("boids_env.observations:nearest_neighbours",
                          ("boids_env.observations:nearest_neighbours",)),
    "study.fill_observations": Twin(_OBSERVER, ("boids_env.observations.observer:_study_blocks",)),
    "study.violations": Twin("boids_env.rewards:Rewards.terms",
                             ("boids_env.metrics:flags_for", "boids_env.rewards:Rewards.terms")),
    "study.rotated": Twin("boids_env.vectors:times_matrix", ("boids_env.vectors:times_matrix",)),
    "study.batch_after": Twin(
        "boids_env.batch:EnvBatch.step_arrays", (),
        "study.nearest, fill_observations and violations of K copies in one call: each copy's "
        "twin is its own step's numpy code (Rewards.terms, Observer.__call__), which the "
        "batch runs for every copy inside reference()"),
    # boids_env._compiled.grid
    "grid.nearest_grid": Twin("boids_env.observations:nearest_neighbours",
                              ("boids_env.observations:nearest_neighbours",)),
    # boids_env._compiled.flags
    "flags.nearest_other": Twin("boids_env.metrics:safety_flags",
                                ("boids_env.metrics:safety_flags",)),
    "flags.safety_gap_terms": Twin("boids_env.rewards:Rewards.terms",
                                   ("boids_env.rewards:Rewards.safety_terms",
                                    "boids_env.rewards:Rewards.gap_term")),
    # boids_env._compiled.motion
    "motion.clip_speed": Twin("boids_env.vectors:clip_speed",
                              ("boids_env.vectors:clip_speed_reference",)),
    "motion.unicycle_substep": Twin("boids_env.world.space:World.step",
                                    ("boids_env.world.robots:Unicycle._substep",)),
    # boids_env._compiled.scene
    "scene.nearest_points": Twin(_SCENE + "nearest_points", (_SCENE + "nearest_points",)),
    "scene.shape_clearance": Twin(_SCENE + "within", (_SCENE + "_shape_clearance",)),
    "scene.capsule_clearance": Twin(_SCENE + "clearance", (_SCENE + "clearance",)),
    "scene.occupied": Twin("boids_env.world.occupancy:OccupancyGrid.occupied",
                           ("boids_env.world.occupancy:OccupancyGrid.occupied",)),
    "scene.within": Twin(_SCENE + "within", (_SCENE + "within",)),
    "scene.box_within": Twin(_SCENE + "within", (_SCENE + "_box_within",)),
    "scene.segments_blocked": Twin(_SCENE + "blocked", (_SCENE + "_capsules_blocked",)),
    "scene.raycast": Twin(_SCENE + "raycast", (_SCENE + "raycast",)),
    "scene.ray_circles_nearest": Twin(_OBSERVER, ("boids_env.observations.sensing:_ranges_along",)),
    # boids_env._compiled.sensing
    "sensing.static_block": Twin(_OBSERVER, ("boids_env.observations.sensing:static_block",)),
    "sensing.noisy_observations": Twin(_OBSERVER, ("boids_env.observations:Observer._noise",
                                                   _OBSERVER)),
    "sensing.in_sight_ahead": Twin("boids_env.world.route:sense_route",
                                   ("boids_env.world.route:_in_sight_ahead",)),
    # boids_env._compiled.safety
    "safety.safety_filter": Twin("boids_env.world.safety:filter_commands",
                                 ("boids_env.world.safety:barrier_constraints",
                                  "boids_env.world.safety:nearest_allowed")),
}
"""Every kernel of :mod:`boids_env._compiled` (``module.name`` in the package; callers
reach it as ``compiled.name``) and its numpy twin. The policies' kernels have their table
beside them (:data:`boids_env.policies.kernels.KERNELS`)."""


def resolve(path: str) -> Any:
    """The object a table names: ``"package.module:Class.attribute"`` imported and looked
    up (``AttributeError`` or ``ImportError`` where it is gone)."""
    module, _, qualname = path.partition(":")
    found: Any = importlib.import_module(module)
    for part in qualname.split("."):
        found = getattr(found, part)
    return found
