"""Uniform random velocity commands: the trivial, seeded baseline."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from boids_env.policies.base import BatchPolicy


class RandomPolicy(BatchPolicy):
    """Commands a uniformly random velocity in the square ±max_speed per follower and step."""

    def __init__(self, max_speed: float = 0.5, seed: int | None = None) -> None:
        if not max_speed > 0:
            raise ValueError(f"max_speed must be > 0 m/s, got {max_speed!r}")
        self.max_speed = float(max_speed)
        self._rng = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def act_batch(self, obs: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
        return self._rng.uniform(-self.max_speed, self.max_speed, (len(obs), 2)).astype(
            np.float32)
