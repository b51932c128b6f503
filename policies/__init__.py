"""Policies for the followers: one protocol, the study's Reynolds controller, baselines."""

from boids_env.policies.base import BatchPolicy, Policy
from boids_env.policies.random_policy import RandomPolicy
from boids_env.policies.reynolds import ReynoldsPolicy

__all__ = ["BatchPolicy", "Policy", "RandomPolicy", "ReynoldsPolicy"]
