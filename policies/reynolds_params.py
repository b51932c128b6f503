"""The Reynolds controller's parameters, their presets and their binding to an env.

:class:`ReynoldsParams` holds the controller's own choices (weights, distances, forces, the
beyond-the-study rules); :data:`PRESETS` names the study's sets and ours. Two of its fields are
physical quantities the env owns too (:data:`ENV_OWNED`: the sensing ``horizon``, the robots'
``max_speed``): a bound controller takes the env's unless it sets its own, at most the env's
(:func:`bound_params`). Its timing, the control period and the start-up hold, is the env's
alone (:class:`Timing`, read at binding).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

from boids_env.checks import flag as _flag
from boids_env.checks import number as _number
from boids_env.checks import set_field as _set
from boids_env.config import FIELD_OWNER, MAX_SPEED_RANGE, EnvConfig, ScenarioConfig, WorldConfig


class Timing(NamedTuple):
    """The env's timing a controller acts on: read from the env it is bound to."""

    dt: float
    """The control period (s)."""
    startup_time: float
    """The followers are held still this long after reset (s)."""

    @classmethod
    def of(cls, config: EnvConfig) -> Timing:
        """The timing of an env of ``config``."""
        return cls(config.world.dt, config.scenario.startup_time)


DEFAULT_TIMING = Timing(WorldConfig.dt, ScenarioConfig.startup_time)
"""An unbound controller's timing: the study's (the env config's defaults, 10 Hz and 2 s)."""


class Range(NamedTuple):
    """The allowed values of a numeric parameter."""

    low: float
    high: float
    low_open: bool = False
    unit: str = ""


RANGES: dict[str, Range] = {
    "separation_weight": Range(0.0, 100), "cohesion_weight": Range(0.0, 100),
    "alignment_weight": Range(0.0, 100), "leader_weight": Range(0.0, 100),
    "horizon": Range(0.0, 100, True, "m"), "desired_separation": Range(0.0, 100, unit="m"),
    "max_speed": Range(*MAX_SPEED_RANGE, True, "m/s"), "max_force": Range(0.0, 1000, True, "N"),
    "mass": Range(0.0, 100, True, "kg"), "obstacle_weight": Range(0.0, 100),
    "obstacle_distance": Range(0.0, 10, True, "m"), "obstacle_lookahead": Range(0.0, 60, unit="s"),
    "personal_space": Range(0.0, 5.0, unit="m"), "robot_avoidance": Range(0.0, 5.0, unit="m"),
    "path_width": Range(0.0, 5, unit="m"), "path_time": Range(0.0, 60, unit="s"),
    "path_flee": Range(0.0, 100), "path_speed": Range(0.0, 5, True, "m/s"),
}
"""The range of every numeric field of :class:`ReynoldsParams` (its one check, which the
reference page and the live panels read too)."""
class Tunable(NamedTuple):
    """A parameter the live window's keys and the ROS controller's panel change."""

    step: float
    """One key press's change (the live window)."""
    text: str
    """Its description (the panel's)."""
    key: str | None = None
    """The live window's key that selects it (None: the panel only)."""
    low: float | None = None
    """The panel's minimum where the range's lower bound is open (a small positive value)."""
    sensed: bool = False
    """Its maximum is the observations' sensing horizon, not its range's."""


TUNABLE: dict[str, Tunable] = {
    "separation_weight": Tunable(0.1, "weight of the separation rule", "1"),
    "cohesion_weight": Tunable(0.1, "weight of the cohesion rule", "2"),
    "alignment_weight": Tunable(0.1, "weight of the alignment rule", "3"),
    "leader_weight": Tunable(0.1, "weight of the leader term (study: 1.0, 1.1, 1.2)", "4"),
    "horizon": Tunable(0.05, "neighbour radius (m), up to the sensing horizon", "5", 0.01,
                       sensed=True),
    "desired_separation": Tunable(0.05, "neighbours closer than this push away (m)", "6"),
    "max_speed": Tunable(0.01, "commanded speed limit (m/s)", low=0.01),
    "max_force": Tunable(0.001, "steering force limit (N)", low=0.001),
}
"""What may be tuned while a flock runs, and how (:data:`RANGES` bounds each)."""


def tunable_range(name: str, sensing_horizon: float) -> tuple[float, float]:
    """The (min, max) a panel offers for tunable ``name``: its range (an open lower bound as
    the tunable's small positive ``low``; the horizon's maximum the sensing horizon)."""
    r, t = RANGES[name], TUNABLE[name]
    low = t.low if r.low_open and t.low is not None else r.low
    return float(low), float(sensing_horizon if t.sensed else r.high)


FLAGS = ("follow_route", "scale_to_robot", "walls_first")
"""Its on/off fields (``obstacle_avoidance`` is a flag or None: automatic)."""


@dataclass(frozen=True)
class ReynoldsParams:
    """Parameters of the Reynolds + leader controller (the study's Table IV, docs:
    explanation/study). Its timing (the control period, the start-up hold) is not among
    them: the controller reads it from the env it is bound to (:class:`Timing`)."""

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
        for name in FLAGS:
            _set(self, name, _flag(name, getattr(self, name)))
        for name, r in RANGES.items():
            _set(self, name, _number(name, getattr(self, name), r.low, r.high,
                                     lo_open=r.low_open, unit=r.unit))


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
"""Named controller parameter sets (docs: explanation/study); ``paper`` is the default."""


ENV_OWNED = tuple(f.name for f in fields(ReynoldsParams) if f.name in FIELD_OWNER)
"""Reynolds parameters that are physical quantities of the env too (``horizon``,
``max_speed``): the env's config owns them. A suite routes them to the env (every policy's
episodes see them); a policy bound to an env takes them from its config unless it sets its
own (:func:`bound_params`)."""
UNITS = {"max_speed": "m/s", "horizon": "m"}


def env_quantities(config: EnvConfig) -> dict[str, float]:
    """The values of :data:`ENV_OWNED` in ``config``: its sensing horizon (m) and robots' top
    speed (m/s), by Reynolds parameter name."""
    return {name: getattr(getattr(config, FIELD_OWNER[name]), name) for name in ENV_OWNED}


TIMING_FIELDS = frozenset(Timing._fields)
"""The env's timing fields (``dt``, ``startup_time``): never the controller's own."""


def reynolds_params(preset: str = "paper", **overrides: Any) -> ReynoldsParams:
    """Returns the named preset with ``overrides`` applied (validated)."""
    if preset not in PRESETS:
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {preset!r}")
    timing = sorted(TIMING_FIELDS & set(overrides))
    if timing:
        raise TypeError(f"{', '.join(timing)}: the env's timing, not a Reynolds parameter (a "
                        f"bound controller acts at the env's control period and start-up): "
                        f"give {' and '.join(timing)} to the env (--set {timing[0]}=...)")
    valid = {f.name for f in fields(ReynoldsParams)}
    unknown = sorted(set(overrides) - valid)
    if unknown:
        raise TypeError(f"unknown Reynolds parameter(s) {unknown}; valid: {sorted(valid)}")
    return dataclasses.replace(PRESETS[preset], **overrides)


def bound_params(params: ReynoldsParams, own: frozenset[str] | set[str], config: EnvConfig
                 ) -> ReynoldsParams:
    """``params`` bound to an env of ``config``: every quantity the env owns taken from it,
    except those in ``own`` (the controller's own choice, at most the env's: it cannot
    command faster than the robots go nor see farther than the sensors). A controller value
    above the env's is a ``ValueError`` naming both values."""
    changes = {}
    for name, value in env_quantities(config).items():
        mine = getattr(params, name)
        if name in own and mine > value:
            unit = UNITS[name]
            raise ValueError(
                f"the Reynolds policy's {name}={mine:g} {unit} conflicts with the env's "
                f"{name}={value:g} {unit}: bound to an env, the policy's {name} must be at "
                f"most the env's; give {name} to the env (--set {name}={mine:g}, a suite "
                f"field) or leave it out of the policy's parameters")
        if name not in own and mine != value:
            changes[name] = value
    return dataclasses.replace(params, **changes) if changes else params


STUDY_RADIUS = 0.036
"""The study's Sphero's radius (m): the size the distances of a preset are given for."""


def turn_time(world: WorldConfig) -> float:
    """Seconds a robot of config section ``world`` needs to turn a quarter turn from rest
    (its drive's answer: π/2 at its top turn rate plus the ramp to it for a unicycle; 0 for a
    holonomic robot, which needs no turn to change its direction of motion)."""
    return world.drive_model.quarter_turn_time(world)


def sized_params(params: ReynoldsParams, radius: float, turn: float = 0.0,
                 sized_for: tuple[float, float] = (STUDY_RADIUS, 0.0)) -> ReynoldsParams:
    """``params``, whose distances are for robots of radius ``sized_for[0]`` and look-ahead
    for robots turning a quarter turn in ``sized_for[1]`` s (the study's holonomic Sphero
    unless given), sized for robots of ``radius`` (m) that turn in ``turn`` s
    (``scale_to_robot``, :func:`turn_time`): centre-to-centre distances
    (``desired_separation``, ``personal_space`` when on) 2·Δradius longer, the
    centre-to-surface ``obstacle_distance`` Δradius longer, so the free gaps stay the same,
    and the ``obstacle_lookahead`` and the leader's path ahead (``path_time``) Δturn longer,
    so a robot that must turn before it can steer away starts that much earlier; the
    ``personal_space`` also grows by ``max_speed`` × Δturn, the way a leader at the robots'
    top speed comes while a follower turns to step aside. The strip's half-width
    ``path_width`` (when on) is centre to centre: 2·Δradius wider. ``params`` itself for the
    same robot."""
    grow = radius - sized_for[0]
    slower = turn - sized_for[1]
    if grow == 0.0 and slower == 0.0:
        return params
    return dataclasses.replace(
        params, desired_separation=max(params.desired_separation + 2 * grow, 0.0),
        personal_space=max(params.personal_space + 2 * grow + params.max_speed * slower, 0.0)
        if params.personal_space else 0.0,
        obstacle_distance=max(params.obstacle_distance + grow, 1e-3),
        obstacle_lookahead=max(params.obstacle_lookahead + slower, 0.0),
        path_width=max(params.path_width + 2 * grow, 0.0) if params.path_width else 0.0,
        path_time=max(params.path_time + slower, 0.0))


@functools.lru_cache(maxsize=16)
def within(p: ReynoldsParams, distance: float) -> ReynoldsParams:
    """``p`` with ``obstacle_distance`` set to ``distance`` (cached: built once per policy)."""
    return dataclasses.replace(p, obstacle_distance=distance)
