"""Frozen, validated configuration of the environment and of the Reynolds controller.

Every default is a number from the study (Akgun, "Development of Leader Following, Boids Inspired
Algorithm Using ROS") unless its docstring says otherwise; the docs' configuration reference
lists them.
Bad values raise ``ValueError`` naming the field, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from boids_env.checks import flag as _flag
from boids_env.checks import integer as _integer
from boids_env.checks import number as _number
from boids_env.checks import set_field as _set
from boids_env.world.realism import RealismConfig
from boids_env.world.safety import SafetyConfig

# the scenario section and its path constants live with the world; re-exported here, where
# the other sections are
from boids_env.world.scenario import (
    CURVE_SPEED_FACTOR,
    LEADER_MAX_SPEED,
    ScenarioConfig,
    layout_extent,
    path_extent,
)
from boids_env.world.scenario import PATHS as PATHS
from boids_env.world.scenario import scene_matrix as scene_matrix

if TYPE_CHECKING:
    from pathlib import Path

    from boids_env.world.scene import Scene

FRAMES = ("world", "leader")
"""Observation (and action) frames: the study's world frame, or the leader's heading frame
(opt-in; see :mod:`boids_env.observations`)."""


# The range checks live in boids_env.checks (shared with the realism section); these names are
# kept for the other packages' configs (e.g. train.config).
check_number = _number
check_integer = _integer


@dataclass(frozen=True)
class WorldConfig:
    """The physical world: arena, robots and the physics time step (DESIGN section 2)."""

    arena_half_size: float = 5.0
    """Half the side of the square arena (m); walls at ±arena_half_size. Paper: 10 m × 10 m."""
    robot_radius: float = 0.036
    """Sphero SPRK+ radius (m)."""
    robot_mass: float = 0.18
    """Sphero SPRK+ mass (kg)."""
    max_speed: float = 0.5
    """Followers' speed limit (m/s); actions are clipped to it. Paper: 0.5 m/s."""
    drive_force: float = 1.0
    """Largest force (N) a robot's drive applies to track its commanded velocity. Not in the
    paper (Stage set velocities instantly); 1 N reaches 0.5 m/s from rest in 0.09 s."""
    dt: float = 0.1
    """Control period (s): 10 Hz, as the original controller and simulator."""
    substeps: int = 10
    """Physics substeps per control step (fixed step dt / substeps)."""
    collision_slop: float = 0.001
    """pymunk collision slop (m). Its default (0.1) assumes pixels; in metres robots would sink."""
    scene: str = "arena"
    """The static world: a built-in scene (``arena``, the study's empty box of side
    2·``arena_half_size``; ``small_room``, ``doorway``, ``corridor``, ``pillars``, ``lab``), a
    ROS ``map_server`` YAML or a shapes file (``.toml`` / ``.json``). Choosing one also sets its
    leader path and start unless given (``map=PATH`` is the same as ``scene=PATH``)."""
    robot: str = "sphero"
    """The robot preset the robot fields come from (:data:`boids_env.world.robots.PRESETS`:
    ``sphero``, the study's; ``sphero_sprk``, ``turtlebot3_burger``, ``gritsbot``). Choosing
    one sets ``robot_radius``, ``robot_mass``, ``max_speed``, ``drive_force``, ``drive``,
    ``max_turn_rate``, ``max_turn_acceleration``, ``heading_gain`` and ``velocity_law``, and
    scales ``leader_speed`` and ``layout_spacing`` to the robot, unless they are given too."""
    drive: str = "holonomic"
    """``holonomic`` (the study's omnidirectional disc) or ``unicycle`` (moves only along its
    heading, which turns at a bounded rate; :mod:`boids_env.world.robots`)."""
    max_turn_rate: float | None = None
    """Top turn rate (rad/s) of a unicycle (required for one; ignored when holonomic)."""
    max_turn_acceleration: float | None = None
    """Largest change of a unicycle's turn rate (rad/s²); None: it follows its command at
    once."""
    heading_gain: float | None = None
    """Gain k (1/s) of a unicycle driver's heading controller, ω = clip(k·sin e, ±ω_max) for
    a heading error e within 90°; None: ``max_turn_rate``."""
    velocity_law: str = "turn_and_drive"
    """A unicycle driver's speed: ``turn_and_drive`` (differential drive: the command's
    component along the heading, never reversing) or ``roll`` (a Sphero: the command's full
    speed while the heading turns)."""

    def __post_init__(self) -> None:
        _set(self, "arena_half_size", _number("arena_half_size", self.arena_half_size, 0.5, 1000,
                                              unit="m"))
        _set(self, "robot_radius", _number("robot_radius", self.robot_radius, 0.0, 0.5,
                                           lo_open=True, unit="m"))
        _set(self, "robot_mass", _number("robot_mass", self.robot_mass, 0.001, 100,
                                         unit="kg"))
        _set(self, "max_speed", _number("max_speed", self.max_speed, 0.0, 5.0, lo_open=True,
                                        unit="m/s"))
        _set(self, "drive_force", _number("drive_force", self.drive_force, 0.0, 1000,
                                          lo_open=True, unit="N"))
        _set(self, "dt", _number("dt", self.dt, 0.0, 1.0, lo_open=True, unit="s"))
        _set(self, "substeps", _integer("substeps", self.substeps, 1, 1000))
        _set(self, "collision_slop", _number("collision_slop", self.collision_slop, 0.0, 0.01,
                                             unit="m"))
        from boids_env.world.scenes import load_scene, scene_key

        load_scene(self.scene, self.arena_half_size)  # a bad name or file is refused here
        _set(self, "scene", scene_key(self.scene))
        self._check_robot()

    def _check_robot(self) -> None:
        """The robot model's fields: a known preset and drive, a unicycle's turn limits."""
        from boids_env.world.robots import DRIVES, MAX_TURN_PER_SUBSTEP, PRESETS, VELOCITY_LAWS

        if self.robot not in PRESETS:
            raise ValueError(f"robot must be one of {sorted(PRESETS)}, got {self.robot!r}")
        if self.drive not in DRIVES:
            raise ValueError(f"drive must be one of {DRIVES}, got {self.drive!r}")
        if self.velocity_law not in VELOCITY_LAWS:
            raise ValueError(f"velocity_law must be one of {VELOCITY_LAWS}, got "
                             f"{self.velocity_law!r}")
        for name, hi, unit in (("max_turn_rate", 50.0, "rad/s"),
                               ("max_turn_acceleration", 10_000.0, "rad/s²"),
                               ("heading_gain", 1000.0, "1/s")):
            if getattr(self, name) is not None:
                _set(self, name, _number(name, getattr(self, name), 0.0, hi, lo_open=True,
                                         unit=unit))
        if self.drive != "unicycle":
            return
        if self.max_turn_rate is None:
            raise ValueError("drive='unicycle' needs max_turn_rate (rad/s), e.g. 2.84 for a "
                             "TurtleBot3 Burger (or choose robot=...)")
        turn = self.max_turn_rate * self.dt / self.substeps
        if turn > MAX_TURN_PER_SUBSTEP:
            raise ValueError(
                f"a unicycle may turn at most {MAX_TURN_PER_SUBSTEP} rad per physics substep; "
                f"max_turn_rate={self.max_turn_rate:g} rad/s × dt={self.dt:g} s / substeps="
                f"{self.substeps} turns {turn:.3g} rad: use substeps >= "
                f"{math.ceil(self.max_turn_rate * self.dt / MAX_TURN_PER_SUBSTEP)}")
        gain = self.max_turn_rate if self.heading_gain is None else self.heading_gain
        if gain * self.dt > 1.0:
            raise ValueError(
                f"heading_gain × dt must be at most 1 (the heading would overshoot its command "
                f"within a control period), got {gain:g} 1/s × {self.dt:g} s")


@dataclass(frozen=True)
class ObservationConfig:
    """What each follower senses (DESIGN section 6): exact positions and velocities."""

    horizon: float = 1.0
    """Neighbour radius (m): robots within it, the leader included, fill the slots. Paper: 1.0."""
    neighbours: int = 18
    """K, the number of neighbour slots (nearest first). 18 holds every other robot of the
    study's largest group, so the Reynolds policy sees exactly what full state gives it."""
    velocity_bound: float = 3.0
    """Observed velocities are clipped to ±this (m/s) so observations stay in their Box."""
    obs_noise: float = 0.0
    """Std of seeded Gaussian noise added to every observed position (m) and velocity (m/s);
    valid flags and empty slots stay exact. 0 (the study's exact sensing) by default."""
    sense_walls: bool = False
    """Append a wall slot: the offset (m) to the nearest point of the walls (any static
    geometry) and a valid flag, when within ``horizon`` (zeros otherwise). Opt-in: the study's
    followers sensed only robots. The same as ``static_slots=1``."""
    static_slots: int | None = None
    """Static-geometry slots: the nearest point of walls or obstacles within ``static_range``
    (offset in m, valid flag), then in each further slot the nearest point more than 45° away
    from the earlier slots' directions. None: 1 with ``sense_walls``, else 0 in the study's
    empty arena and 4 in any other scene (so every policy, the Reynolds one included, sees the
    obstacles without a flag)."""
    static_range: float | None = None
    """Range (m) of the static slots; None: ``horizon``."""
    lidar_rays: int = 0
    """Rays of a range sensor (0: none): distances (m) to walls, obstacles and other robots
    along rays evenly spaced in the observation's frame, ``lidar_range`` where nothing is hit.
    Opt-in."""
    lidar_range: float = 3.0
    """Range (m) of the range sensor."""
    pedestrian_slots: int | None = None
    """Pedestrian slots: the nearest pedestrians within ``pedestrian_range`` (relative
    position, velocity, valid flag each, as a neighbour slot). None: 4 with a crowd, else 0."""
    pedestrian_range: float = 3.0
    """Range (m) of the pedestrian slots."""
    frame: str = "world"
    """Frame of observations and actions, one of FRAMES: ``world`` (the study's) or
    ``leader`` (x along the leader's heading, y to its left; opt-in, for policies that should
    learn a formation relative to the leader)."""
    action: str = "velocity"
    """Action space, one of :data:`boids_env.world.robots.ACTIONS`: ``velocity`` (world-frame
    (vx, vy), the study's; a robot with a heading turns it into (v, ω) with its driver's law)
    or ``unicycle`` ((v, ω) in the robot's limits, for ``drive="unicycle"``)."""
    relative_actions: bool = False
    """Read each follower's action as a velocity relative to the leader's velocity as that
    follower observes it (noise included): the command is the observed leader velocity plus
    the action, in ``frame``, and the action space widens to ±2·``max_speed`` so that any
    command stays reachable. Opt-in, for learned policies (a zero action matches the leader's
    speed on any path and at any speed); a policy that outputs absolute velocities, like the
    Reynolds controller, needs it off."""
    route_sensing: bool = False
    """Append the ``route`` block (:mod:`boids_env.world.route`): per follower, the unit
    direction of the shortest path to the leader through free space (walls inflated by the
    robot radius, so a door narrower than a robot is no way through), the path's length (m)
    and a valid flag (0 where no free path exists: the straight line's direction and
    distance then). Opt-in; the ``route`` Reynolds preset follows it."""
    route_cell: float = 0.1
    """Cell size (m) of the route sensing's grid (finer: narrower doors resolved, slower)."""
    route_leader: bool = False
    """Sense a leader out of sight along its route: for a follower that does not see the
    leader through free space (walls inflated by the robot radius, the route grid's cells),
    the ``leader_position`` block holds the route's direction × its length (clipped to the
    scene's span like the straight line) instead of the straight-line offset, so a follower
    behind a wall finds the leader through the door; a follower that sees the leader reads
    the straight line, bit for bit as without this flag. Needs ``route_sensing`` (whose
    block still follows, valid flag included). Opt-in, for learned followers in buildings
    (``learned-buildings``)."""

    def __post_init__(self) -> None:
        _set(self, "horizon", _number("horizon", self.horizon, 0.0, 100, lo_open=True, unit="m"))
        _set(self, "neighbours", _integer("neighbours", self.neighbours, 0, 1024))
        _set(self, "velocity_bound", _number("velocity_bound", self.velocity_bound, 0.0, 100,
                                             lo_open=True, unit="m/s"))
        _set(self, "obs_noise", _number("obs_noise", self.obs_noise, 0.0, 10.0, unit="m, m/s"))
        _set(self, "sense_walls", _flag("sense_walls", self.sense_walls))
        if self.static_slots is not None:
            _set(self, "static_slots", _integer("static_slots", self.static_slots, 0, 64))
            if self.sense_walls and self.static_slots == 0:
                raise ValueError("sense_walls=True asks for a static slot; static_slots=0 "
                                 "refuses it (leave static_slots None or >= 1)")
        if self.static_range is not None:
            _set(self, "static_range", _number("static_range", self.static_range, 0.0, 100,
                                               lo_open=True, unit="m"))
        _set(self, "lidar_rays", _integer("lidar_rays", self.lidar_rays, 0, 1024))
        _set(self, "lidar_range", _number("lidar_range", self.lidar_range, 0.0, 100,
                                          lo_open=True, unit="m"))
        if self.pedestrian_slots is not None:
            _set(self, "pedestrian_slots", _integer("pedestrian_slots", self.pedestrian_slots,
                                                    0, 64))
        _set(self, "pedestrian_range", _number("pedestrian_range", self.pedestrian_range, 0.0,
                                               100, lo_open=True, unit="m"))
        _set(self, "relative_actions", _flag("relative_actions", self.relative_actions))
        _set(self, "route_sensing", _flag("route_sensing", self.route_sensing))
        _set(self, "route_cell", _number("route_cell", self.route_cell, 0.02, 1.0, unit="m"))
        _set(self, "route_leader", _flag("route_leader", self.route_leader))
        if self.route_leader and not self.route_sensing:
            raise ValueError("route_leader=True reads the leader along the route: it needs "
                             "route_sensing=True")
        from boids_env.world.robots import ACTIONS

        if self.action not in ACTIONS:
            raise ValueError(f"action must be one of {ACTIONS}, got {self.action!r}")
        if self.action == "unicycle" and self.relative_actions:
            raise ValueError("relative_actions=True reads velocities relative to the leader's; "
                             "action='unicycle' takes (v, ω): use one of them")
        if self.frame not in FRAMES:
            raise ValueError(f"frame must be one of {FRAMES}, got {self.frame!r}")


REWARDS = ("study", "safe")
"""Reward presets: ``study`` (the study's three violations only, the default) and ``safe``
(adds penalties for crowding, contact and walls; see :data:`SAFE_WEIGHTS`)."""
ALIGNMENT_SOURCES = ("command", "heading")
"""What the alignment rule compares (``alignment_source``)."""
SAFE_WEIGHTS = {"reward_proximity": 1.0, "reward_contact": 4.0, "reward_wall": 2.0}
"""Weights of the safety terms under ``reward="safe"`` (per step, × dt, like a violation)."""


@dataclass(frozen=True)
class MetricsConfig:
    """Violation thresholds (all against the leader) and reward weights (DESIGN section 4)."""

    separation_threshold: float = 0.7
    """Separation violation when a follower is closer than this to the leader (m)."""
    cohesion_threshold: float = 2.25
    """Cohesion violation when a follower is farther than this from the leader (m)."""
    alignment_threshold_deg: float = 45.0
    """Alignment violation when the commanded directions differ by more than this (degrees)."""
    wrap_alignment: bool = True
    """Wrap the angle difference into [0°, 180°]. False reproduces the study's analysis, which
    took |θ_leader − θ_i| unwrapped (so −179° vs 180° counted as a violation)."""
    alignment_source: str = "command"
    """What the alignment rule compares: ``command`` (the commanded velocities' directions,
    the study's) or ``heading`` (the robots' measured headings; robots with a heading only,
    the study's own complaint about its holonomic robots). Both are reported for robots with
    a heading (``V_align_command``, ``V_align_heading``); this one is ``V_align`` and the
    reward's."""
    reward_separation: float = 1.0
    """Weight of the separation flag in the reward."""
    reward_cohesion: float = 1.0
    """Weight of the cohesion flag in the reward."""
    reward_alignment: float = 1.0
    """Weight of the alignment flag in the reward."""
    reward: str = "study"
    """Reward preset, one of REWARDS: ``study`` (the study's metrics only) or ``safe`` (the
    study's plus the safety terms below at :data:`SAFE_WEIGHTS`)."""
    reward_proximity: float | None = None
    """Weight of the penalty while a follower is closer than ``safety_distance`` to another
    robot (follower or leader); None: the preset's (0 for ``study``)."""
    reward_contact: float | None = None
    """Weight of the penalty while a follower touches another robot; None: the preset's."""
    reward_wall: float | None = None
    """Weight of the penalty while a follower's centre is within ``wall_distance`` of a wall;
    None: the preset's."""
    reward_gap: float = 0.0
    """Weight of the penalty per metre a follower is beyond ``cohesion_threshold`` (−w · excess
    · dt per step). Not in the study: the cohesion flag alone tells a follower too far to get
    back soon nothing about getting closer, so it trades the flag for alignment; this dense
    term pays for closing in. 0 (off) under both rewards."""
    reward_intrusion: float = 0.0
    """Weight of the penalty while a follower's centre is within ``intrusion_distance`` of
    the leader (a person's personal space) or of a pedestrian (−w · dt per step). Not in the
    study; 0 (off) under both rewards."""
    intrusion_distance: float = 1.2
    """Centre distance (m) under which ``reward_intrusion`` applies: the outer edge of Hall's
    personal zone (1.2 m)."""
    reward_parked: float = 0.0
    """Weight of the penalty on a follower's speed while the leader stands still (−w · speed
    · dt per step, once the leader's command has been zero for more than ``parked_after``).
    Not in the study (its leader never stops): followers should park around a leader who
    stands, not mill. 0 (off) under both rewards."""
    parked_after: float = 2.0
    """Seconds the leader must have stood still before ``reward_parked`` applies (the
    followers first settle around it)."""
    parked_within: float = 0.0
    """``reward_parked`` applies only to followers within this distance (m) of the leader
    (along the route for one that does not see it, with ``route_leader``): one still far
    behind a standing leader should come, not stop. 0: to every follower (as before)."""
    safety_distance: float = 0.3
    """Centre distance (m) under which ``reward_proximity`` applies. Not in the study."""
    wall_distance: float = 0.15
    """Centre-to-wall distance (m) under which ``reward_wall`` applies (a robot touches at
    its radius, 0.036 m). Not in the study."""

    def __post_init__(self) -> None:
        _set(self, "separation_threshold",
             _number("separation_threshold", self.separation_threshold, 0.0, 100, unit="m"))
        _set(self, "cohesion_threshold",
             _number("cohesion_threshold", self.cohesion_threshold, 0.0, 1000, lo_open=True,
                     unit="m"))
        _set(self, "alignment_threshold_deg",
             _number("alignment_threshold_deg", self.alignment_threshold_deg, 0.0, 360,
                     unit="degrees"))
        if not isinstance(self.wrap_alignment, bool):
            raise ValueError(f"wrap_alignment must be True or False, got {self.wrap_alignment!r}")
        for name in ("reward_separation", "reward_cohesion", "reward_alignment", "reward_gap",
                     "reward_intrusion", "reward_parked"):
            _set(self, name, _number(name, getattr(self, name), 0.0, 1000))
        _set(self, "parked_after", _number("parked_after", self.parked_after, 0.0, 3600,
                                           unit="s"))
        _set(self, "parked_within", _number("parked_within", self.parked_within, 0.0, 1000,
                                            unit="m"))
        if self.separation_threshold >= self.cohesion_threshold:
            raise ValueError(f"separation_threshold ({self.separation_threshold} m) must be "
                             f"below cohesion_threshold ({self.cohesion_threshold} m)")
        if self.alignment_source not in ALIGNMENT_SOURCES:
            raise ValueError(f"alignment_source must be one of {ALIGNMENT_SOURCES}, got "
                             f"{self.alignment_source!r}")
        if self.reward not in REWARDS:
            raise ValueError(f"reward must be one of {REWARDS}, got {self.reward!r}")
        for name in SAFE_WEIGHTS:
            if getattr(self, name) is not None:
                _set(self, name, _number(name, getattr(self, name), 0.0, 1000))
        _set(self, "intrusion_distance", _number("intrusion_distance", self.intrusion_distance,
                                                 0.0, 10, lo_open=True, unit="m"))
        _set(self, "safety_distance", _number("safety_distance", self.safety_distance, 0.0, 10,
                                              lo_open=True, unit="m"))
        _set(self, "wall_distance", _number("wall_distance", self.wall_distance, 0.0, 10,
                                            unit="m"))

    @property
    def safety_weights(self) -> tuple[float, float, float]:
        """Resolved weights of the proximity, contact and wall terms (the preset's where a
        field is None)."""
        preset = SAFE_WEIGHTS if self.reward == "safe" else dict.fromkeys(SAFE_WEIGHTS, 0.0)
        return tuple(preset[name] if getattr(self, name) is None else getattr(self, name)
                     for name in SAFE_WEIGHTS)  # type: ignore[return-value]


_SECTIONS = {"world": WorldConfig, "scenario": ScenarioConfig, "observation": ObservationConfig,
             "metrics": MetricsConfig, "realism": RealismConfig, "safety": SafetyConfig}


def field_owners(sections: dict[str, type]) -> dict[str, str]:
    """Which section owns each flat field name; a name in two sections is a ``TypeError``
    (every field has one owner: a flat name must never reach the wrong section)."""
    owners: dict[str, str] = {}
    for section, cls in sections.items():
        for f in fields(cls):
            if f.name in owners:
                raise TypeError(f"config field {f.name!r} is in both {owners[f.name]!r} and "
                                f"{section!r}; every flat field name has one owner")
            owners[f.name] = section
    return owners


FIELD_OWNER: dict[str, str] = field_owners(_SECTIONS)
"""Which section owns each flat config name (``robots`` -> ``scenario``, ...)."""


@dataclass(frozen=True)
class EnvConfig:
    """The whole environment configuration: one section per concern.

    Build it from flat field names with :meth:`from_kwargs` (``EnvConfig.from_kwargs(robots=19,
    leader_speed=0.6)``) and derive variants with :meth:`replace`.
    """

    world: WorldConfig = field(default_factory=WorldConfig)
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    metrics: MetricsConfig = field(default_factory=MetricsConfig)
    realism: RealismConfig = field(default_factory=RealismConfig)
    """Opt-in ROS/Stage realism (:mod:`boids_env.world.realism`); off by default."""
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    """The opt-in safety filter between the policy and the robots
    (:mod:`boids_env.world.safety`); off by default."""

    def __post_init__(self) -> None:
        for name, cls in _SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"{name} must be a {cls.__name__}, got "
                                f"{type(getattr(self, name)).__name__}")
        _check_fits(self)

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> EnvConfig:
        """Builds a config from flat field names; unknown names raise ``TypeError``."""
        return cls().replace(**kwargs)

    def replace(self, **kwargs: Any) -> EnvConfig:
        """Returns a copy with the named flat fields changed (validated). Choosing a
        ``scene`` (or ``map``, the same field) also sets the scenario fields it defines (its
        leader path and start) unless they are given too; ``waypoints`` without ``path``
        sets ``path="waypoints"``."""
        if "map" in kwargs:
            if "scene" in kwargs:
                raise TypeError("give the scene or the map, not both (map=PATH is scene=PATH)")
            kwargs = {("scene" if k == "map" else k): v for k, v in kwargs.items()}
        unknown = sorted(set(kwargs) - set(FIELD_OWNER))
        if unknown:
            raise TypeError(f"unknown config field(s) {unknown}; {_close_fields(unknown)}")
        if "path" not in kwargs and _has_items(kwargs.get("waypoints", ())):
            kwargs["path"] = "waypoints"  # as boids run --waypoints: targets mean that path
        asked = dict(kwargs)  # what the caller gave, before a scene's or robot's defaults
        if "scene" in kwargs:
            kwargs = {**_scene_defaults(kwargs["scene"], kwargs.get(
                "arena_half_size", self.world.arena_half_size)), **kwargs}
        if "robot" in kwargs:
            kwargs = {**_robot_defaults(kwargs), **kwargs}
        changes: dict[str, dict[str, Any]] = {}
        for name, value in kwargs.items():
            changes.setdefault(FIELD_OWNER[name], {})[name] = value
        sections = {sec: dataclasses.replace(getattr(self, sec), **chg)
                    for sec, chg in changes.items()}
        if "start" in asked and "scenario" in sections:
            _check_walk_start(asked["start"], sections["scenario"])
        return dataclasses.replace(self, **sections)

    @property
    def scene(self) -> Scene:
        """The static scene (walls, obstacles) of ``world.scene``."""
        from boids_env.world.scenes import load_scene

        return load_scene(self.world.scene, self.world.arena_half_size)

    def input_files(self) -> tuple[Path, ...]:
        """Every file this config reads (resolved paths, each once): a scene's shapes file or
        map YAML and image, a recorded walk. Whatever depends on their content (a run
        folder's identity) hashes these (:func:`boids_env.files.file_digest`)."""
        from boids_env.world.scenes import scene_files
        from boids_env.world.walks import walk_file

        files = list(scene_files(self.world.scene))
        if self.scenario.leader_trajectory is not None:
            files.append(walk_file(self.scenario.leader_trajectory))
        return tuple(dict.fromkeys(files))

    @property
    def static_slots(self) -> int:
        """The number of static-geometry slots in the observations (``static_slots``
        resolved: see :class:`ObservationConfig`)."""
        obs = self.observation
        if obs.static_slots is not None:
            return obs.static_slots
        if obs.sense_walls:
            return 1
        return 0 if self.world.scene == "arena" else DEFAULT_STATIC_SLOTS

    @property
    def pedestrian_slots(self) -> int:
        """The number of pedestrian slots in the observations (``pedestrian_slots``
        resolved: see :class:`ObservationConfig`)."""
        slots = self.observation.pedestrian_slots
        if slots is not None:
            return slots
        return DEFAULT_PEDESTRIAN_SLOTS if self.scenario.crowd else 0

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """A JSON-ready nested dict (tuples become lists)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Mapping[str, Any]]) -> EnvConfig:
        """Inverse of :meth:`to_dict`; unknown sections or fields raise ``TypeError``."""
        if not isinstance(data, Mapping):
            raise TypeError(f"config must be a mapping of sections, got {type(data).__name__}")
        unknown = sorted(set(data) - set(_SECTIONS))
        if unknown:
            raise TypeError(f"unknown config section(s) {unknown}; valid: {sorted(_SECTIONS)}")
        flat: dict[str, Any] = {}
        for section in data.values():
            flat.update(section)
        if "waypoints" in flat:
            flat["waypoints"] = tuple(tuple(p) for p in flat["waypoints"])
        if isinstance(flat.get("start"), list):
            flat["start"] = tuple(flat["start"])
        return cls.from_kwargs(**flat)


DEFAULT_PEDESTRIAN_SLOTS = 4
"""Pedestrian slots in the observations with a crowd (``pedestrian_slots``)."""
DEFAULT_STATIC_SLOTS = 4
"""Static slots in the observations of any scene but the study's arena (``static_slots``)."""


def _close_fields(unknown: list[str]) -> str:
    """"did you mean ..." with the fields close to the unknown names (difflib), or every
    field when none is close."""
    import difflib

    close = {name: difflib.get_close_matches(name, FIELD_OWNER, n=3) for name in unknown}
    if not any(close.values()):
        return f"valid fields: {sorted(FIELD_OWNER)}"
    return "; ".join(f"{name}: did you mean {' or '.join(found)}?" if found else
                     f"{name}: no field is close" for name, found in close.items())


def _check_walk_start(given: Any, sc: ScenarioConfig) -> None:
    """A recorded walk starts at its first row: a ``start`` elsewhere would be ignored, so it
    is refused (the walk's own start, as a saved config holds it, is accepted)."""
    try:
        same = tuple(map(float, given)) == sc.start
    except (TypeError, ValueError):
        same = False
    if sc.leader == "trajectory" and not same:
        raise ValueError(
            f"start {tuple(given)} cannot be given with leader='trajectory': the walk "
            f"{sc.leader_trajectory} fixes the start at its first row ({sc.start[0]:g}, "
            f"{sc.start[1]:g}); drop start (boids run: --start), or record a walk that starts "
            f"where you want")


def _has_items(value: Any) -> bool:
    """Whether ``value`` is a non-empty sequence, or not a sequence at all (the field's own
    check then names it)."""
    try:
        return len(value) > 0
    except TypeError:
        return True


def _scene_defaults(spec: Any, arena_half_size: Any) -> dict[str, Any]:
    """The scenario fields scene ``spec`` sets (nothing for a spec that does not load: the
    world section then refuses it by name)."""
    from boids_env.world.scenes import load_scene

    try:
        return dict(load_scene(spec, arena_half_size).defaults)
    except (ValueError, TypeError):
        return {}


def _robot_defaults(kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """The fields robot preset ``kwargs["robot"]`` sets, and the scenario scaled to the robot
    (its top speed and size, as given or the preset's); nothing for an unknown preset (the
    world section then refuses it by name)."""
    from boids_env.world.robots import PRESETS, scaled_scenario

    name = kwargs["robot"]
    if not isinstance(name, str) or name not in PRESETS:
        return {}
    fields = PRESETS[name].fields()
    speed = kwargs.get("max_speed", fields["max_speed"])
    radius = kwargs.get("robot_radius", fields["robot_radius"])
    try:
        return {**fields, **scaled_scenario(float(speed), float(radius))}
    except (TypeError, ValueError):
        return fields


def fastest_speed(config: EnvConfig) -> tuple[float, str]:
    """The fastest a robot of this config is ever commanded (m/s) and what sets it: followers'
    ``max_speed``, the ``leader_speed`` (a curve's correction included), or an external
    leader's cap."""
    sc = config.scenario
    if sc.path == "external":
        leader = (LEADER_MAX_SPEED, f"an external leader's cap ({LEADER_MAX_SPEED:g} m/s)")
    elif sc.path in ("circle", "figure_eight"):
        leader = (sc.leader_speed * CURVE_SPEED_FACTOR,
                  f"leader_speed={sc.leader_speed:g} m/s × {CURVE_SPEED_FACTOR:g} on a curve")
    else:
        leader = (sc.leader_speed, f"leader_speed={sc.leader_speed:g} m/s")
    follower = (config.world.max_speed, f"max_speed={config.world.max_speed:g} m/s")
    return max(follower, leader, *_people_speeds(sc))


def _people_speeds(sc: ScenarioConfig) -> list[tuple[float, str]]:
    """The fastest the person and the crowd move (m/s), and what sets it."""
    from boids_env.world.people import CROWD_SPEED_SPREAD, GAIT_RANGE

    out = []
    if sc.leader == "person" and sc.path != "external":
        out.append((sc.leader_speed * GAIT_RANGE[1],
                    f"a person at leader_speed={sc.leader_speed:g} m/s × {GAIT_RANGE[1]:g} "
                    f"(its fastest gait)"))
    if sc.leader == "trajectory":
        from boids_env.world.walks import max_walk_speed, read_walk

        assert sc.leader_trajectory is not None
        fastest = max_walk_speed(*read_walk(sc.leader_trajectory))
        out.append((fastest, f"the walk {sc.leader_trajectory} ({fastest:.3g} m/s at most)"))
    if sc.crowd:
        out.append((sc.crowd_speed * CROWD_SPEED_SPREAD[1],
                    f"pedestrians at crowd_speed={sc.crowd_speed:g} m/s × "
                    f"{CROWD_SPEED_SPREAD[1]:g}"))
    return out


MAX_DRIVE_ACCELERATION = 100.0
"""Largest drive acceleration drive_force / robot_mass (m/s², about 10 g; the study's robot:
5.6). Stronger drives push crowds through walls faster than contacts can resolve."""


def _check_physics(config: EnvConfig) -> None:
    """Refuses combinations the physics cannot hold: a physics substep moving a robot farther
    than its radius (robots could pass through each other), a drive accelerating a robot harder
    than contacts can hold, a collision slop that is a large part of a robot, and initial cells
    closer than a robot's diameter (robots would start overlapping)."""
    w, sc = config.world, config.scenario
    accel = w.drive_force / w.robot_mass
    if accel > MAX_DRIVE_ACCELERATION:
        raise ValueError(
            f"drive_force / robot_mass must be at most {MAX_DRIVE_ACCELERATION:g} m/s², got "
            f"{w.drive_force:g} N / {w.robot_mass:g} kg = {accel:.4g} m/s²")
    if w.collision_slop > w.robot_radius / 4:
        raise ValueError(
            f"collision_slop must be at most a quarter of robot_radius ({w.robot_radius / 4:g} m)"
            f", got {w.collision_slop:g} m")
    obs = config.observation
    if obs.action == "unicycle" and w.drive != "unicycle":
        raise ValueError("action='unicycle' takes (v, ω) for robots with a heading; this robot "
                         "is holonomic (drive='holonomic'): choose robot=... with a unicycle "
                         "drive, or action='velocity'")
    if config.metrics.alignment_source == "heading" and w.drive != "unicycle":
        raise ValueError("alignment_source='heading' compares the robots' headings; this "
                         "robot is holonomic and has none (drive='holonomic'): choose robot=... "
                         "with a unicycle drive")
    if obs.action == "unicycle" and config.realism.active:
        raise ValueError("realism acts on world-frame velocity commands: use it with "
                         "action='velocity' (the robots' drivers then turn the executed "
                         "velocities into (v, ω))")
    fastest, why = fastest_speed(config)
    travel = fastest * w.dt / w.substeps
    if travel > w.robot_radius:
        need = math.ceil(fastest * w.dt / w.robot_radius)
        raise ValueError(
            f"dt / substeps too coarse for the speed: robots commanded up to {why} move "
            f"{travel * 1000:.1f} mm per physics substep (dt={w.dt:g} s / substeps="
            f"{w.substeps}), more than robot_radius={w.robot_radius * 1000:g} mm, so they could "
            f"pass through each other; use substeps >= {need} or a smaller dt or speed")
    gap = sc.layout_spacing - 2 * sc.init_jitter
    if sc.robots > 1 and gap <= 2 * w.robot_radius:
        raise ValueError(
            f"initial robots could overlap: layout_spacing ({sc.layout_spacing:g} m) minus twice "
            f"init_jitter ({sc.init_jitter:g} m) must exceed a robot's diameter "
            f"(2 × robot_radius = {2 * w.robot_radius:g} m)")


def _check_fits(config: EnvConfig) -> None:
    """Raises ``ValueError`` if the initial layout or the leader path leaves the arena (or
    meets an obstacle of the scene), or the physics cannot hold (see ``_check_physics``).

    In the study's arena from the origin, the extents of the grid and of the scripted path
    are checked first for a message in the arena's own terms; the scene check (the leader's
    actual path: a recorded walk, a turned start grid) always runs after it, so no start
    position or leader kind skips it."""
    _check_physics(config)
    if config.world.scene == "arena" and config.scenario.start == (0.0, 0.0):
        _check_arena_extents(config)
    _check_scene(config)


def _check_arena_extents(config: EnvConfig) -> None:
    """The study grid and the scripted path's bounding box against the arena's half size."""
    half = config.world.arena_half_size
    room = half - config.world.robot_radius
    need = layout_extent(config.scenario)
    if need >= room:
        sc = config.scenario
        raise ValueError(
            f"arena_half_size must exceed {need + config.world.robot_radius:.2f} m to hold the "
            f"initial grid of robots={sc.robots} at layout_spacing={sc.layout_spacing:g} m "
            f"(init_jitter={sc.init_jitter:g} m, robot_radius={config.world.robot_radius:g} m, "
            f"path_rotation={sc.path_rotation:g}°), got {half}")
    reach = path_extent(config.scenario)
    if reach + config.scenario.arrival_margin >= room:
        sc = config.scenario
        raise ValueError(
            f"the leader path '{sc.path}' (path_size={sc.path_size:g} m, path_rotation="
            f"{sc.path_rotation:g}°) reaches {reach:.2f} m: path_size / waypoints must keep it "
            f"below {room - sc.arrival_margin:.2f} m (arena_half_size={half} minus "
            f"robot_radius and arrival_margin)")


def _start_advice(sc: ScenarioConfig, k: int) -> str:
    """What to change when robot ``k`` starts too close to the scene (a walk fixes the
    leader's start: only the grid behind it can move)."""
    grid = f"layout_spacing ({sc.layout_spacing:g} m) or robots ({sc.robots})"
    if sc.leader != "trajectory":
        return f"change start ({sc.start[0]:g}, {sc.start[1]:g}), start_heading, {grid}"
    if k == 0:
        return (f"the walk {sc.leader_trajectory} starts there (it fixes the start): use a "
                f"walk that starts in free space or another scene")
    return (f"the walk {sc.leader_trajectory} fixes the start ({sc.start[0]:g}, "
            f"{sc.start[1]:g}): change start_heading (the grid lies behind it), {grid}")


def _check_scene(config: EnvConfig) -> None:
    """The start layout and the leader's path checked against the scene: every robot starts
    more than its radius plus the jitter from static geometry, and every leg of the path
    keeps a robot radius from obstacles (and its arrival margin more from the box's walls)."""
    from boids_env.world.leader import preview_path
    from boids_env.world.scenario import initial_positions, layout_heading

    sc, w = config.scenario, config.world
    scene = config.scene
    path = preview_path(sc, w.dt)
    cells = initial_positions(sc, None, layout_heading(sc, w.scene, path))
    need = np.full(len(cells), w.robot_radius + sc.init_jitter * math.sqrt(2))
    if sc.leader != "robot":
        need[0] = sc.person_radius  # a person (or a walk) starts exactly at its start
    clear = scene.clearance(cells)
    bad = np.flatnonzero(clear <= need)
    if bad.size:
        k = int(bad[0])
        who = "the leader" if k == 0 else f"follower {k}"
        rule = ("person_radius" if k == 0 and sc.leader != "robot"
                else "robot_radius + init_jitter·√2")
        raise ValueError(
            f"the start does not fit scene {scene.name!r}: {who} would start at "
            f"({cells[k][0]:.2f}, {cells[k][1]:.2f}), {max(clear[k], 0.0):.3f} m from "
            f"{scene.nearest_name(cells[k])}; it needs more than {need[k]:.3f} m ({rule}): "
            f"{_start_advice(sc, k)}")
    if path is None:
        return
    blocked, which = scene.blocked(path[:-1], path[1:], w.robot_radius)
    what = (f"the walk {sc.leader_trajectory}" if sc.leader == "trajectory"
            else f"the leader path '{sc.path}'")
    if scene.box is not None:
        margin = w.robot_radius + sc.arrival_margin
        near_box = scene.box_clearance(path) <= margin
        if near_box.any():
            k = int(np.argmax(near_box))
            raise ValueError(
                f"{what} reaches ({path[k][0]:.2f}, {path[k][1]:.2f}), "
                f"within {margin:.3f} m (robot_radius + arrival_margin) of "
                f"{scene.box_wall_name(path[k:k + 1], margin + 1e-9)} of scene "
                f"{scene.name!r}: keep its waypoints / path_size inside")
    if blocked.any():
        k = int(np.argmax(blocked))
        a, b = path[k], path[k + 1]
        leg = (f"leg {k + 1} from ({a[0]:.2f}, {a[1]:.2f}) to ({b[0]:.2f}, {b[1]:.2f})"
               if sc.path in ("square", "waypoints") else
               f"the part near ({a[0]:.2f}, {a[1]:.2f})")
        obstacle = scene.names[which[k]] if which[k] >= 0 else "an occupied map cell"
        raise ValueError(
            f"{what} of scene {scene.name!r}: {leg} crosses or passes "
            f"closer than robot_radius ({w.robot_radius:g} m) to {obstacle}; change the "
            f"waypoints, path, path_size, path_rotation or start")


@dataclass(frozen=True)
class ReynoldsParams:
    """Parameters of the Reynolds + leader controller (DESIGN section 3)."""

    separation_weight: float = 1.0
    """Weight of the separation term (paper: 1.0)."""
    cohesion_weight: float = 1.0
    """Weight of the cohesion term (paper: 1.0)."""
    alignment_weight: float = 1.0
    """Weight of the alignment term (paper: 1.0)."""
    leader_weight: float = 1.0
    """Weight of the leader-following term. Study: 1.0, 1.1, 1.2."""
    horizon: float = 1.0
    """Neighbour radius (m). Paper 1.0, original code 0.75. Bound to an env, the env's sensing
    ``horizon`` unless the preset or the caller sets one (at most the env's)."""
    desired_separation: float = 0.7
    """Neighbours closer than this push away (m). Paper 0.7, original code 0.45."""
    max_speed: float = 0.5
    """Commanded speed limit (m/s). Bound to an env, the robots' ``max_speed`` unless given
    (at most the env's)."""
    max_force: float = 0.23
    """Steering force limit (N); not stated in the paper, the original code's 0.23."""
    mass: float = 0.18
    """Mass (kg) used to integrate the steering force."""
    dt: float = 0.1
    """Control period (s) of an unbound controller; bound to an env, always the env's ``dt``
    (see :data:`ENV_OWNED`)."""
    startup_time: float = 2.0
    """Zero command for this long after reset (s); bound to an env, always the env's
    ``startup_time``."""
    obstacle_avoidance: bool | None = None
    """Steer away from walls and obstacles (not in the study). None: on whenever the env's
    scene is not the study's empty arena and its observations carry static slots (the policy
    learns both from :meth:`~boids_env.policies.ReynoldsPolicy.bind`), off in the arena, so
    the study's numbers stay exact."""
    obstacle_weight: float = 1.0
    """Weight of the obstacle-avoidance force. It is served first: the other rules share
    what is left of ``max_force`` (Reynolds' prioritised acceleration allocation)."""
    obstacle_distance: float = 0.4
    """Centre-to-surface distance (m) within which an obstacle pushes a follower away, at
    full strength at contact; shortened by the follower's approach speed × lookahead."""
    obstacle_lookahead: float = 1.0
    """Look-ahead time (s): approaching an obstacle at speed u counts as being u × lookahead
    closer to it, so a fast follower starts braking earlier."""
    personal_space: float = 0.0
    """Radius (m) of a person's personal space the leader term keeps clear (the
    proxemics-aware variant, preset ``proxemic``: 1.2 m, Hall's personal zone): the leader
    term seeks the circle of this radius around the leader and pushes followers sideways out
    of its path ahead. 0: the study's leader term (seek the leader's centre)."""
    follow_route: bool = False
    """Seek the leader along its route through free space instead of the straight line (not in
    the study; preset ``route``): the leader term becomes the route's direction × its length
    from the observations' ``route`` block, so a follower behind a wall heads for the door.
    The policy then asks the env for ``route_sensing``."""
    robot_avoidance: float = 0.0
    """Surface-to-surface distance (m) within which another robot counts as an obstacle
    point of the obstacle rule (served first, its approach speed × ``obstacle_lookahead``
    counted as nearer), so that a flock squeezed through a door or a corridor does not
    touch (not in the study; preset ``route``: 0.15). 0: off."""
    scale_to_robot: bool = False
    """Size the distances for the env's robot (not in the study; preset ``scaled``): bound to
    an env whose ``robot_radius`` r differs from the study's Sphero (r0 = 0.036 m), the
    centre-to-centre distances ``desired_separation`` and ``personal_space`` grow by 2·(r − r0)
    and the centre-to-surface ``obstacle_distance`` by r − r0, so the free gaps between bodies
    stay the ones given for the Sphero (``robot_avoidance`` is a surface gap already), and
    ``obstacle_lookahead`` and ``path_time`` grow by the time the robot needs to turn a
    quarter turn (0 for a holonomic one), so a robot that must turn to steer away starts that
    much earlier; ``personal_space`` also grows by ``max_speed`` × that time (the way a
    leader at the robots' top speed comes while a follower turns), and ``path_width`` (when
    on) by 2·(r − r0). A holonomic Sphero's parameters are unchanged."""

    path_width: float = 0.0
    """For robots with a heading (they turn before they move), with ``follow_route`` and
    ``personal_space`` on: half-width (m, centre to centre) of the strip ahead of the leader
    that is kept clear (preset ``scaled``: 0.3, sized for the robot). Inside it the leader
    term does not pull towards the leader; it pushes sideways to ``path_width`` from the
    leader's line and forwards by ``path_flee``; the strip lies along the leader's velocity
    from ``path_speed`` on and along its heading below (a robot leader turning in place
    drives off along it) and reaches ``path_time`` × max(its speed, ``max_speed``) +
    ``personal_space`` ahead. 0: off (the proxemic strip of ``personal_space``, 2 s)."""
    path_time: float = 2.0
    """Seconds of the leader's travel the ``path_width`` strip covers (grown by the robot's
    quarter-turn time with ``scale_to_robot``)."""
    path_flee: float = 0.0
    """Weight of the ``path_width`` strip's push along the leader's travel (m per m of strip
    left ahead): a follower that cannot step aside (a corridor) moves on ahead of the
    leader. Preset ``scaled``: 0.5."""
    walls_first: bool = False
    """For robots with a heading, with ``robot_avoidance`` on: serve the walls' (and
    people's) push before other robots', and drop a quarter of a robot's push against it,
    so that a follower squeezed between a neighbour and a wall is not held against the wall
    (preset ``scaled``). Off: the pushes are summed."""
    path_speed: float = 0.2
    """The ``path_width`` strip follows the leader's velocity from this speed (m/s) on, its
    heading below."""

    def __post_init__(self) -> None:
        if self.obstacle_avoidance is not None:
            _set(self, "obstacle_avoidance", _flag("obstacle_avoidance",
                                                   self.obstacle_avoidance))
        _set(self, "obstacle_weight", _number("obstacle_weight", self.obstacle_weight, 0.0, 100))
        _set(self, "obstacle_distance", _number("obstacle_distance", self.obstacle_distance,
                                                0.0, 10, lo_open=True, unit="m"))
        _set(self, "obstacle_lookahead", _number("obstacle_lookahead", self.obstacle_lookahead,
                                                 0.0, 60, unit="s"))
        _set(self, "personal_space", _number("personal_space", self.personal_space, 0.0, 5.0,
                                             unit="m"))
        _set(self, "path_time", _number("path_time", self.path_time, 0.0, 60, unit="s"))
        _set(self, "path_flee", _number("path_flee", self.path_flee, 0.0, 100))
        _set(self, "path_width", _number("path_width", self.path_width, 0.0, 5, unit="m"))
        _set(self, "path_speed", _number("path_speed", self.path_speed, 0.0, 5, lo_open=True,
                                         unit="m/s"))
        _set(self, "walls_first", _flag("walls_first", self.walls_first))
        _set(self, "follow_route", _flag("follow_route", self.follow_route))
        _set(self, "scale_to_robot", _flag("scale_to_robot", self.scale_to_robot))
        _set(self, "robot_avoidance", _number("robot_avoidance", self.robot_avoidance, 0.0, 5.0,
                                              unit="m"))
        for name in ("separation_weight", "cohesion_weight", "alignment_weight",
                     "leader_weight"):
            _set(self, name, _number(name, getattr(self, name), 0.0, 100))
        _set(self, "horizon", _number("horizon", self.horizon, 0.0, 100, lo_open=True, unit="m"))
        _set(self, "desired_separation", _number("desired_separation", self.desired_separation,
                                                 0.0, 100, unit="m"))
        _set(self, "max_speed", _number("max_speed", self.max_speed, 0.0, 5, lo_open=True,
                                        unit="m/s"))
        _set(self, "max_force", _number("max_force", self.max_force, 0.0, 1000, lo_open=True,
                                        unit="N"))
        _set(self, "mass", _number("mass", self.mass, 0.0, 100, lo_open=True, unit="kg"))
        _set(self, "dt", _number("dt", self.dt, 0.0, 1, lo_open=True, unit="s"))
        _set(self, "startup_time", _number("startup_time", self.startup_time, 0.0, 600,
                                           unit="s"))


PRESETS: dict[str, ReynoldsParams] = {
    # Table IV of the paper.
    "paper": ReynoldsParams(),
    # The defaults of the original code (boids_ros / sphero_formation).
    "boids_ros": ReynoldsParams(horizon=0.75, desired_separation=0.45),
    # Beyond the study: the proxemics-aware leader term for following a person.
    "proxemic": ReynoldsParams(personal_space=1.2),
    # Beyond the study: the leader sought along its route through doors (route sensing).
    "route": ReynoldsParams(follow_route=True, robot_avoidance=0.15),
    # Beyond the study: route following sized for the robot (issue 38), and a clear path
    # ahead of the leader (the proxemic leader term along the route), so that robots larger
    # than a Sphero never pack into contact nor meet a leader backing out of a dead end. For
    # a robot with a heading (it turns before it moves) the path is cleared earlier and wider
    # (path_width, path_flee, sized by its turning time) and walls are served before
    # neighbours (walls_first); walls are avoided in the study's arena too.
    "scaled": ReynoldsParams(follow_route=True, robot_avoidance=0.15, personal_space=0.56,
                             scale_to_robot=True, path_width=0.3, path_flee=0.5,
                             walls_first=True, obstacle_avoidance=True),
}
"""Named controller parameter sets (DESIGN section 3); ``paper`` is the default."""


ENV_OWNED = tuple(f.name for f in fields(ReynoldsParams) if f.name in FIELD_OWNER)
"""Reynolds parameters that are physical or timing quantities of the env (``horizon``,
``max_speed``, ``dt``, ``startup_time``): the env's config owns them. A suite routes them to
the env (every policy's episodes see them); a policy bound to an env takes them from its
config (:func:`env_quantities`)."""


def env_quantities(config: EnvConfig) -> dict[str, float]:
    """The values of :data:`ENV_OWNED` in ``config``: its sensing horizon (m), robots' top
    speed (m/s), control period (s) and start-up time (s), by Reynolds parameter name."""
    return {name: getattr(getattr(config, FIELD_OWNER[name]), name) for name in ENV_OWNED}


def reynolds_params(preset: str = "paper", **overrides: Any) -> ReynoldsParams:
    """Returns the named preset with ``overrides`` applied (validated)."""
    if preset not in PRESETS:
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {preset!r}")
    valid = {f.name for f in fields(ReynoldsParams)}
    unknown = sorted(set(overrides) - valid)
    if unknown:
        raise TypeError(f"unknown Reynolds parameter(s) {unknown}; valid: {sorted(valid)}")
    return dataclasses.replace(PRESETS[preset], **overrides)
