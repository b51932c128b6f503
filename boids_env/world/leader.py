"""Leader paths: the paper's square and the opt-in ones (circle, figure-eight, waypoints,
random waypoints, a leader driven from outside).

Each is a :class:`~boids_env.world.leader_base.Leader` (the small state machine every leader
is: ``command(t, position)`` and ``finished``); :func:`make_leader` builds the scenario's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from boids_env.vectors import as_velocities, clip_speed, sin_cos
from boids_env.world.leader_base import Leader as Leader
from boids_env.world.scenario import CURVE_SPEED_FACTOR, LEADER_MAX_SPEED, scene_matrix

if TYPE_CHECKING:
    from boids_env.world.scenario import ScenarioConfig
    from boids_env.world.scene import Scene

Vec = npt.NDArray[np.float64]

PAPER_SQUARE = ((0.0, 4.0), (-4.0, 4.0), (-4.0, -4.0), (4.0, -4.0), (4.0, 4.0), (-4.0, 4.0))
"""The study's leader targets (m), driven from (0, 0) one axis at a time."""


class WaypointLeader(Leader):
    """Drives to absolute targets in turn at constant speed; a move ends within ``margin``.

    With ``axis_aligned`` (the paper's square) each move runs along the one axis on which the
    target differs from the previous one and its end is judged along that axis, as the original
    script drove the Sphero; otherwise the leader heads straight at the target.
    """

    def __init__(self, targets: npt.ArrayLike, speed: float, startup_time: float, margin: float,
                 *, axis_aligned: bool, start: npt.ArrayLike = (0.0, 0.0),
                 transform: Vec | None = None, dt: float | None = None,
                 origin: npt.ArrayLike = (0.0, 0.0),
                 pauses: tuple[tuple[float, float], ...] = ()) -> None:
        super().__init__(speed, startup_time, transform, origin, pauses)
        self.dt = dt
        self.targets = np.asarray(targets, dtype=float).reshape(-1, 2)
        self.margin = margin
        self.axis_aligned = axis_aligned
        self.index = 0
        self.start = np.asarray(start, dtype=float)
        previous = np.vstack([self.start, self.targets[:-1]])
        self._axes = np.argmax(np.abs(self.targets - previous), axis=1)
        self._length = float(np.sum(np.linalg.norm(self.targets - previous, axis=1)))

    def _move(self, t: float, position: Vec) -> Vec:
        while self.index < len(self.targets):
            offset = self.targets[self.index] - position
            if self.axis_aligned:
                axis = self._axes[self.index]
                if abs(offset[axis]) > self.margin:
                    out = np.zeros(2)
                    out[axis] = math.copysign(self._speed_for(abs(offset[axis])), offset[axis])
                    return out
            else:
                distance = math.hypot(offset[0], offset[1])
                if distance > self.margin:
                    return offset * (self._speed_for(distance) / distance)
            self.index += 1  # arrived: corners are instantaneous
        self.finished = True
        return np.zeros(2)

    def _speed_for(self, remaining: float) -> float:
        """The path speed, slowed on a move's last step so that a fast leader with a small
        arrival margin lands within the margin instead of overshooting its target forever.
        With the study's numbers (0.55 m/s, 0.1 m margin, 0.1 s) it never slows."""
        if self.dt is None:
            return self.speed
        return min(self.speed, remaining / self.dt)

    def _driving_duration(self) -> float:
        return (self._length - len(self.targets) * self.margin) / self.speed

    def _local_path(self) -> Vec:
        return np.vstack([self.start, self.targets])


class CurveLeader(Leader):
    """Follows a closed curve at constant speed: a reference point moves along the curve by
    arc length and the leader tracks it (feed-forward tangent plus proportional correction)."""

    gain = 2.0
    """Proportional gain (1/s) pulling the leader back onto its reference point."""

    def __init__(self, curve: Callable[[Vec], Vec], speed: float, startup_time: float,
                 laps: int, transform: Vec | None = None,
                 origin: npt.ArrayLike = (0.0, 0.0),
                 pauses: tuple[tuple[float, float], ...] = ()) -> None:
        super().__init__(speed, startup_time, transform, origin, pauses)
        phase = np.linspace(0.0, 2 * math.pi * laps, 4000 * laps + 1)
        self._points = curve(phase)
        seg = np.linalg.norm(np.diff(self._points, axis=0), axis=1)
        self._arc = np.concatenate([[0.0], np.cumsum(seg)])
        # contiguous columns: np.interp copies a strided column on every call (4001 points
        # a lap)
        self._xs = np.ascontiguousarray(self._points[:, 0])
        self._ys = np.ascontiguousarray(self._points[:, 1])

    def _here_and_ahead(self, s: float, ahead: float) -> tuple[Vec, Vec]:
        """The curve's points at arc lengths ``s`` and ``s + ahead`` (each clamped to the
        curve), interpolated as two calls of ``np.interp`` on both lengths (the same
        arithmetic per length as one call each)."""
        end = self._arc[-1]
        at = [min(max(s, 0.0), end), min(max(s + ahead, 0.0), end)]
        x = np.interp(at, self._arc, self._xs)
        y = np.interp(at, self._arc, self._ys)
        return np.array([x[0], y[0]]), np.array([x[1], y[1]])

    def _move(self, t: float, position: Vec) -> Vec:
        s = self.speed * t
        if s >= self._arc[-1]:
            self.finished = True
            return np.zeros(2)
        here, ahead = self._here_and_ahead(s, 0.05)
        step = ahead - here  # its length elementwise: a 1-D norm is a BLAS dot (per-CPU bits)
        tangent = step / max(math.sqrt(step[0] * step[0] + step[1] * step[1]), 1e-12)
        out = self.speed * tangent + self.gain * (here - position)
        return clip_speed(out, CURVE_SPEED_FACTOR * self.speed)

    def _driving_duration(self) -> float:
        return float(self._arc[-1]) / self.speed

    def _local_path(self) -> Vec:
        return self._points.copy()


class ExternalLeader(Leader):
    """A leader driven from outside: :meth:`set_command` (keyboard, scripts) or a callable
    ``controller(t, position) -> velocity``, in the world frame (a scene transform does not
    apply to it). Its path never finishes."""

    def __init__(self, speed: float, startup_time: float,
                 controller: Callable[[float, Vec], npt.ArrayLike] | None = None) -> None:
        super().__init__(speed, startup_time)
        self.controller = controller
        self._command = np.zeros(2)

    def set_command(self, velocity: npt.ArrayLike) -> None:
        """Sets the velocity (m/s) used from the next step on; its speed is capped at
        ``LEADER_MAX_SPEED`` (2 m/s)."""
        v = as_velocities(velocity, "leader velocity", (2,))
        self._command = clip_speed(v, LEADER_MAX_SPEED)

    def command(self, t: float, position: Vec) -> Vec:
        if t < self.startup_time - 1e-9:
            return np.zeros(2)
        if self.controller is not None:
            self.set_command(self.controller(t - self.startup_time, position))
        return self._command.copy()


def make_leader(scenario: ScenarioConfig, rng: np.random.Generator, dt: float | None = None
                ) -> Leader:
    """Builds the leader of ``scenario.path``, turned by ``path_rotation`` / ``path_mirror``
    about its ``start``; ``rng`` draws the random waypoints; ``dt`` (the control period) lets
    waypoint moves land. Waypoints are absolute (world) positions."""
    size, speed, start = scenario.path_size, scenario.leader_speed, scenario.startup_time
    margin = scenario.arrival_margin
    turn = scene_matrix(scenario)
    origin = np.asarray(scenario.start, dtype=float)
    pauses = scenario.leader_pauses
    if scenario.path == "square":
        targets = np.array(PAPER_SQUARE) * (size / 4.0)
        return WaypointLeader(targets, speed, start, margin, axis_aligned=True, transform=turn,
                              dt=dt, origin=origin, pauses=pauses)
    if scenario.path == "waypoints":
        local = np.array(scenario.waypoints, dtype=float)
        if np.any(origin != 0.0):
            local = local - origin  # the path's frame starts at the leader's start
        return WaypointLeader(local, speed, start, margin, axis_aligned=False,
                              transform=turn, dt=dt, origin=origin, pauses=pauses)
    if scenario.path == "random_waypoints":
        targets = rng.uniform(-size, size, (scenario.random_waypoint_count, 2))
        return WaypointLeader(targets, speed, start, margin, axis_aligned=False, transform=turn,
                              dt=dt, origin=origin, pauses=pauses)
    if scenario.path == "circle":
        radius = size / 2

        def circle(phi: Vec) -> Vec:  # through the origin, heading +y, centre (-r, 0)
            sin, cos = sin_cos(phi)
            return np.stack([radius * (cos - 1), radius * sin], axis=1)

        return CurveLeader(circle, speed, start, scenario.laps, turn, origin, pauses)
    if scenario.path == "figure_eight":

        def eight(phi: Vec) -> Vec:  # through the origin, lobes above and below it
            return np.stack([-size / 2 * sin_cos(2 * phi)[0], size * sin_cos(phi)[0]], axis=1)

        return CurveLeader(eight, speed, start, scenario.laps, turn, origin, pauses)
    return ExternalLeader(speed, start)


def preview_path(scenario: ScenarioConfig, dt: float | None = None) -> Vec | None:
    """The leader's scripted path (M, 2, world frame) without drawing anything: None for a
    random or external path; a recorded walk's samples for ``leader="trajectory"`` (a person
    walks the path's corners: its path is the robot's)."""
    fixed = scenario.leader_kind.preview_path(scenario)
    if fixed is not None:
        return fixed
    if scenario.path in ("random_waypoints", "external"):
        return None
    return make_leader(scenario, np.random.default_rng(0), dt).reference_path()


REDRAWS = 100
"""Random waypoints crossing an obstacle are drawn again, at most this many times."""


def redraw_clear(scenario: ScenarioConfig, scene: Scene, radius: float, leader: Leader,
                 rng: np.random.Generator, dt: float | None = None) -> Leader:
    """``leader`` (random waypoints) if its legs keep ``radius`` from every obstacle of the
    scene (and ``radius`` + the arrival margin from its walls), else new draws from ``rng``
    until they do (``ValueError`` after :data:`REDRAWS`)."""
    for _ in range(REDRAWS):
        path = leader.reference_path()
        assert path is not None
        inside = scene.clearance(path) > radius + scenario.arrival_margin
        if inside.all() and not scene.blocked(path[:-1], path[1:], radius)[0].any():
            return leader
        leader = make_leader(scenario, rng, dt)
    raise ValueError(f"random_waypoints: no path of {scenario.random_waypoint_count} targets "
                     f"within path_size={scenario.path_size:g} m of the start keeps clear of the "
                     f"scene's obstacles in {REDRAWS} draws; use a smaller path_size or fewer "
                     f"targets")
