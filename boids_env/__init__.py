"""boids-env: the leader-following boids flock of Akgun's ROS study as a PettingZoo env.

The environment lives in :mod:`boids_env.environment` (``BoidsEnv``) and
:mod:`boids_env.boids_leader_v0` (PettingZoo's module convention); the layers above it install
as :mod:`boids_env.policies`, :mod:`boids_env.eval`, :mod:`boids_env.train` and
:mod:`boids_env.bench`.

The names below are imported on first use (PEP 562), not with the package: every module of the
``boids`` command lives under this package, so importing it is the first thing the command
does, before it can catch a Ctrl-C; the env's imports (numpy, scipy, pymunk: about 0.6 s) now
run inside the command, which answers a Ctrl-C with one line instead of a traceback.

Importing the package registers the Gymnasium id ``boids_env/SingleFollower-v0``
(:class:`boids_env.single.SingleFollowerEnv`) by its entry-point string, so ``gym.make`` and
``gym.make_vec`` find it: at once if gymnasium is imported already, else as soon as it is
(importing gymnasium and numpy here would undo the lazy imports above). The glue
for other libraries (SuperSuit + SB3, RLlib, BenchMARL) is in :mod:`boids_env.integrations`,
imported only when asked.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from boids_env.config import (
        EnvConfig,
        MetricsConfig,
        ObservationConfig,
        ScenarioConfig,
        WorldConfig,
    )
    from boids_env.environment import BoidsEnv, env, parallel_env, raw_env

__version__ = "0.1.0"

_EXPORTS = {
    **dict.fromkeys(("EnvConfig", "MetricsConfig", "ObservationConfig", "ScenarioConfig",
                     "WorldConfig"), "boids_env.config"),
    **dict.fromkeys(("BoidsEnv", "env", "parallel_env", "raw_env"), "boids_env.environment"),
}
"""Each public name and the module that defines it."""

__all__ = [
    "BoidsEnv",
    "EnvConfig",
    "MetricsConfig",
    "ObservationConfig",
    "ScenarioConfig",
    "WorldConfig",
    "env",
    "parallel_env",
    "raw_env",
]


GYMNASIUM_IDS = {"boids_env/SingleFollower-v0": "boids_env.single:SingleFollowerEnv"}
"""The Gymnasium ids this package registers on import, and their entry points."""


def _register_gymnasium_ids() -> None:
    import gymnasium

    for env_id, entry_point in GYMNASIUM_IDS.items():
        if env_id not in gymnasium.registry:  # importlib.reload registers once
            gymnasium.register(id=env_id, entry_point=entry_point)


class _RegisterAfterGymnasium(importlib.abc.MetaPathFinder):
    """Registers the ids once gymnasium has been imported, whoever imports it: importing
    gymnasium (and numpy) with the package would run before the ``boids`` command can answer
    a Ctrl-C (see above), and the command never needs the ids. A look-up that imports
    nothing (``importlib.util.find_spec``, as :mod:`boids_env.extras` probes the extras)
    leaves the hook in place: it goes once gymnasium has run."""

    def __init__(self) -> None:
        self._looking = False

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != "gymnasium" or self._looking:
            return None
        self._looking = True  # the look-up below comes back through sys.meta_path
        try:
            spec = importlib.util.find_spec(name)
        finally:
            self._looking = False
        if spec is not None and spec.loader is not None:
            exec_module = spec.loader.exec_module

            def exec_then_register(module: Any) -> None:
                exec_module(module)
                if self in sys.meta_path:
                    sys.meta_path.remove(self)
                _register_gymnasium_ids()

            # wrapping the loader's method on this one loader object is the point
            spec.loader.exec_module = exec_then_register  # type: ignore[method-assign]
        return spec


if "gymnasium" in sys.modules:
    _register_gymnasium_ids()
elif not any(isinstance(f, _RegisterAfterGymnasium) for f in sys.meta_path):
    sys.meta_path.insert(0, _RegisterAfterGymnasium())


def __getattr__(name: str) -> Any:
    """A public name, imported from its module on first use (then cached here); a submodule
    (``boids_env.metrics``) is imported too, as an eager package import used to make it."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):
        try:
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
