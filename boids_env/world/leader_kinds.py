"""Who leads: one object per leader kind (``ScenarioConfig.leader``), answering every question
the rest of the code has about it.

- :class:`RobotLeader` (``robot``, the study's): a robot like the followers, driving its path.
- :class:`PersonLeader` (``person``): a pedestrian walked by the pedestrian model to the
  corners of its path (or by hand with ``path="external"``), a person-sized body the robots
  cannot push.
- :class:`WalkLeader` (``trajectory``): a recorded walk (``leader_trajectory``, a CSV of
  ``t, x, y``) replayed; it fixes the start at its first row.

The world, the env, the observations, the metrics, recordings, bags, ROS and the model cards
ask the kind (``scenario.leader_kind``) or the scenario's derived answers
(``scenario.leader_radius``), never the kind's name. A new kind is a :class:`LeaderKind`
subclass registered in :data:`LEADER_KINDS` (:func:`register_leader_kind`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np
import numpy.typing as npt

from boids_env.world.leader_base import Leader, TrajectoryLeader

FloatArray = npt.NDArray[np.float64]


class ScenarioConfig(Protocol):
    """The fields of :class:`boids_env.world.scenario.ScenarioConfig` a kind reads (the
    scenario imports this module to check its ``leader``, so it is not imported here); read
    only, as the frozen config's fields are."""

    @property
    def leader(self) -> str: ...
    @property
    def leader_trajectory(self) -> str | None: ...
    @property
    def leader_speed(self) -> float: ...
    @property
    def path(self) -> str: ...
    @property
    def person_radius(self) -> float: ...
    @property
    def crowd(self) -> int: ...
    @property
    def start(self) -> tuple[float, float]: ...
    @property
    def start_heading(self) -> float | None: ...


class LeaderKind:
    """A kind of leader: the base class answers for the study's robot leader."""

    name: ClassVar[str] = ""
    """The value of ``ScenarioConfig.leader`` that selects this kind."""
    words: ClassVar[str] = ""
    """How a warning or a model card names it ("a walking person")."""
    takes_trajectory: ClassVar[bool] = False
    """Whether ``leader_trajectory`` (a recorded walk) belongs to this kind."""

    def check(self, scenario: ScenarioConfig) -> dict[str, Any]:
        """Refuses (``ValueError``) scenario fields this kind cannot lead with; returns the
        fields it fixes (by name: e.g. a walk's start), set on the scenario by its caller."""
        if scenario.leader_trajectory is not None and not self.takes_trajectory:
            raise ValueError(f"leader_trajectory is a walk for leader='trajectory', but "
                             f"leader={scenario.leader!r}; give leader='trajectory' too")
        return {}

    def radius(self, scenario: ScenarioConfig) -> float | None:
        """The leader's body radius (m) when it is not a robot (None: a robot, the
        followers' size)."""
        return None

    def kinematic(self, scenario: ScenarioConfig) -> bool:
        """Whether the leader's body is kinematic (moved by its command exactly; nothing,
        not even a pedestrian, pushes it)."""
        return False

    def walks(self, scenario: ScenarioConfig) -> bool:
        """Whether the pedestrian model walks the leader (it runs then, crowd or not)."""
        return False

    def top_speeds(self, scenario: ScenarioConfig) -> list[tuple[float, str]]:
        """The fastest this leader moves beyond its path's own speed (m/s), each with what
        sets it (for the physics' substep check); none for a robot."""
        return []

    def fixed_start(self, scenario: ScenarioConfig) -> str | None:
        """What fixes the leader's start when the kind does ("the walk W fixes the start"),
        for errors; None when ``start`` is free."""
        return None

    def path_words(self, scenario: ScenarioConfig) -> str:
        """How an error names the leader's path."""
        return f"the leader path '{scenario.path}'"

    def preview_path(self, scenario: ScenarioConfig) -> FloatArray | None:
        """The leader's path (M, 2) when the kind fixes it (a walk's samples); None: the
        path's own (:func:`boids_env.world.leader.preview_path`)."""
        return None

    def leader(self, scenario: ScenarioConfig, path_leader: Leader, dt: float) -> Leader:
        """The episode's leader object before the pedestrian model is added: the path's
        robot leader unchanged, or the kind's own (a replayed walk)."""
        return path_leader

    def walk(self, scenario: ScenarioConfig) -> tuple[FloatArray, FloatArray] | None:
        """The recorded walk (times, points) the pedestrian model keeps clear, or None."""
        return None


class RobotLeader(LeaderKind):
    """The study's leader: a robot driving its scripted path."""

    name = "robot"
    words = "a scripted robot leader"


class PersonLeader(LeaderKind):
    """A person walked by the pedestrian model along the path's corners (JuPedSim, the
    ``people`` extra), or by hand with ``path="external"``."""

    name = "person"
    words = "a walking person"

    def radius(self, scenario: ScenarioConfig) -> float | None:
        return scenario.person_radius

    def walks(self, scenario: ScenarioConfig) -> bool:
        return scenario.path != "external"

    def top_speeds(self, scenario: ScenarioConfig) -> list[tuple[float, str]]:
        if not self.walks(scenario):
            return []
        from boids_env.world.people import GAIT_RANGE

        return [(scenario.leader_speed * GAIT_RANGE[1],
                 f"a person at leader_speed={scenario.leader_speed:g} m/s × {GAIT_RANGE[1]:g} "
                 f"(its fastest gait)")]


class WalkLeader(LeaderKind):
    """A recorded walk replayed (``leader_trajectory``): it starts at its first row and faces
    its first move; among a crowd its body is kinematic."""

    name = "trajectory"
    words = "a recorded walk"
    takes_trajectory = True

    def check(self, scenario: ScenarioConfig) -> dict[str, Any]:
        path = scenario.leader_trajectory
        if not isinstance(path, str) or not path:
            raise ValueError(f"leader='trajectory' needs leader_trajectory, the path of a CSV "
                             f"of t,x,y, got {path!r}")
        from boids_env.world.walks import WALKS, read_walk

        _, points = read_walk(path)
        fixed: dict[str, Any] = {"start": (float(points[0][0]), float(points[0][1]))}
        if path not in WALKS:
            fixed["leader_trajectory"] = str(Path(path).resolve())
        if scenario.start_heading is None:
            steps = points[1:] - points[0]
            moving = np.flatnonzero(np.hypot(steps[:, 0], steps[:, 1]) > 1e-6)
            if len(moving):
                dx, dy = steps[moving[0]]
                fixed["start_heading"] = math.degrees(math.atan2(dy, dx))
        return fixed

    def radius(self, scenario: ScenarioConfig) -> float | None:
        return scenario.person_radius

    def kinematic(self, scenario: ScenarioConfig) -> bool:
        return scenario.crowd > 0

    def top_speeds(self, scenario: ScenarioConfig) -> list[tuple[float, str]]:
        from boids_env.world.walks import max_walk_speed

        fastest = max_walk_speed(*self._walk(scenario))
        return [(fastest, f"the walk {scenario.leader_trajectory} ({fastest:.3g} m/s at most)")]

    def fixed_start(self, scenario: ScenarioConfig) -> str | None:
        return f"the walk {scenario.leader_trajectory} fixes the start"

    def path_words(self, scenario: ScenarioConfig) -> str:
        return f"the walk {scenario.leader_trajectory}"

    def preview_path(self, scenario: ScenarioConfig) -> FloatArray | None:
        return np.array(self._walk(scenario)[1])

    def leader(self, scenario: ScenarioConfig, path_leader: Leader, dt: float) -> Leader:
        return TrajectoryLeader(*self._walk(scenario), dt)

    def walk(self, scenario: ScenarioConfig) -> tuple[FloatArray, FloatArray] | None:
        return self._walk(scenario)

    @staticmethod
    def _walk(scenario: ScenarioConfig) -> tuple[FloatArray, FloatArray]:
        from boids_env.world.walks import read_walk

        assert scenario.leader_trajectory is not None  # check() refuses a walk without one
        return read_walk(scenario.leader_trajectory)


LEADER_KINDS: dict[str, LeaderKind] = {kind.name: kind for kind in
                                       (RobotLeader(), PersonLeader(), WalkLeader())}
"""The leader kinds by name (``ScenarioConfig.leader``); ``robot`` is the study's."""


def register_leader_kind(kind: LeaderKind) -> LeaderKind:
    """Adds ``kind`` to :data:`LEADER_KINDS` under ``kind.name``; ``ValueError`` for a name
    that is empty or taken by another kind."""
    if not isinstance(kind, LeaderKind):
        raise TypeError(f"a leader kind is a LeaderKind instance, got {kind!r}")
    taken = LEADER_KINDS.get(kind.name)
    if not kind.name or (taken is not None and type(taken) is not type(kind)):
        raise ValueError(f"a leader kind needs a new name (its class's ``name``), got "
                         f"{kind.name!r}; taken: {sorted(LEADER_KINDS)}")
    LEADER_KINDS[kind.name] = kind
    return kind


def leader_kind(name: str) -> LeaderKind:
    """The kind of leader ``name``; ``ValueError`` naming the kinds."""
    if not isinstance(name, str) or name not in LEADER_KINDS:
        raise ValueError(f"leader must be one of {tuple(LEADER_KINDS)}, got {name!r}")
    return LEADER_KINDS[name]
