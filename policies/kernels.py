"""The policies' compiled kernels (:mod:`boids_env.policies._compiled`), switched on and off
with the core's (:mod:`boids_env.kernels`): loaded once the core's are, off without numba,
with ``BOIDS_KERNELS=0`` or inside :func:`boids_env.kernels.reference`. The same bits as the
numpy code they replace (:data:`KERNELS`), which runs instead whenever they are off."""

from __future__ import annotations

import warnings
from types import ModuleType

from boids_env import kernels
from boids_env.kernels import Twin

_module: ModuleType | None = None
_failed = False


def compiled() -> ModuleType | None:
    """The policies' kernel module, or None while the numpy reference runs (the core's
    :func:`boids_env.kernels.compiled` is None: not loaded yet, no numba, switched off).
    Each call counts towards the core's ``LOAD_AFTER``, as a core caller's does."""
    global _module, _failed
    if kernels.compiled() is None or _failed:
        return None
    if _module is None:
        try:
            from boids_env.policies import _compiled
        except (ImportError, RuntimeError, OSError) as err:  # as the core's load: numpy runs
            warnings.warn(f"the policies' compiled kernels could not load ({err}); the numpy "
                          f"reference runs instead (same results, slower)", RuntimeWarning,
                          stacklevel=2)
            _failed = True
            return None
        _module = _compiled
    return _module


_ACTOR = "boids_env.policies.mlp_actor:MLPActor.act_batch"
_LAYER = "boids_env.policies.exact:ExactLinear.__call__"
KERNELS: dict[str, Twin] = {
    "reynolds_forces": Twin("boids_env.policies.reynolds:ReynoldsPolicy.act_batch",
                            ("boids_env.policies.reynolds:reynolds_forces",)),
    "exact_slices": Twin(_ACTOR, (_LAYER,)),
    "exact_combine": Twin(_ACTOR, (_LAYER, "boids_env.policies.exact:tanh",
                                   "boids_env.policies.exact:relu")),
    "exact_combine_slices": Twin(_ACTOR, (_LAYER, "boids_env.policies.exact:tanh")),
    "clip_actions": Twin(_ACTOR, (_ACTOR,)),
}
"""Every kernel of :mod:`boids_env.policies._compiled` (by name; callers reach it as
``compiled.name``) and its numpy twin (:class:`~boids_env.kernels.Twin`), as the core's
:data:`boids_env.kernels.KERNELS`."""
