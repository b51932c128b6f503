"""A person as the leader: walked by the pedestrian model (``leader="person"``) or replayed
from a recorded walk (``leader="trajectory"``, a CSV of ``t, x, y``).

Both are commanded kinematically: the world moves robot 0 by the command these leaders return,
the displacement to the person's next position over one control period, so the leader's
position after each step is the walk's own, but for what robots pushing the person's 20 kN
driven body move it (micrometres, corrected the next period). A replayed walk among a crowd
(whose pedestrians are as heavy and as strongly driven) is a kinematic body that nothing
pushes, on its walk to rounding, and the pedestrian model walks around it
(:meth:`~boids_env.world.people.People._place_walker`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from boids_env.world.leader_base import Leader
from boids_env.world.people import GAIT_RANGE, People, within_speeds

if TYPE_CHECKING:
    from boids_env.world.crowd_replay import ReplayedCrowd
    from boids_env.world.scenario import ScenarioConfig
    from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]

def _polyline_length(path: FloatArray) -> float:
    steps = np.diff(path, axis=0)
    return float(np.hypot(steps[:, 0], steps[:, 1]).sum())


class PersonLeader(Leader):
    """The person walked by :class:`~boids_env.world.people.People` to its path's corners.

    Args:
        people: the pedestrian simulation holding the person (its first agent).
        path: the person's path (M, 2): its start, then its goals (m, world frame).
        speed: preferred walking speed (m/s).
        startup_time: the person stands still until then (s).
        goal_pause: mean pause (s) at each goal but the last.
        dt: the control period (s).
    """

    def __init__(self, people: People, path: FloatArray, speed: float, startup_time: float,
                 goal_pause: float, dt: float) -> None:
        super().__init__(speed, startup_time)
        self.people = people
        self.path = np.asarray(path, dtype=float).reshape(-1, 2)
        self.goal_pause = goal_pause
        self.dt = dt

    def command(self, t: float, position: FloatArray) -> FloatArray:
        """The velocity that takes the leader's body to the person's position after this
        period (the env advances the people first)."""
        target = self.people.positions[0]
        self.finished = self.people.finished
        velocity = np.array([[(target[0] - position[0]) / self.dt,
                              (target[1] - position[1]) / self.dt]])
        return within_speeds(velocity, self.top_speed)[0]  # never faster than it walks

    @property
    def top_speed(self) -> float:
        """The fastest the person walks (m/s): its preferred speed at its fastest gait."""
        return self.speed * GAIT_RANGE[1]

    @property
    def nominal_duration(self) -> float:
        pauses = max(len(self.path) - 2, 0) * self.goal_pause
        return _polyline_length(self.path) / self.speed + pauses

    def reference_path(self) -> FloatArray:
        return self.path.copy()

    def _local_path(self) -> FloatArray:
        return self.path.copy()


def make_person(scenario: ScenarioConfig, scene: Scene, leader: Leader,
                initial: FloatArray, rng: np.random.Generator, dt: float,
                robot_radius: float = 0.0) -> tuple[Leader, People | ReplayedCrowd | None]:
    """The episode's leader and people for the person and crowd fields of ``scenario``:
    ``leader`` (the path's robot leader) unchanged for ``leader="robot"`` and for a person
    walked from outside (``path="external"``), the person walking its path's corners, or the
    recorded walk; the pedestrian simulation when a person walks or a crowd is asked for
    (None otherwise), or the replayed crowd of ``crowd_file`` (no draw). ``initial`` (N, 2):
    the robots' start (of ``robot_radius``), kept clear of pedestrians."""
    from boids_env.world.crowd_replay import ReplayedCrowd
    from boids_env.world.people import People

    sc = scenario
    kind = sc.leader_kind
    leader = kind.leader(sc, leader, dt)
    walking = kind.walks(sc)
    if sc.crowd_file is not None:  # the scenario refuses it with a walking person or a crowd
        return leader, ReplayedCrowd(sc, scene, dt, initial, robot_radius)
    if not walking and not sc.crowd:
        return leader, None
    path = leader.reference_path() if walking else None
    goals = np.zeros((0, 2)) if path is None else _goals(path)
    curve = sc.path in ("circle", "figure_eight")
    people = People(scene, dt, np.random.default_rng(rng.integers(2**63)),
                    person=(float(initial[0][0]), float(initial[0][1])) if walking else None,
                    goals=goals, speed=sc.leader_speed, gait_variation=sc.gait_variation,
                    goal_pause=0.0 if curve else sc.goal_pause, startup_time=sc.startup_time,
                    crowd=sc.crowd, crowd_speed=sc.crowd_speed, radius=sc.person_radius,
                    keep_clear=initial, walk=kind.walk(sc))
    if walking:
        assert path is not None
        leader = PersonLeader(people, np.vstack([initial[:1], goals]), sc.leader_speed,
                              sc.startup_time, 0.0 if curve else sc.goal_pause, dt)
    return leader, people


GOAL_SPACING = 0.5
"""A curve's points closer than this (m) to the previous goal are not goals of the person."""


def _goals(path: FloatArray) -> FloatArray:
    """The person's goals along ``path`` (M, 2): its points after the start, thinned to
    :data:`GOAL_SPACING` (a curve's dense points), the last always kept."""
    kept = [path[0]]
    for point in path[1:-1]:
        if math.hypot(point[0] - kept[-1][0], point[1] - kept[-1][1]) >= GOAL_SPACING:
            kept.append(point)
    kept.append(path[-1])
    return np.array(kept[1:], dtype=float)
