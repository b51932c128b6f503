"""Policies for the followers: one protocol, the study's Reynolds controller, baselines."""

from policies.base import BatchPolicy, Policy, SB3Predictor
from policies.random_policy import RandomPolicy
from policies.reynolds import ReynoldsPolicy

__all__ = ["BatchPolicy", "Policy", "RandomPolicy", "ReynoldsPolicy", "SB3Predictor"]
