"""Turns a policy spec (``reynolds``, ``random``, ``model.zip``, ``module:object``) into a
:class:`~policies.base.Policy`."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from policies.base import Policy
from policies.random_policy import RandomPolicy
from policies.reynolds import ReynoldsPolicy

BUILTIN = ("reynolds", "random", "learned")
LEARNED_MODEL = Path(__file__).parent / "models" / "ppo_followers.zip"
"""The shipped PPO follower policy (train/recipes/ppo_followers.toml); needs the train extra."""


def load_policy(spec: str, *, preset: str = "paper", max_speed: float = 0.5,
                **reynolds_overrides: Any) -> Policy:
    """Builds the policy named by ``spec``.

    Args:
        spec: ``reynolds`` (the study's controller), ``random``, ``learned`` (the shipped PPO
            followers), a path to a saved SB3 model
            (``.zip``), or ``module:object`` naming a Policy instance, class or factory.
        preset: Reynolds parameter preset (``paper`` or ``boids_ros``).
        max_speed: the random policy's speed range (m/s).
        reynolds_overrides: Reynolds parameters (e.g. ``leader_weight=1.1``).
    """
    if spec == "reynolds":
        return ReynoldsPolicy(preset, **reynolds_overrides)
    if spec == "random":
        return RandomPolicy(max_speed)
    if spec == "learned":
        spec = str(LEARNED_MODEL)
    if spec.endswith(".zip"):
        if not Path(spec).is_file():
            raise FileNotFoundError(f"policy model file not found: {spec}")
        try:
            from policies.sb3_policy import SB3Policy
        except ImportError as exc:
            raise ImportError("loading an SB3 model needs: pip install 'boids-env[train]'"
                              ) from exc
        return SB3Policy.load(spec)
    if ":" in spec:
        module_name, _, attr = spec.partition(":")
        try:
            obj = getattr(importlib.import_module(module_name), attr)
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"cannot import policy {spec!r}: {exc}") from exc
        policy = obj() if callable(obj) and not isinstance(obj, Policy) else obj
        if not isinstance(policy, Policy):
            raise TypeError(f"{spec!r} is not a Policy (needs reset(seed) and act(obs))")
        return policy
    raise ValueError(f"policy must be one of {BUILTIN}, a .zip SB3 model or module:object, "
                     f"got {spec!r}")
