"""The leader's motion: the base class of every leader (scripted, walked, replayed), and the
replay of a recorded walk, which needs nothing of the scenario.

A leader is a small state machine: ``command(t, position)`` returns the velocity (m/s, world
frame) to command at time ``t`` given the leader's measured position, and ``finished`` tells
whether its path is done. Before ``startup_time`` every leader commands zero.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from boids_env.vectors import times_matrix

Vec = npt.NDArray[np.float64]
FloatArray = Vec


class Leader:
    """Base class: zero command until the start-up time, then the path's own command.

    Subclasses script their path in its own frame (``_move``); ``transform`` (from
    :func:`boids_env.world.scenario.scene_matrix`) places that frame in the world, so a rotated or
    mirrored square is exactly the study's square turned.
    """

    def __init__(self, speed: float, startup_time: float, transform: Vec | None = None,
                 origin: npt.ArrayLike = (0.0, 0.0),
                 pauses: tuple[tuple[float, float], ...] = ()) -> None:
        self.speed = speed
        self.startup_time = startup_time
        self.finished = False
        self.pauses = tuple(pauses)
        """Standstills ((when, how long), ...) in s of driving time (``leader_pauses``)."""
        turn = np.eye(2) if transform is None else np.asarray(transform, dtype=float)
        self.transform = turn
        # The identity is skipped, not multiplied: x·1 + y·0 turns −0.0 into 0.0, which flips
        # a heading of exactly ±180° and so the study's unwrapped alignment rule.
        self._turned = not np.array_equal(turn, np.eye(2))
        self.origin = np.asarray(origin, dtype=float).reshape(2)
        """Where the path's own frame starts in the world (the leader's start)."""
        self._moved = bool(np.any(self.origin != 0.0))

    def command(self, t: float, position: Vec) -> Vec:
        """Velocity command (m/s) at time ``t`` (s since reset) for the measured ``position``."""
        if t < self.startup_time - 1e-9 or self.finished:
            return np.zeros(2)
        driving = self.driving_time(t - self.startup_time)
        if driving is None:
            return np.zeros(2)
        local = np.asarray(position, dtype=float)
        if self._moved:
            local = local - self.origin
        if not self._turned:
            return self._move(driving, local)
        turned = self._move(driving, times_matrix(local, self.transform))  # T⁻¹ = Tᵀ
        return times_matrix(turned, self.transform.T)

    def driving_time(self, elapsed: float) -> float | None:
        """The path's own clock ``elapsed`` s after the start-up: the time spent driving,
        pauses left out; None while the leader stands in a pause."""
        for when, length in self.pauses:
            if elapsed < when:
                break
            if elapsed < when + length:
                return None
            elapsed -= length
        return elapsed

    def _move(self, t: float, position: Vec) -> Vec:
        raise NotImplementedError

    @property
    def nominal_duration(self) -> float | None:
        """Time (s) the path takes at ``speed`` from the end of start-up, pauses included;
        None if unbounded."""
        driving = self._driving_duration()
        if driving is None:
            return None
        return driving + sum(length for _, length in self.pauses) if self.pauses else driving

    def _driving_duration(self) -> float | None:
        """Time (s) the path takes at ``speed`` without pauses; None if unbounded."""
        return None

    def reference_path(self) -> Vec | None:
        """The scripted path as a polyline (M, 2) in metres, world frame (None: no script, e.g.
        external), for the leader's path deviation."""
        local = self._local_path()
        if local is None:
            return None
        world = times_matrix(local, self.transform.T) if self._turned else local
        return world + self.origin if self._moved else world

    def _local_path(self) -> Vec | None:
        return None

    @property
    def initial_heading(self) -> float:
        """Direction (rad, world frame) of the path's first move: where the leader faces at
        the start (the leader frame of the observations starts there)."""
        path = self._local_path()
        direction = np.array([0.0, 1.0])
        if path is not None:
            steps = np.diff(path, axis=0)
            moving = np.flatnonzero(np.hypot(steps[:, 0], steps[:, 1]) > 1e-9)
            if len(moving):
                direction = steps[moving[0]]
        x, y = times_matrix(direction, self.transform.T)
        return math.atan2(y, x)


class TrajectoryLeader(Leader):
    """Replays a recorded walk: at episode time t the leader is at the walk's position at t
    (rows interpolated linearly; before the first row at the first, after the last at the
    last, and then finished).

    Args:
        times: (M,) strictly increasing sample times (s), the episode's clock.
        points: (M, 2) positions (m, world frame).
        dt: the control period (s).
    """

    def __init__(self, times: FloatArray, points: FloatArray, dt: float) -> None:
        super().__init__(0.0, 0.0)
        self.times = np.asarray(times, dtype=float)
        self.points = np.asarray(points, dtype=float).reshape(-1, 2)
        self.dt = dt

    def position_at(self, t: float) -> FloatArray:
        """The walk's position at time ``t`` (s), linearly interpolated."""
        return np.array([np.interp(t, self.times, self.points[:, 0]),
                         np.interp(t, self.times, self.points[:, 1])])

    def command(self, t: float, position: FloatArray) -> FloatArray:
        """The velocity that takes the leader's body to the walk's position at ``t + dt``."""
        nxt = t + self.dt
        if nxt >= self.times[-1] - 1e-9:
            self.finished = True
        target = self.position_at(nxt)
        return np.array([(target[0] - position[0]) / self.dt,
                         (target[1] - position[1]) / self.dt])

    @property
    def nominal_duration(self) -> float:
        return float(self.times[-1])

    def reference_path(self) -> FloatArray:
        return self.points.copy()

    def _local_path(self) -> FloatArray:
        return self.points.copy()
