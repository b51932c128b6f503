"""Stable-Baselines3 training of learned followers (parameter sharing across followers)."""
