"""What a robot model (:mod:`boids_env.world.robots`) sees of the config and of the world, as
Protocols: both import that module, so it cannot import them.

The config's fields are read-only properties here, as the frozen dataclass's are (a Protocol
attribute would promise a settable one).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
import pymunk
import pymunk.batch as batch

FloatArray = npt.NDArray[np.float64]


class WorldConfig(Protocol):
    """The robot fields of :class:`boids_env.config.WorldConfig` a model reads."""

    @property
    def robot_radius(self) -> float: ...
    @property
    def robot_mass(self) -> float: ...
    @property
    def drive_force(self) -> float: ...
    @property
    def dt(self) -> float: ...
    @property
    def substeps(self) -> int: ...
    @property
    def drive(self) -> str: ...
    @property
    def max_turn_rate(self) -> float | None: ...
    @property
    def max_turn_acceleration(self) -> float | None: ...
    @property
    def heading_gain(self) -> float | None: ...
    @property
    def velocity_law(self) -> str: ...


class World(Protocol):
    """What a model drives of :class:`boids_env.world.space.World`: its space, robot count,
    velocities, batch buffers and substeps."""

    space: pymunk.Space
    n: int
    velocities: FloatArray
    _write_velocities: FloatArray
    _schedule: list[float]

    @property
    def heading_vectors(self) -> FloatArray | None: ...  # read only, as the world's is

    def _read_buffer(self) -> batch.Buffer: ...

    def _write_buffer(self) -> batch.Buffer: ...

    def _people_velocities(self, w: FloatArray) -> None: ...

    def _run_substeps(self, before: Callable[[Any, float], None] | None = None) -> None: ...
