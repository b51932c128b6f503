"""The study's case on the Robotarium: the testbed's limits, the flock scaled to its
3.2 m × 2 m floor, the env config that runs the same case here first and the Reynolds
parameters both use.

The testbed's figures are its simulator's (``rps/robotarium_abc.py``, robotarium_python_simulator
2.x): 0.033 s steps, 0.2 m/s, wheels of 16 mm radius 0.11 m apart (so |v| + 0.055·|ω| ≤ 0.2;
3.64 rad/s turning in place), collision discs of 0.135 m centred 0.025 m ahead of the axle,
at most 20 robots, 900 s.

Scaling: lengths by 0.6 (the start grid's 0.5 m cells become 0.3 m, the least that the
testbed's own drive to the initial conditions reaches reliably: its barrier keeps 0.25 m
between points 5 cm ahead), speeds by 0.3 (the followers' 0.5 m/s become 0.15 m/s, three
quarters of the GRITSbot's top speed, as the Robotarium's examples leave for turning), so
time runs 2× slower and accelerations scale by 0.15 (``max_force`` 0.23 N → 0.0345 N). The
leader keeps the study's ratio: 1.1 × the followers' top speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.checks import integer, number, set_field
from boids_env.config import EnvConfig
from boids_env.policies.reynolds_params import ReynoldsParams

TIME_STEP = 0.033
"""The Robotarium's step (s)."""
MAX_LINEAR = 0.2
"""A GRITSbot's top speed (m/s)."""
HALF_BASE = 0.055
"""Half the wheel base (m): a wheel's speed is v ± 0.055·ω."""
MAX_ROBOTS = 20
"""Robots on the testbed at most."""
MAX_SECONDS = 900.0
"""An experiment's limit (s)."""
ENV_MARGIN = 0.08
"""The env's safety filter's margin (m), its stand-in for the script's barrier certificate:
0.08 keeps collision centres beyond the testbed's 0.135 m in the 7/13/19 cases."""
STUDY_GROUPS = (7, 13, 19)
"""The study's group sizes, leader included: all fit the testbed."""
LENGTH_SCALE = 0.6
SPEED_SCALE = 0.3
STUDY_FORCE = 0.23
STUDY_MASS = 0.18


@dataclass(frozen=True)
class RobotariumCase:
    """The flock on the testbed: what ``boids export robotarium`` writes into the script."""

    robots: int = 13
    """Robots, the leader included (2..20; the study's 7, 13, 19 all fit)."""
    follower_speed: float = SPEED_SCALE * 0.5
    """Followers' top speed (m/s): the study's 0.5 scaled by 0.3 (0.15)."""
    leader_speed: float | None = None
    """The leader's speed (m/s); None: 1.1 × ``follower_speed``, the study's ratio."""
    seconds: float | None = None
    """Length of the experiment (s); None: the start-up, the leader's path at 1.3 × its
    nominal time and 10 s to settle."""
    safety_radius: float = 0.13
    """rps barrier certificate's ``safety_radius`` (m) between the points
    ``projection_distance`` ahead (plus 2 × that): 0.17 m between collision centres."""
    projection_distance: float = 0.03
    """rps barrier certificate's ``projection_distance`` (m)."""
    barrier_gain: float = 100.0
    """rps barrier certificate's ``barrier_gain``."""
    wheel_margin: float = 0.95
    """The commands are scaled so that no wheel exceeds this share of its top speed."""

    def __post_init__(self) -> None:
        set_field(self, "robots", integer("robots", self.robots, 2, MAX_ROBOTS))
        set_field(self, "follower_speed", number(
            "follower_speed", self.follower_speed, 0.0, 0.9 * MAX_LINEAR, lo_open=True,
            unit="m/s"))
        if self.leader_speed is not None:
            set_field(self, "leader_speed", number(
                "leader_speed", self.leader_speed, 0.0, 0.9 * MAX_LINEAR, lo_open=True,
                unit="m/s"))
        if self.seconds is not None:
            set_field(self, "seconds", number(
                "seconds", self.seconds, 0.0, MAX_SECONDS - 60.0, lo_open=True, unit="s"))
        for name, lo, hi in (("safety_radius", 0.075, 0.3), ("projection_distance", 0.01, 0.1),
                             ("barrier_gain", 1.0, 1000.0), ("wheel_margin", 0.5, 1.0)):
            set_field(self, name, number(name, getattr(self, name), lo, hi))

    @property
    def leader(self) -> float:
        """The leader's speed (m/s)."""
        return self.leader_speed if self.leader_speed is not None else round(
            1.1 * self.follower_speed, 9)

    def env_config(self, **fields: Any) -> EnvConfig:
        """The same case in our env: GRITSbots in the ``robotarium`` scene at the testbed's
        step, the leader at :attr:`leader`, plus ``fields``."""
        params = self.reynolds()
        return EnvConfig.from_kwargs(**{
            "scene": "robotarium", "robot": "gritsbot", "robots": self.robots,
            "dt": TIME_STEP, "leader_speed": self.leader, "horizon": params.horizon,
            "init_jitter": 0.0, "safety_filter": True, "safety_margin": ENV_MARGIN, **fields})

    def reynolds(self) -> ReynoldsParams:
        """The study's (paper) Reynolds parameters scaled to the testbed."""
        time_scale = LENGTH_SCALE / (self.follower_speed / 0.5)
        return ReynoldsParams(
            horizon=round(1.0 * LENGTH_SCALE, 9),
            desired_separation=round(0.7 * LENGTH_SCALE, 9),
            max_speed=self.follower_speed,
            max_force=round(STUDY_FORCE * LENGTH_SCALE / time_scale ** 2, 9),
            mass=STUDY_MASS, obstacle_avoidance=False)

    def startup_steps(self, config: EnvConfig) -> int:
        """Steps the followers are held still (the study's 2 s start-up)."""
        return math.ceil(config.scenario.startup_time / TIME_STEP - 1e-9)

    def iterations(self, config: EnvConfig) -> int:
        """Steps of the experiment (:attr:`seconds`, or its default)."""
        if self.seconds is not None:
            return math.ceil(self.seconds / TIME_STEP)
        path = np.array(((0.0, 0.0), *waypoints(config))) + 0.0
        path[0] = config.scenario.start
        length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        seconds = config.scenario.startup_time + 1.3 * length / self.leader + 10.0
        return math.ceil(min(seconds, MAX_SECONDS - 60.0) / TIME_STEP)


def waypoints(config: EnvConfig) -> tuple[tuple[float, float], ...]:
    """The leader's targets (m) in the env of ``config``."""
    return tuple((float(x), float(y)) for x, y in config.scenario.waypoints)


def initial_poses(config: EnvConfig) -> npt.NDArray[np.float64]:
    """(3, N) start poses (x, y, θ) as the env places the robots (no jitter), all facing the
    start heading."""
    from boids_env.world.scenario import initial_positions

    heading = math.radians(config.scenario.start_heading or 0.0)
    positions = initial_positions(config.scenario, None, heading)
    return np.vstack([positions.T, np.full(len(positions), heading)])
