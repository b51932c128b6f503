"""What the physics must never allow, checked as it runs: no body deep inside static geometry
(a wall, an obstacle, an occupied map cell) and no body faster than what can move it.

Contacts keep a body out of walls and its drive keeps it within its top speed, but a body
pushed by something much heavier (a 70 kg person on a 0.18 kg robot) could be squeezed into
or through a wall, and a body that falls behind where the pedestrian model puts it could be
driven to catch up at any speed. The people's bodies are limited to their walking speed and
the crowd walks around the robots (:mod:`~boids_env.world.people`), so neither happens; this
guard proves it on every step of a world with people in it, and says so at once if the
physics ever allows it (a :class:`PhysicsWarning` naming the body, the step and the figure,
once per world, and :attr:`PhysicsGuard.counts` for every violation).
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]

DEPTH_SHARE = 0.5
"""A body whose centre comes within this share of its radius of static geometry is inside
it (a touching body's centre is a radius away; contacts let it sink millimetres)."""
SPEED_SLACK = 1.05
"""A body is too fast beyond this times its limit (a drive tracking its command overshoots
by a fraction of a percent)."""
SPEED_MARGIN = 0.01
"""... plus this (m/s)."""


class PhysicsWarning(UserWarning):
    """The physics let a body into a wall or beyond its speed (a bug: please report it)."""


class PhysicsGuard:
    """Checks one world's bodies after every step.

    Args:
        scene: the world's static geometry.
        robot_radius: the robots' radius (m).
        person_radius: the people's radius (m).
        robot_speed: the robots' limit (m/s): their top speed, or a walking person's where
            people can push them.
        person_speed: the fastest any person walks (m/s).
    """

    def __init__(self, scene: Scene, robot_radius: float, person_radius: float,
                 robot_speed: float, person_speed: float) -> None:
        self.scene = scene
        self.radii = (robot_radius, person_radius)
        self.limits = (robot_speed * SPEED_SLACK + SPEED_MARGIN,
                       person_speed * SPEED_SLACK + SPEED_MARGIN)
        self.counts = {"robots_in_walls": 0, "people_in_walls": 0, "robots_too_fast": 0,
                       "people_too_fast": 0}
        """Violations so far, by kind (body-steps)."""
        self._warned = False

    def check(self, step: int, robots: FloatArray, robot_velocities: FloatArray,
              people: FloatArray, people_velocities: FloatArray) -> None:
        """Counts (and warns once of) the bodies in walls or too fast after step ``step``:
        ``robots`` and ``people`` (K, 2) positions (m), their velocities (m/s)."""
        for kind, points, velocities, radius, limit in (
                ("robots", robots, robot_velocities, self.radii[0], self.limits[0]),
                ("people", people, people_velocities, self.radii[1], self.limits[1])):
            if not len(points):
                continue
            deep = np.flatnonzero(self.scene.within(points, DEPTH_SHARE * radius))
            speed = np.sqrt(velocities[:, 0] * velocities[:, 0]
                            + velocities[:, 1] * velocities[:, 1])
            fast = np.flatnonzero(speed > limit)
            self.counts[f"{kind}_in_walls"] += len(deep)
            self.counts[f"{kind}_too_fast"] += len(fast)
            if (len(deep) or len(fast)) and not self._warned:
                self._warned = True
                what = (f"{kind[:-1]} {deep[0]} at ({points[deep[0]][0]:.3f}, "
                        f"{points[deep[0]][1]:.3f}) inside static geometry" if len(deep) else
                        f"{kind[:-1]} {fast[0]} at {speed[fast[0]]:.3f} m/s (limit "
                        f"{limit:.3f})")
                warnings.warn(f"physics violation at step {step}: {what}; the episode goes on "
                              f"(counts in the world's guard); please report it",
                              PhysicsWarning, stacklevel=4)
