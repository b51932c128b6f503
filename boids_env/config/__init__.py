"""Frozen, validated configuration of the environment: one section per concern (world,
scenario, observation, metrics, realism, safety), composed by :class:`EnvConfig`, and the
checks across sections (the physics, the start and the path against the scene).

Every default is a number from the study (Akgun, "Development of Leader Following, Boids Inspired
Algorithm Using ROS") unless its docstring says otherwise; the docs' configuration reference
lists them.
Bad values raise ``ValueError`` naming the field, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from boids_env.checks import integer as _integer
from boids_env.checks import number as _number
from boids_env.config.clock import check_clock
from boids_env.config.metrics import ALIGNMENT_SOURCES as ALIGNMENT_SOURCES
from boids_env.config.metrics import REWARDS as REWARDS
from boids_env.config.metrics import SAFE_WEIGHTS as SAFE_WEIGHTS
from boids_env.config.metrics import MetricsConfig
from boids_env.config.observation import FRAMES as FRAMES
from boids_env.config.observation import ObservationConfig
from boids_env.config.world import MAX_SPEED_RANGE as MAX_SPEED_RANGE
from boids_env.config.world import WorldConfig
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

# The range checks live in boids_env.checks (shared with the realism section); these names are
# kept for the other packages' configs (e.g. train.config).
check_number = _number
check_integer = _integer


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
        # a class is hashable; mypy checks a type[...] against Hashable with its instances'
        # __hash__ (python/mypy#20409)
        return _default_config(cls).replace(**kwargs)  # type: ignore[arg-type]

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
        if self.scenario.crowd_file is not None:
            from pathlib import Path

            files.append(Path(self.scenario.crowd_file).resolve())
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
        replayed = self.scenario.crowd_file is not None
        return DEFAULT_PEDESTRIAN_SLOTS if self.scenario.crowd or replayed else 0

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
            f"start {tuple(given)} cannot be given with leader={sc.leader!r}: {fixed} at its "
            f"first row ({sc.start[0]:g}, {sc.start[1]:g}); drop start (boids run: --start), "
            f"or record a walk that starts where you want")


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
    from boids_env.world.robots import ROBOT_PRESETS, scaled_scenario

    name = kwargs["robot"]
    if not isinstance(name, str) or name not in ROBOT_PRESETS:
        return {}
    fields = ROBOT_PRESETS[name].fields()
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
    if sc.crowd_file is not None:
        from boids_env.world.crowd_replay import max_replay_speed

        fastest = max_replay_speed(sc)
        out.append((fastest, f"the replayed crowd {sc.crowd_file} ({fastest:.3g} m/s at "
                             f"most)"))
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
    check_clock(config)
    scene = config.scene
    key = (config.world, config.scenario, id(scene))
    if key in _FITTED:
        return  # this world and scenario were checked against this scene already
    if config.world.scene == "arena" and config.scenario.start == (0.0, 0.0):
        _check_arena_extents(config)
    _check_scene(config)
    if config.scenario.crowd and importlib.util.find_spec("shapely") is not None:
        from boids_env.world.people import check_crowd_fits  # (the people extra)

        check_crowd_fits(scene, config.scenario.crowd, config.scenario.person_radius)
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
    at = f"({sc.start[0]:g}, {sc.start[1]:g})"
    if k == 0:
        return f"{fixed} {at}: use one that starts in free space or another scene"
    return f"{fixed} {at}: change start_heading (the grid lies behind it), {grid}"


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
