"""The numba kernels behind :mod:`boids_env.kernels` (imported on first use, never at
``import boids_env``), one module per concern:

- :mod:`~boids_env._compiled.study`: the study's neighbour search, observation blocks and
  violation flags, the frame rotation, and all of them for K copies in one call;
- :mod:`~boids_env._compiled.grid`: many robots' neighbours on a grid (the KD-tree's bits);
- :mod:`~boids_env._compiled.flags`: the safety flags' nearest robots, the opt-in reward rows;
- :mod:`~boids_env._compiled.motion`: the speed limit, a unicycle's substep;
- :mod:`~boids_env._compiled.scene`: the scene's queries (wall points, clearance, wall
  flags, map cells, sight lines, ray casts);
- :mod:`~boids_env._compiled.sensing`: the static slots' turn, the sensing noise, route
  sensing's sight lines;
- :mod:`~boids_env._compiled.safety`: the safety filter.

The policies' kernels live with the policies (:mod:`boids_env.policies._compiled`). Which
numpy function each kernel pairs with: :data:`boids_env.kernels.KERNELS`.

Each is a loop port of a numpy reference and rounds exactly as it does: no ``fastmath`` (LLVM
then never contracts ``a * b + c`` into one fused multiply-add, which rounds once instead of
twice), the same operations in the same order, ``sqrt`` and the float64 → float32 cast (both
correctly rounded), and no transcendental function (numpy's SIMD ``arctan2`` and the C
library's differ in the last bit: the angles come in from numpy). ``cache=True``: compiled
once per machine into each module's ``__pycache__``, loaded afterwards.

No kernel calls one of another module: numba's cache checks only the file a cached function
is defined in, so a kernel compiled against another file's kernel would keep running the old
machine code after that file changed. Kernels that call each other share a module.

Callers reach a kernel through this package, the handle :func:`boids_env.kernels.compiled`
returns (``compiled.nearest(...)``), not by importing it: the handle is what keeps numba's
import (half a second) off a short process, an ``import`` inside the caller would cost about
0.3 µs a call against one attribute lookup, and tests count or stub a kernel on it.
"""

from __future__ import annotations

from boids_env._compiled.flags import nearest_other, safety_gap_terms
from boids_env._compiled.grid import RANK_LIMIT, nearest_grid
from boids_env._compiled.motion import clip_speed, unicycle_substep
from boids_env._compiled.safety import safety_filter
from boids_env._compiled.scene import (
    box_within,
    capsule_clearance,
    nearest_points,
    occupied,
    ray_circles_nearest,
    raycast,
    segments_blocked,
    shape_clearance,
    within,
)
from boids_env._compiled.sensing import in_sight_ahead, noisy_observations, static_block
from boids_env._compiled.study import (
    batch_after,
    fill_observations,
    nearest,
    rotated,
    violations,
)

__all__ = ["RANK_LIMIT", "batch_after", "box_within", "capsule_clearance", "clip_speed",
           "fill_observations", "in_sight_ahead", "nearest", "nearest_grid", "nearest_other",
           "nearest_points", "noisy_observations", "occupied", "ray_circles_nearest",
           "raycast", "rotated", "safety_filter", "safety_gap_terms", "segments_blocked",
           "shape_clearance", "static_block", "unicycle_substep", "violations", "within"]
