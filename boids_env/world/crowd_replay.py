"""A replayed crowd (``crowd_file``): the pedestrians of a dataset file walking their recorded
tracks, placed in the scene by ``crowd_offset``, ``crowd_rotation`` and ``crowd_scale``, their
clock shifted by ``crowd_time``, linearly interpolated between samples at every control
period.

Each pedestrian is a body like a JuPedSim pedestrian's (:class:`~boids_env.world.space.World`'s
70 kg disc of ``person_radius`` with a 20 kN drive, which no robot can push) steered each period
to its recorded position at the period's end, never faster than its own fastest recorded
speed plus :data:`CATCH_UP`: robots see it, collide with it and count its contacts as any
pedestrian's, and it does not give way. A pedestrian exists from its first sample to its last:
before and after it waits off stage at :data:`OFF_STAGE`, beyond every sensor, and the world
moves it on and off stage between two periods (:meth:`ReplayedCrowd.places`).

Everything is a pure function of the episode's time: no random draw, the same run bit for bit
(and on unpickling, the world replays the same placements).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from boids_env.world.crowd_files import Tracks, read_crowd
from boids_env.world.people import within_speeds

if TYPE_CHECKING:
    from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


class _Bodies(Protocol):
    """What a replayed crowd reads of :class:`~boids_env.world.space.World` (which imports
    the config, which imports the scenario, which imports this module)."""

    @property
    def pedestrian_positions(self) -> FloatArray: ...


class ScenarioConfig(Protocol):
    """The fields of :class:`boids_env.world.scenario.ScenarioConfig` a replayed crowd reads
    (the scenario imports this module to check its file, so it is not imported here)."""

    @property
    def crowd_file(self) -> str | None: ...
    @property
    def crowd_format(self) -> str: ...
    @property
    def crowd_frame_step(self) -> float: ...
    @property
    def crowd_rate(self) -> float: ...
    @property
    def crowd_time(self) -> float: ...
    @property
    def crowd_offset(self) -> tuple[float, float]: ...
    @property
    def crowd_rotation(self) -> float: ...
    @property
    def crowd_scale(self) -> float: ...
    @property
    def person_radius(self) -> float: ...

OFF_STAGE = (1.0e5, 1.0e5)
"""Where the first pedestrian not in the recording at the time waits (m): far beyond every
sensor and scene (coordinates are bounded by ±1000 m); pedestrian k waits
``k`` × :data:`OFF_STAGE_SPACING` farther in x, clear of the others."""
OFF_STAGE_SPACING = 2.0
"""Spacing (m) of the pedestrians waiting off stage (more than two bodies: they never touch)."""
CATCH_UP = 0.05
"""A replayed pedestrian held back (by a robot against a wall) catches up at most this much
(m/s) faster than its fastest recorded speed."""
TIME_EPS = 1e-9
"""Tolerance (s) of a pedestrian's presence at its first and last sample."""


def crowd_tracks(scenario: ScenarioConfig) -> Tracks:
    """The tracks of ``scenario.crowd_file`` (read, checked and cached)."""
    assert scenario.crowd_file is not None, "crowd_tracks needs a crowd_file"
    return read_crowd(scenario.crowd_file, scenario.crowd_format, scenario.crowd_frame_step,
                      scenario.crowd_rate)


def placed(scenario: ScenarioConfig, tracks: Tracks) -> tuple[FloatArray, FloatArray]:
    """The tracks' ``(times (M,) s on the episode's clock, points (M, 2) m in the world)``:
    world = offset + scale · R(rotation) · file point, time = file time − ``crowd_time``."""
    a = math.radians(scenario.crowd_rotation)
    turn = scenario.crowd_scale * np.array([[math.cos(a), -math.sin(a)],
                                            [math.sin(a), math.cos(a)]])
    points = tracks.points @ turn.T + np.asarray(scenario.crowd_offset, dtype=float)
    return tracks.times - scenario.crowd_time, points


def max_replay_speed(scenario: ScenarioConfig) -> float:
    """The fastest a replayed pedestrian of ``scenario`` moves (m/s), catching up included."""
    speeds = crowd_tracks(scenario).max_speeds()
    return float(speeds.max(initial=0.0)) * scenario.crowd_scale + CATCH_UP


class ReplayedCrowd:
    """The pedestrians of a crowd file on their tracks (see the module).

    Args:
        scenario: the episode's scenario (``crowd_file`` and its placement fields).
        scene: the scene they walk in: a sample inside its static geometry is refused.
        dt: the control period (s).
        robots: (N, 2) the robots' start (m): a pedestrian on stage at the start touching one
            (closer than ``person_radius`` + ``robot_radius``) is refused.
        robot_radius: the robots' radius (m).
    """

    def __init__(self, scenario: ScenarioConfig, scene: Scene, dt: float,
                 robots: FloatArray | None = None, robot_radius: float = 0.0) -> None:
        tracks = crowd_tracks(scenario)
        times, points = placed(scenario, tracks)
        last = times[tracks.start[1:] - 1]
        keep = np.flatnonzero(last >= -TIME_EPS)  # tracks over before the episode: gone
        lengths = np.diff(tracks.start)[keep]
        index = np.concatenate([np.arange(tracks.start[k], tracks.start[k + 1]) for k in keep]
                               ) if len(keep) else np.zeros(0, dtype=np.int64)
        self.times, self.points = times[index], points[index]
        self.start = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        self.dt = float(dt)
        self.radius = scenario.person_radius
        self.count = len(keep)
        inside = (np.flatnonzero(scene.within(self.points, 0.0)) if len(self.points)
                  else np.zeros(0, dtype=np.int64))
        if len(inside):
            k = int(np.searchsorted(self.start, inside[0], side="right") - 1)
            x, y = self.points[inside[0]]
            raise ValueError(f"crowd_file {scenario.crowd_file}: pedestrian "
                             f"{tracks.ids[keep[k]]} at t={self.times[inside[0]]:g} s is at "
                             f"({x:.3g}, {y:.3g}) m, inside the static geometry of scene "
                             f"{scene.name!r}; place the crowd with crowd_offset, "
                             f"crowd_rotation and crowd_scale")
        self.first = self.times[self.start[:-1]]
        self.last = self.times[self.start[1:] - 1]
        self.speeds = tracks.max_speeds()[keep] * scenario.crowd_scale + CATCH_UP
        # one sorted key per sample, track k's in [2k, 2k + 1): one vectorised search for all
        self._origin = float(self.times.min(initial=0.0))
        self._span = float(self.times.max(initial=0.0)) - self._origin + 1.0
        owner = np.repeat(np.arange(self.count), lengths)
        self._keys = 2.0 * owner + (self.times - self._origin) / self._span
        self.start_pedestrians = self.positions(0.0)
        if robots is not None and self.count:
            self._check_clear(scenario, np.asarray(robots, dtype=float).reshape(-1, 2),
                              robot_radius, tracks.ids[keep])

    def _check_clear(self, scenario: ScenarioConfig, robots: FloatArray, robot_radius: float,
                     ids: npt.NDArray[np.int64]) -> None:
        gaps = np.hypot(self.start_pedestrians[:, None, 0] - robots[None, :, 0],
                        self.start_pedestrians[:, None, 1] - robots[None, :, 1])
        close = np.argwhere(gaps < self.radius + robot_radius)
        if len(close):
            k, robot = close[0]
            x, y = self.start_pedestrians[k]
            raise ValueError(f"crowd_file {scenario.crowd_file}: pedestrian {ids[k]} starts at "
                             f"({x:.3g}, {y:.3g}) m on robot {robot}'s start; place the crowd "
                             f"elsewhere (crowd_offset, crowd_rotation, crowd_scale) or start it "
                             f"later (crowd_time)")

    def present(self, t: float) -> BoolArray:
        """(P,) whether each pedestrian is in the recording at time ``t`` (s)."""
        return (self.first <= t + TIME_EPS) & (t - TIME_EPS <= self.last)

    def positions(self, t: float) -> FloatArray:
        """(P, 2) each pedestrian's recorded position at ``t`` (s), linearly interpolated
        between its samples; off stage (:data:`OFF_STAGE`) when it is not in the recording
        then."""
        out = np.empty((self.count, 2))
        out[:] = OFF_STAGE
        out[:, 0] += OFF_STAGE_SPACING * np.arange(self.count)
        if not self.count:
            return out
        clipped = np.clip(t, self.first, self.last)
        k = np.arange(self.count)
        query = 2.0 * k + (clipped - self._origin) / self._span
        j = np.searchsorted(self._keys, query, side="right") - 1
        j = np.clip(j, self.start[:-1], np.maximum(self.start[1:] - 2, self.start[:-1]))
        nxt = np.minimum(j + 1, self.start[1:] - 1)
        gap = self.times[nxt] - self.times[j]
        frac = np.where(gap > 0, (clipped - self.times[j]) / np.where(gap > 0, gap, 1.0), 0.0)
        frac = np.clip(frac, 0.0, 1.0)
        here = self.points[j] + frac[:, None] * (self.points[nxt] - self.points[j])
        shown = self.present(t)
        out[shown] = here[shown]
        return out

    def places(self, t: float) -> tuple[npt.NDArray[np.int64], FloatArray]:
        """The pedestrians that come on or go off stage in the period from ``t`` (s) and
        where the world puts them before the period's physics: their positions at its end
        (off stage for those leaving)."""
        now, then = self.present(t), self.present(t + self.dt)
        changed = np.flatnonzero(now != then)
        return changed, self.positions(t + self.dt)[changed]

    def walk(self, t: float, world: _Bodies) -> FloatArray:
        """The crowd's body velocities (P, 2) for the period from ``t`` (s): to each
        pedestrian's recorded position at its end, within its speed (zero for one coming on
        or going off stage, which the world places)."""
        moving = self.present(t) & self.present(t + self.dt)
        velocity = (self.positions(t + self.dt) - world.pedestrian_positions) / self.dt
        velocity[~moving] = 0.0
        return within_speeds(velocity, self.speeds)
