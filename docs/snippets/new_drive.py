"""A new robot drive: a holonomic robot whose motors ignore commands below a dead band.

In the repository this class would sit in ``boids_env/world/robots.py`` beside
``Holonomic`` (with its ``DRIVES`` entry), a preset in ``ROBOT_PRESETS`` if a real robot has it,
and a test: every other part of the code asks the drive, never its name.
"""

import numpy as np

from boids_env import BoidsEnv
from boids_env.world.robots import DRIVES, Holonomic, register_drive

DEAD_BAND = 0.02
"""Commands slower than this (m/s) do not move the motors."""


class DeadBand(Holonomic):
    """The study's omnidirectional disc, with a dead band on the commanded speed."""

    name = "dead_band"

    @classmethod
    def check_config(cls, config):
        if config.max_speed <= DEAD_BAND:
            raise ValueError(f"drive='dead_band' needs max_speed above {DEAD_BAND} m/s, got "
                             f"{config.max_speed}")

    def command(self, world, commanded, executed, native):
        sent, _, run = super().command(world, commanded, executed, native)
        speed = np.sqrt(run[:, 0] * run[:, 0] + run[:, 1] * run[:, 1])
        return sent, None, np.where((speed < DEAD_BAND)[:, None], 0.0, run)


if DeadBand.name not in DRIVES:  # the snippet may run twice in one process
    register_drive(DeadBand)

env = BoidsEnv(robots=4, drive="dead_band", max_cycles=40)
env.reset(seed=0)
for _ in range(40):
    env.step({agent: np.array([0.01, 0.0]) for agent in env.agents})  # inside the band
print(f"after 4 s of 1 cm/s commands the followers moved "
      f"{np.abs(env.snapshot().velocities[1:]).max():.3f} m/s at most")
