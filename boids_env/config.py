"""Frozen, validated configuration of the environment and of the Reynolds controller.

Every default is a number from the study (Akgun, "Development of Leader Following, Boids Inspired
Algorithm Using ROS") unless its docstring says otherwise; the README lists them.
Bad values raise ``ValueError`` naming the field, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from boids_env.checks import flag as _flag
from boids_env.checks import integer as _integer
from boids_env.checks import number as _number
from boids_env.checks import set_field as _set
from boids_env.layout import follower_cells
from boids_env.realism import RealismConfig
from boids_env.vectors import times_matrix

FRAMES = ("world", "leader")
"""Observation (and action) frames: the study's world frame, or the leader's heading frame
(opt-in; see :mod:`boids_env.observations`)."""
LEADER_MAX_SPEED = 2.0
"""Fastest leader (m/s): the bound of ``leader_speed`` and of an external leader's command."""
CURVE_SPEED_FACTOR = 1.5
"""A curve-following leader may command up to this × ``leader_speed`` to regain its path."""
PATHS = ("square", "circle", "figure_eight", "waypoints", "random_waypoints", "external")
"""Leader paths. ``square`` is the paper's; the others are opt-in (DESIGN section 2)."""


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


@dataclass(frozen=True)
class ScenarioConfig:
    """Group size, initial layout, leader path and episode end (DESIGN sections 2 and 6)."""

    robots: int = 13
    """Group size, the leader included, as the study counts it (study: 7, 13, 19)."""
    leader_speed: float = 0.55
    """Leader speed along its path (m/s). Study: 0.5, 0.55 (default), 0.6."""
    path: str = "square"
    """Leader path, one of PATHS. ``square`` is the paper's; the others are opt-in."""
    path_size: float = 4.0
    """Half extent of the leader path (m). 4.0 gives the paper's square exactly; the circle's
    diameter, the figure-eight's length and the random waypoints' box scale with it."""
    path_rotation: float = 0.0
    """Rotation (degrees, counter-clockwise about the leader's start) of the leader path and of
    the initial layout: the whole scene turned. 0 is the study's. Opt-in, for robustness."""
    path_mirror: bool = False
    """Mirror the leader path and the initial layout in x before the rotation (the square then
    turns right at its first corner). False is the study's."""
    waypoints: tuple[tuple[float, float], ...] = ()
    """Absolute targets (m) for ``path="waypoints"``; ignored by the other paths."""
    laps: int = 1
    """Laps of the circle and figure-eight paths."""
    random_waypoint_count: int = 6
    """Number of targets drawn for ``path="random_waypoints"``."""
    arrival_margin: float = 0.1
    """A leader move ends when within this distance of its target (m). Paper: 0.1 m."""
    startup_time: float = 2.0
    """Time (s) the leader waits after reset before moving; the Reynolds followers hold still as
    long. Paper: 2.0 s."""
    startup_hold: bool = False
    """Hold every follower still (command zero) for ``startup_time`` whatever the policy
    asks, as the study's controller did at its start-up. Off by default: the Reynolds policy
    holds by itself; learned policies trained with it carry it in their env fields."""
    tail_time: float = 0.5
    """Time (s) the episode goes on after the leader finishes its path; 0.5 s makes the paper's
    case last 74.6 s, the study's T (the leader's own acceleration at the corners and the
    0.1 s control period add about 1.2 s to the path's nominal 70.9 s)."""
    max_cycles: int | None = None
    """Hard step limit (truncation). None: 3× the path's nominal duration, or 1000 steps for the
    ``external`` leader."""
    init_jitter: float = 0.05
    """Half width (m) of the uniform, seeded jitter added to every follower's initial grid
    position, so that seeds give different runs (the study's runs differed through ROS timing)."""
    layout_spacing: float = 0.5
    """Spacing (m) of the initial grid behind the leader. Paper: 0.5 m."""

    def __post_init__(self) -> None:
        _set(self, "robots", _integer("robots", self.robots, 2, 10_000))
        _set(self, "leader_speed", _number("leader_speed", self.leader_speed, 0.0,
                                           LEADER_MAX_SPEED, lo_open=True, unit="m/s"))
        if self.path not in PATHS:
            raise ValueError(f"path must be one of {PATHS}, got {self.path!r}")
        _set(self, "path_size", _number("path_size", self.path_size, 0.0, 1000, lo_open=True,
                                        unit="m"))
        _set(self, "path_rotation", _number("path_rotation", self.path_rotation, -360, 360,
                                            unit="degrees"))
        if not isinstance(self.path_mirror, bool):
            raise ValueError(f"path_mirror must be True or False, got {self.path_mirror!r}")
        _set(self, "waypoints", _waypoints(self.waypoints))
        if self.path == "waypoints" and not self.waypoints:
            raise ValueError("waypoints must hold at least one (x, y) target when "
                             "path='waypoints', got ()")
        _set(self, "laps", _integer("laps", self.laps, 1, 1000))
        _set(self, "random_waypoint_count",
             _integer("random_waypoint_count", self.random_waypoint_count, 1, 1000))
        _set(self, "arrival_margin", _number("arrival_margin", self.arrival_margin, 0.0, 1.0,
                                             lo_open=True, unit="m"))
        _set(self, "startup_time", _number("startup_time", self.startup_time, 0.0, 600, unit="s"))
        if not isinstance(self.startup_hold, bool):
            raise ValueError(f"startup_hold must be True or False, got {self.startup_hold!r}")
        _set(self, "tail_time", _number("tail_time", self.tail_time, 0.0, 600, unit="s"))
        if self.max_cycles is not None:
            _set(self, "max_cycles", _integer("max_cycles", self.max_cycles, 1, 10**9))
        _set(self, "init_jitter", _number("init_jitter", self.init_jitter, 0.0, 0.2, unit="m"))
        _set(self, "layout_spacing", _number("layout_spacing", self.layout_spacing, 0.1, 10,
                                             unit="m"))


def _waypoints(value: Any) -> tuple[tuple[float, float], ...]:
    try:
        points = tuple((float(p[0]), float(p[1])) for p in value)
        if any(len(p) != 2 for p in value):
            raise ValueError
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"waypoints must be a sequence of (x, y) pairs in metres, "
                         f"got {value!r}") from None
    if not all(math.isfinite(c) for p in points for c in p):
        raise ValueError(f"waypoints must be finite, got {value!r}")
    return points


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
    """Append a wall slot: the offset (m) to the nearest point of the walls and a valid flag,
    when a wall is within ``horizon`` (zeros otherwise). Opt-in: the study's followers sensed
    only robots."""
    frame: str = "world"
    """Frame of observations and actions, one of FRAMES: ``world`` (the study's) or
    ``leader`` (x along the leader's heading, y to its left; opt-in, for policies that should
    learn a formation relative to the leader)."""
    relative_actions: bool = False
    """Read each follower's action as a velocity relative to the leader's velocity as that
    follower observes it (noise included): the command is the observed leader velocity plus
    the action, in ``frame``, and the action space widens to ±2·``max_speed`` so that any
    command stays reachable. Opt-in, for learned policies (a zero action matches the leader's
    speed on any path and at any speed); a policy that outputs absolute velocities, like the
    Reynolds controller, needs it off."""

    def __post_init__(self) -> None:
        _set(self, "horizon", _number("horizon", self.horizon, 0.0, 100, lo_open=True, unit="m"))
        _set(self, "neighbours", _integer("neighbours", self.neighbours, 0, 1024))
        _set(self, "velocity_bound", _number("velocity_bound", self.velocity_bound, 0.0, 100,
                                             lo_open=True, unit="m/s"))
        _set(self, "obs_noise", _number("obs_noise", self.obs_noise, 0.0, 10.0, unit="m, m/s"))
        _set(self, "sense_walls", _flag("sense_walls", self.sense_walls))
        _set(self, "relative_actions", _flag("relative_actions", self.relative_actions))
        if self.frame not in FRAMES:
            raise ValueError(f"frame must be one of {FRAMES}, got {self.frame!r}")


REWARDS = ("study", "safe")
"""Reward presets: ``study`` (the study's three violations only, the default) and ``safe``
(adds penalties for crowding, contact and walls; see :data:`SAFE_WEIGHTS`)."""
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
        for name in ("reward_separation", "reward_cohesion", "reward_alignment", "reward_gap"):
            _set(self, name, _number(name, getattr(self, name), 0.0, 1000))
        if self.separation_threshold >= self.cohesion_threshold:
            raise ValueError(f"separation_threshold ({self.separation_threshold} m) must be "
                             f"below cohesion_threshold ({self.cohesion_threshold} m)")
        if self.reward not in REWARDS:
            raise ValueError(f"reward must be one of {REWARDS}, got {self.reward!r}")
        for name in SAFE_WEIGHTS:
            if getattr(self, name) is not None:
                _set(self, name, _number(name, getattr(self, name), 0.0, 1000))
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
             "metrics": MetricsConfig, "realism": RealismConfig}
FIELD_OWNER: dict[str, str] = {f.name: sec for sec, cls in _SECTIONS.items() for f in fields(cls)}
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
    """Opt-in ROS/Stage realism (:mod:`boids_env.realism`); off by default."""

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
        """Returns a copy with the named flat fields changed (validated)."""
        unknown = sorted(set(kwargs) - set(FIELD_OWNER))
        if unknown:
            raise TypeError(f"unknown config field(s) {unknown}; valid fields: "
                            f"{sorted(FIELD_OWNER)}")
        changes: dict[str, dict[str, Any]] = {}
        for name, value in kwargs.items():
            changes.setdefault(FIELD_OWNER[name], {})[name] = value
        sections = {sec: dataclasses.replace(getattr(self, sec), **chg)
                    for sec, chg in changes.items()}
        return dataclasses.replace(self, **sections)

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
        return cls.from_kwargs(**flat)


def scene_matrix(scenario: ScenarioConfig) -> np.ndarray:
    """The matrix T (2, 2) of ``path_rotation`` and ``path_mirror``: world = T @ local."""
    a = math.radians(scenario.path_rotation)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return rot * np.array([-1.0 if scenario.path_mirror else 1.0, 1.0])  # rot @ diag, exact


def layout_extent(scenario: ScenarioConfig) -> float:
    """Largest |coordinate| (m) an initial position can take, jitter included."""
    cells = times_matrix(follower_cells(scenario.robots, scenario.layout_spacing),
                         scene_matrix(scenario).T)
    return float(np.abs(cells).max(initial=0.0)) + scenario.init_jitter


def path_extent(scenario: ScenarioConfig) -> float:
    """Largest |coordinate| (m) the leader's path can reach (0 for an external leader): the
    corners of the path's bounding box in its own frame, turned into the world."""
    s = scenario.path_size
    if scenario.path == "waypoints":
        points = np.array(scenario.waypoints)
    elif scenario.path == "external":
        return 0.0
    else:
        box = {"square": (-s, s, -s, s), "random_waypoints": (-s, s, -s, s),
               "circle": (-s, 0.0, -s / 2, s / 2), "figure_eight": (-s / 2, s / 2, -s, s)}
        x0, x1, y0, y1 = box[scenario.path]
        points = np.array([[x0, y0], [x0, y1], [x1, y0], [x1, y1]])
    return float(np.abs(times_matrix(points, scene_matrix(scenario).T)).max())


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
    return max(follower, leader)


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
    """Raises ``ValueError`` if the initial layout or the leader path leaves the arena, or the
    physics cannot hold (see ``_check_physics``)."""
    _check_physics(config)
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


@dataclass(frozen=True)
class ReynoldsParams:
    """Parameters of the Reynolds + leader controller (DESIGN section 3)."""

    separation_weight: float = 1.0
    cohesion_weight: float = 1.0
    alignment_weight: float = 1.0
    leader_weight: float = 1.0
    """Weight of the leader-following term. Study: 1.0, 1.1, 1.2."""
    horizon: float = 1.0
    """Neighbour radius (m). Paper 1.0, original code 0.75."""
    desired_separation: float = 0.7
    """Neighbours closer than this push away (m). Paper 0.7, original code 0.45."""
    max_speed: float = 0.5
    """Commanded speed limit (m/s)."""
    max_force: float = 0.23
    """Steering force limit (N); not stated in the paper, the original code's 0.23."""
    mass: float = 0.18
    """Mass (kg) used to integrate the steering force."""
    dt: float = 0.1
    """Control period (s)."""
    startup_time: float = 2.0
    """Zero command for this long after reset (s)."""

    def __post_init__(self) -> None:
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
}
"""Named controller parameter sets (DESIGN section 3); ``paper`` is the default."""


def reynolds_params(preset: str = "paper", **overrides: Any) -> ReynoldsParams:
    """Returns the named preset with ``overrides`` applied (validated)."""
    if preset not in PRESETS:
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {preset!r}")
    valid = {f.name for f in fields(ReynoldsParams)}
    unknown = sorted(set(overrides) - valid)
    if unknown:
        raise TypeError(f"unknown Reynolds parameter(s) {unknown}; valid: {sorted(valid)}")
    return dataclasses.replace(PRESETS[preset], **overrides)
