"""Policies for the followers: one protocol, the study's Reynolds controller, baselines."""

from boids_env.policies.base import BatchPolicy, Policy
from boids_env.policies.random_policy import RandomPolicy
from boids_env.policies.reynolds import ReynoldsPolicy
from boids_env.policies.reynolds_params import PRESETS, ReynoldsParams, reynolds_params

__all__ = ["PRESETS", "BatchPolicy", "Policy", "RandomPolicy", "ReynoldsParams", "ReynoldsPolicy",
           "reynolds_params"]
