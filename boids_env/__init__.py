"""boids-env: the leader-following boids flock of Akgun's ROS study as a PettingZoo env."""

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
from boids_env.env import BoidsEnv, env, parallel_env

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
    "reynolds_params",
]
