"""boids-env: the leader-following boids flock of Akgun's ROS study as a PettingZoo env.

The environment lives in :mod:`boids_env.environment` (``BoidsEnv``) and
:mod:`boids_env.boids_leader_v0` (PettingZoo's module convention); the layers above it install
as :mod:`boids_env.policies`, :mod:`boids_env.eval`, :mod:`boids_env.train` and
:mod:`boids_env.bench`.
"""

from boids_env.config import (
    PRESETS,
    EnvConfig,
    MetricsConfig,
    ObservationConfig,
    ReynoldsParams,
    ScenarioConfig,
    WorldConfig,
    reynolds_params,
)
from boids_env.environment import BoidsEnv, env, parallel_env, raw_env

__version__ = "0.1.0"

__all__ = [
    "PRESETS",
    "BoidsEnv",
    "EnvConfig",
    "MetricsConfig",
    "ObservationConfig",
    "ReynoldsParams",
    "ScenarioConfig",
    "WorldConfig",
    "env",
    "parallel_env",
    "raw_env",
    "reynolds_params",
]
