"""Uniform random velocity commands: the trivial, seeded baseline."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from boids_env.checks import number
from boids_env.config import MAX_SPEED_RANGE
from boids_env.policies.base import BatchPolicy


class RandomPolicy(BatchPolicy):
    """Commands a uniformly random velocity in the square ±max_speed per follower and step."""

    def __init__(self, max_speed: float = 0.5, seed: int | None = None) -> None:
        self.max_speed = number("max_speed", max_speed, *MAX_SPEED_RANGE, lo_open=True,
                                unit="m/s")
        self._rng = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def act_batch(self, obs: npt.NDArray[np.floating]) -> npt.NDArray[np.float32]:
        return self._rng.uniform(-self.max_speed, self.max_speed, (len(obs), 2)).astype(
            np.float32)
