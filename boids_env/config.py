"""Frozen, validated configuration of the environment and of the Reynolds controller.

Every default is a number from the study (Akgun, "Development of Leader Following, Boids Inspired
Algorithm Using ROS") unless its docstring says otherwise; the docs' configuration reference
lists them.
Bad values raise ``ValueError`` naming the field, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import functools
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

    from boids_env.world.robots import RobotModel
    from boids_env.world.scene import Scene

FRAMES = ("world", "leader")
"""Observation (and action) frames: the study's world frame, or the leader's heading frame
(opt-in; see :mod:`boids_env.observations`)."""


MAX_SPEED_RANGE = (0.0, 5.0)
"""The range (m/s, open below) of a top speed: the robots' ``max_speed``, a controller's,
a random policy's; the one check every layer uses."""

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
        _set(self, "max_speed", _number("max_speed", self.max_speed, *MAX_SPEED_RANGE,
                                        lo_open=True, unit="m/s"))
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
        """The robot model's fields: a known preset, drive and velocity law, the turn limits
        in range, and whatever the drive itself requires (:meth:`RobotModel.check_config`)."""
        from boids_env.world.robots import PRESETS, VELOCITY_LAWS, drive_model

        if self.robot not in PRESETS:
            raise ValueError(f"robot must be one of {sorted(PRESETS)}, got {self.robot!r}")
        model = drive_model(self.drive)
        if self.velocity_law not in VELOCITY_LAWS:
            raise ValueError(f"velocity_law must be one of {VELOCITY_LAWS}, got "
                             f"{self.velocity_law!r}")
        for name, hi, unit in (("max_turn_rate", 50.0, "rad/s"),
                               ("max_turn_acceleration", 10_000.0, "rad/s²"),
                               ("heading_gain", 1000.0, "1/s")):
            if getattr(self, name) is not None:
                _set(self, name, _number(name, getattr(self, name), 0.0, hi, lo_open=True,
                                         unit=unit))
        model.check_config(self)

    @property
    def drive_model(self) -> type[RobotModel]:
        """The robot model class of ``drive`` (:data:`boids_env.world.robots.DRIVES`): what
        every caller asks about the drive (its heading, its turn time, its checks)."""
        from boids_env.world.robots import drive_model

        return drive_model(self.drive)

    @property
    def has_heading(self) -> bool:
        """Whether these robots have a heading (their drive's answer)."""
        return self.drive_model.has_heading


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
        return _default_config(cls).replace(**kwargs)

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


@functools.cache
def _default_config(cls: type[EnvConfig]) -> EnvConfig:
    """The default config of ``cls``, built (and checked) once per process."""
    return cls()


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
    fixed = sc.leader_kind.fixed_start(sc)
    if fixed is not None and not same:
        raise ValueError(
            f"start {tuple(given)} cannot be given with leader={sc.leader!r}: {fixed}; drop "
            f"start (boids run: --start), or record a walk that starts where you want")


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
    from boids_env.world.people import CROWD_SPEED_SPREAD

    out = sc.leader_kind.top_speeds(sc)
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
    if obs.action == "unicycle" and not w.has_heading:
        raise ValueError(f"action='unicycle' takes (v, ω) for robots with a heading; this robot "
                         f"is {w.drive} (drive={w.drive!r}) and has none: choose robot=... "
                         f"with a unicycle drive, or action='velocity'")
    if config.metrics.alignment_source == "heading" and not w.has_heading:
        raise ValueError(f"alignment_source='heading' compares the robots' headings; this "
                         f"robot is {w.drive} and has none (drive={w.drive!r}): choose "
                         f"robot=... with a unicycle drive")
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
    scene = config.scene
    key = (config.world, config.scenario, id(scene))
    if key in _FITTED:
        return  # this world and scenario were checked against this scene already
    if config.world.scene == "arena" and config.scenario.start == (0.0, 0.0):
        _check_arena_extents(config)
    _check_scene(config)
    if len(_FITTED) >= FITTED_LIMIT:
        _FITTED.clear()
    _FITTED[key] = scene  # held: the scene's id stays its own while the entry lives


FITTED_LIMIT = 256
"""The most (world, scenario, scene) combinations :func:`_check_fits` remembers as fitting."""
_FITTED: dict[tuple[Any, ...], Scene] = {}
"""The combinations that passed the scene check (a config's sections are frozen values, the
scene the loaded object): building a config again from the same values (a command passes
one config through several layers, a suite builds each case's variants) checks the scene
once, not once per copy."""


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
    fixed = sc.leader_kind.fixed_start(sc)
    if fixed is None:
        return f"change start ({sc.start[0]:g}, {sc.start[1]:g}), start_heading, {grid}"
    if k == 0:
        return f"{fixed}: use one that starts in free space or another scene"
    return f"{fixed}: change start_heading (the grid lies behind it), {grid}"


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
    body = sc.leader_radius
    if body is not None:
        need[0] = body  # a person (or a walk) starts exactly at its start
    clear = scene.clearance(cells)
    bad = np.flatnonzero(clear <= need)
    if bad.size:
        k = int(bad[0])
        who = "the leader" if k == 0 else f"follower {k}"
        rule = ("person_radius" if k == 0 and body is not None
                else "robot_radius + init_jitter·√2")
        raise ValueError(
            f"the start does not fit scene {scene.name!r}: {who} would start at "
            f"({cells[k][0]:.2f}, {cells[k][1]:.2f}), {max(clear[k], 0.0):.3f} m from "
            f"{scene.nearest_name(cells[k])}; it needs more than {need[k]:.3f} m ({rule}): "
            f"{_start_advice(sc, k)}")
    if path is None:
        return
    blocked, which = scene.blocked(path[:-1], path[1:], w.robot_radius)
    what = sc.leader_kind.path_words(sc)
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
