"""The policies' compiled kernels (:mod:`boids_env.policies._compiled`), switched on and off
with the core's (:mod:`boids_env.kernels`): loaded once the core's are, off without numba,
with ``BOIDS_KERNELS=0`` or inside :func:`boids_env.kernels.reference`. The same bits as the
numpy code they replace, which runs instead whenever they are off."""

from __future__ import annotations

import warnings
from types import ModuleType

from boids_env import kernels

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
