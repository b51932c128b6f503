"""The stand-in ``rps.robotarium.Robotarium``: the 2.x API and the testbed's rejection rules.

Constants as ``rps/robotarium_abc.py`` states them. Every step is checked before the robots
move (as the real ``_validate``): a robot's centre outside ``BOUNDARIES``, two collision
centres (``COLLISION_OFFSET`` ahead of each robot's axle) within ``COLLISION_DIAMETER``, a
wheel speed beyond ``MAX_WHEEL_VELOCITY`` (the real simulator clips and warns; the stand-in
rejects), an experiment beyond ``MAX_EXPERIMENT_SECONDS``. Also refused at once: more than
``MAX_TESTBED_ROBOTS``, initial conditions outside the testbed or too close, calls out of
order. Poses start at the initial conditions (the real testbed drives the robots there).
The dynamics are the unicycle's, integrated as the real ``step`` does.

``debug()`` (``call_at_scripts_end()`` in rps 1.x) writes the report, a JSON object, to the
file named by ``$STAND_IN_RPS_REPORT`` (when set) and prints the verdict.
"""

import json
import math
import os

import numpy as np

TIME_STEP = 0.033
MAX_LINEAR_VELOCITY = 0.2
ROBOT_DIAMETER = 0.11
WHEEL_RADIUS = 0.016
BASE_LENGTH = 0.11
COLLISION_DIAMETER = 0.135
COLLISION_OFFSET = 0.025
BOUNDARIES = np.array([-1.6, 1.6, -1.0, 1.0])
MAX_WHEEL_VELOCITY = MAX_LINEAR_VELOCITY / WHEEL_RADIUS
MAX_ANGULAR_VELOCITY = 2.0 * (WHEEL_RADIUS / ROBOT_DIAMETER) * MAX_WHEEL_VELOCITY
MAX_TESTBED_ROBOTS = 20
MAX_EXPERIMENT_SECONDS = 900.0
WHEEL_TOLERANCE = 1e-9
"""Relative slack on the wheel limit (rounding of a command scaled to it exactly)."""


class Rejected(RuntimeError):
    """A script the testbed refuses before it runs (bad arguments, calls out of order)."""


def collision_centres(poses):
    """(2, N) centres of the robots' collision discs: ``COLLISION_OFFSET`` ahead."""
    return poses[:2] + COLLISION_OFFSET * np.vstack([np.cos(poses[2]), np.sin(poses[2])])


def closest_pair(poses):
    """Smallest distance (m) between two collision centres (inf for one robot)."""
    c = collision_centres(poses).T
    if len(c) < 2:
        return math.inf
    d = np.sqrt(((c[:, None, :] - c[None, :, :]) ** 2).sum(axis=2))
    return float(d[np.triu_indices(len(c), 1)].min())


def wheel_speeds(dxu):
    """(2, N) wheel angular speeds (rad/s) of unicycle commands (v, ω), as rps's."""
    return np.vstack([(2 * dxu[0] - BASE_LENGTH * dxu[1]) / (2 * WHEEL_RADIUS),
                      (2 * dxu[0] + BASE_LENGTH * dxu[1]) / (2 * WHEEL_RADIUS)])


class Robotarium:
    """``Robotarium(number_of_robots=N, show_figure=..., initial_conditions=3xN,
    sim_in_real_time=...)``; the other keywords of rps 2.x are taken and ignored."""

    TIME_STEP = TIME_STEP
    MAX_LINEAR_VELOCITY = MAX_LINEAR_VELOCITY
    MAX_ANGULAR_VELOCITY = MAX_ANGULAR_VELOCITY
    ROBOT_DIAMETER = ROBOT_DIAMETER
    COLLISION_DIAMETER = COLLISION_DIAMETER
    BOUNDARIES = BOUNDARIES

    def __init__(self, **kwargs):
        n = kwargs.get("number_of_robots", -1)
        if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_TESTBED_ROBOTS:
            raise Rejected(f"number_of_robots must be an int in 1..{MAX_TESTBED_ROBOTS} (the "
                           f"testbed's robots), got {n!r}")
        for name in ("show_figure", "sim_in_real_time"):
            if not isinstance(kwargs.get(name, False), bool):
                raise Rejected(f"{name} must be a bool, got {kwargs[name]!r}")
        x0 = kwargs.get("initial_conditions", np.array([]))
        if not isinstance(x0, np.ndarray) or x0.shape != (3, n) or not np.all(np.isfinite(x0)):
            raise Rejected(f"initial_conditions must be a finite 3 x {n} ndarray")
        b = BOUNDARIES
        if np.any((x0[0] < b[0]) | (x0[0] > b[1]) | (x0[1] < b[2]) | (x0[1] > b[3])):
            raise Rejected("initial_conditions: a robot outside the testbed")
        if closest_pair(x0) <= COLLISION_DIAMETER:
            raise Rejected("initial_conditions: two robots within the collision diameter")
        self.number_of_robots = n
        self._poses = np.array(x0, dtype=float)
        self._velocities = np.zeros((2, n))
        self._polled = False
        self._iterations = 0
        self._errors = {}
        self._min_distance = closest_pair(self._poses)
        self._max_wheel = 0.0
        self._max_linear = 0.0
        self._max_angular = 0.0
        self._extent = np.abs(self._poses[:2]).max(axis=1)
        self.finished = False

    def get_poses(self):
        if self._polled:
            raise Rejected("get_poses() may be called once per step()")
        self._polled = True
        return self._poses.copy()

    def set_velocities(self, ids, velocities):
        velocities = np.asarray(velocities, dtype=float)
        ids = np.asarray(ids)
        if velocities.ndim != 2 or velocities.shape != (2, ids.size):
            raise Rejected(f"set_velocities: velocities must be 2 x {ids.size}, got "
                           f"{velocities.shape}")
        if not np.all(np.isfinite(velocities)):
            raise Rejected("set_velocities: a velocity that is not finite")
        self._velocities[:, ids] = velocities

    def _count(self, name):
        self._errors[name] = self._errors.get(name, 0) + 1

    def step(self):
        if not self._polled:
            raise Rejected("call get_poses() before step()")
        self._polled = False
        p, b = self._poses, BOUNDARIES
        if np.any((p[0] < b[0]) | (p[0] > b[1]) | (p[1] < b[2]) | (p[1] > b[3])):
            self._count("robots_outside_boundaries")
        closest = closest_pair(p)
        self._min_distance = min(self._min_distance, closest)
        if closest <= COLLISION_DIAMETER:
            self._count("robots_too_close")
        wheels = float(np.abs(wheel_speeds(self._velocities)).max(initial=0.0))
        self._max_wheel = max(self._max_wheel, wheels)
        self._max_linear = max(self._max_linear, float(np.abs(self._velocities[0]).max()))
        self._max_angular = max(self._max_angular, float(np.abs(self._velocities[1]).max()))
        if wheels > MAX_WHEEL_VELOCITY * (1 + WHEEL_TOLERANCE):
            self._count("exceeded_actuator_limits")
        self._iterations += 1
        if self._iterations * TIME_STEP > MAX_EXPERIMENT_SECONDS:
            self._count("over_time_limit")
        v, w = self._velocities
        p[0] += TIME_STEP * v * np.cos(p[2])
        p[1] += TIME_STEP * v * np.sin(p[2])
        p[2] = np.arctan2(np.sin(p[2] + TIME_STEP * w), np.cos(p[2] + TIME_STEP * w))
        self._extent = np.maximum(self._extent, np.abs(p[:2]).max(axis=1))

    def report(self):
        """What the run did: iterations, the rejection counts, the closest approach, the
        largest commands and how far robots went."""
        return {"robots": self.number_of_robots, "iterations": self._iterations,
                "seconds": self._iterations * TIME_STEP, "errors": dict(self._errors),
                "rejected": bool(self._errors), "min_distance": self._min_distance,
                "max_wheel_speed": self._max_wheel, "max_linear": self._max_linear,
                "max_angular": self._max_angular,
                "max_abs_x": float(self._extent[0]), "max_abs_y": float(self._extent[1])}

    def debug(self):
        self.finished = True
        report = self.report()
        path = os.environ.get("STAND_IN_RPS_REPORT")
        if path:
            with open(path, "w") as f:
                json.dump(report, f)
        if report["rejected"]:
            print(f"Errors detected, your script will NOT run on the Robotarium! "
                  f"{report['errors']}")
        else:
            print("No errors in your simulation! Your script will run on the Robotarium!")

    call_at_scripts_end = debug
