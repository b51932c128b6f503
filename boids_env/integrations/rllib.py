"""The env registered for RLlib (``pip install -e '.[rllib]'``, which is ``ray[rllib]``:
the ``ray`` extra alone has no RLlib, ``No module named 'tree'``).

``register(name, **fields)`` registers an env creator under ``name`` with
``ray.tune.registry.register_env``: RLlib's ``ParallelPettingZooEnv`` over a :class:`BoidsEnv`
with ``fields`` (env fields by flat name), updated by the ``env_config`` RLlib passes. Followers
are interchangeable, so they usually share one policy: ``config.multi_agent(**shared_policy())``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from boids_env.environment import BoidsEnv
from boids_env.integrations import missing_extra

DEFAULT_NAME = "boids_leader_v0"
"""The name :func:`register` uses unless told another (PettingZoo's module name)."""

POLICY = "follower"
"""The one module every follower maps to in :func:`shared_policy`."""


def make_env(env_config: Mapping[str, Any] | None = None, **fields: Any) -> Any:
    """RLlib's ``ParallelPettingZooEnv`` over a :class:`BoidsEnv` with ``fields`` updated by
    ``env_config``; RLlib's own keys of an ``EnvContext`` (worker index ...) are not in it."""
    try:
        from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
    except ImportError as exc:
        raise missing_extra("rllib", "rllib", exc) from exc
    return ParallelPettingZooEnv(BoidsEnv(**{**fields, **dict(env_config or {})}))


def register(name: str = DEFAULT_NAME, **fields: Any) -> str:
    """Register the env for RLlib under ``name`` (then ``config.environment(name)``); ``fields``
    are env fields by flat name, the defaults of every env made, which an algorithm's
    ``env_config`` updates. A bad field fails here, not in a remote worker. Returns ``name``."""
    if not isinstance(name, str) or not name:
        raise TypeError(f"name must be a non-empty str, got {name!r}")
    BoidsEnv(**fields)
    try:
        import ray.rllib  # noqa: F401  (ray without its rllib extra has no RLlib)
        from ray.tune.registry import register_env
    except ImportError as exc:
        raise missing_extra("rllib", "rllib", exc) from exc
    register_env(name, _Creator(fields))
    return name


class _Creator:
    """The env creator :func:`register` gives RLlib: picklable (sent to workers), unlike a
    closure in some pickling modes."""

    def __init__(self, fields: Mapping[str, Any]) -> None:
        self.fields = dict(fields)

    def __call__(self, env_config: Mapping[str, Any] | None = None) -> Any:
        return make_env(env_config, **self.fields)


def map_to_shared_policy(agent_id: str, *args: Any, **kwargs: Any) -> str:
    """RLlib's ``policy_mapping_fn``: every follower acts with the one module :data:`POLICY`."""
    return POLICY


def shared_policy() -> dict[str, Any]:
    """The keyword arguments of ``AlgorithmConfig.multi_agent`` for parameter sharing."""
    return {"policies": {POLICY}, "policy_mapping_fn": map_to_shared_policy}


__all__ = ["DEFAULT_NAME", "POLICY", "make_env", "map_to_shared_policy", "register",
           "shared_policy"]
