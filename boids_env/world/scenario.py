"""The scenario: group size, initial layout, leader path and episode end (its config section
and the pure geometry of starts and paths).

Initial positions are the study's grids of :mod:`~boids_env.world.layout` plus seeded jitter,
turned and placed at the leader's start; the episode's length follows from the path.
"""

from __future__ import annotations

import itertools
import math
import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.checks import integer as _integer
from boids_env.checks import number as _number
from boids_env.checks import set_field as _set
from boids_env.vectors import times_matrix
from boids_env.world.layout import PAPER_LAYOUTS, follower_cells, grid_cells
from boids_env.world.leader_kinds import LEADER_KINDS, LeaderKind, leader_kind

__all__ = ["CURVE_SPEED_FACTOR", "LEADERS", "LEADER_MAX_SPEED", "PAPER_LAYOUTS", "PATHS",
           "ScenarioConfig",
           "grid_cells", "holding", "initial_positions", "layout_extent", "layout_heading",
           "path_extent",
           "scene_matrix", "step_limit"]

LEADER_MAX_SPEED = 2.0
"""Fastest leader (m/s): the bound of ``leader_speed`` and of an external leader's command."""
CURVE_SPEED_FACTOR = 1.5
"""A curve-following leader may command up to this × ``leader_speed`` to regain its path."""
PATHS = ("square", "circle", "figure_eight", "waypoints", "random_waypoints", "external")
"""Leader paths. ``square`` is the paper's; the others are opt-in."""
LEADERS = tuple(LEADER_KINDS)
"""Who leads (the built-in kinds of :mod:`~boids_env.world.leader_kinds`): the study's robot
(default), a person walked by the pedestrian model along the path (opt-in), or a recorded
walk replayed from ``leader_trajectory`` (opt-in)."""



@dataclass(frozen=True)
class ScenarioConfig:
    """Group size, initial layout, leader path and episode end ."""

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
    """Absolute targets (m) for ``path="waypoints"``; ignored by the other paths. Given without
    ``path`` (to :meth:`EnvConfig.replace`, ``parallel_env``), they set ``path="waypoints"``."""
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
    start: tuple[float, float] = (0.0, 0.0)
    """Where the leader starts (m, world frame); the layout and the shaped paths (square,
    circle, figure-eight, random waypoints) move with it and turn about it. The study's:
    (0, 0). Scenes set their own."""
    start_heading: float | None = None
    """Direction (degrees, counter-clockwise from +x) the leader faces at the start; the
    grid lies behind it. None: the study's (+y, turned with ``path_rotation``) in the arena,
    the direction of the path's first target in any other scene."""
    leader_pauses: tuple[tuple[float, float], ...] = ()
    """Standstills of the leader: ``(when, how long)`` pairs in seconds, ``when`` counted in
    driving time since the start-up (earlier pauses not included), in increasing order. The
    leader commands zero for ``how long`` and then drives on where it stopped. Not in the
    study (its leader never stops): opt-in, for followers that must park around a leader who
    stands still. Not for the ``external`` leader."""

    leader: str = "robot"
    """Who leads, one of LEADERS: ``robot`` (the study's), ``person`` (a pedestrian walked by
    JuPedSim to the corners of ``path`` at ``leader_speed`` as preferred walking speed, with a
    varying gait and pauses; with ``path="external"`` the keyboard or a script walks it) or
    ``trajectory`` (a recorded walk, ``leader_trajectory``). A person is a kinematic disc of
    ``person_radius`` that robots collide with and cannot push. Opt-in."""
    leader_trajectory: str | None = None
    """The recorded walk for ``leader="trajectory"``: a CSV of ``t, x, y`` (s, m), its time the
    episode's; the leader starts at its first row (``start`` is set from it)."""
    person_radius: float = 0.22
    """Body radius (m) of the person and of the crowd's pedestrians (adults: 0.2-0.25 m)."""
    gait_variation: float = 0.15
    """Standard deviation of the person's speed factor around its preferred speed (relative;
    a slowly varying, seeded Ornstein-Uhlenbeck factor with a 2 s correlation time)."""
    goal_pause: float = 1.0
    """Mean time (s) the person stops at each corner of its path (drawn uniformly in
    [0, 2·goal_pause] per corner; not on curves)."""
    crowd: int = 0
    """Other pedestrians walking through the scene to random goals (0: none). Opt-in; they
    are moving obstacles for the robots (observations, range sensor, metrics)."""
    crowd_speed: float = 1.0
    """The pedestrians' preferred walking speed (m/s), each drawn within ±20 %."""
    crowd_file: str | None = None
    """A replayed crowd (opt-in): a pedestrian-dataset file, ETH/UCY's ``frame ped x y`` text
    or TrajNet++'s JSON lines (:mod:`~boids_env.world.crowd_files`), its pedestrians walking
    their recorded tracks (:mod:`~boids_env.world.crowd_replay`). Not with ``crowd`` > 0 nor
    with a person the pedestrian model walks."""
    crowd_format: str = "auto"
    """The crowd file's format: ``auto`` (a first line starting with ``{`` is TrajNet++),
    ``eth_ucy`` or ``trajnet``."""
    crowd_frame_step: float = 10.0
    """Frame numbers from one sample of the crowd file to the next (ETH/UCY: every 10th)."""
    crowd_rate: float = 2.5
    """Samples per second of the crowd file (ETH/UCY and TrajNet++: 2.5 Hz, 0.4 s)."""
    crowd_time: float = 0.0
    """The crowd file's time (s from its first frame) at the episode's start."""
    crowd_offset: tuple[float, float] = (0.0, 0.0)
    """Where the crowd file's origin lies in the world (m), after rotation and scale."""
    crowd_rotation: float = 0.0
    """Rotation (degrees, counter-clockwise about the file's origin) of the crowd file."""
    crowd_scale: float = 1.0
    """Scale of the crowd file's coordinates (1: metres; the file's unit in metres)."""

    def __post_init__(self) -> None:
        self._check_people()
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
        if not (_pair_sequence(self.start) and len(self.start) == 2):
            raise ValueError(f"start must be an (x, y) position in metres, got {self.start!r}")
        _set(self, "start", _waypoints((self.start,), "start")[0])
        if self.start_heading is not None:
            _set(self, "start_heading", _number("start_heading", self.start_heading, -360, 360,
                                                unit="degrees"))
        _set(self, "leader_pauses", _pauses(self.leader_pauses, self.path))


    def _check_people(self) -> None:
        """The person and crowd fields (``leader`` ... ``crowd_speed``); the leader kind's
        own checks, and the fields it fixes (a walk's start)."""
        kind = leader_kind(self.leader)
        _set(self, "person_radius", _number("person_radius", self.person_radius, 0.05, 0.5,
                                            unit="m"))
        _set(self, "gait_variation", _number("gait_variation", self.gait_variation, 0.0, 0.5))
        _set(self, "goal_pause", _number("goal_pause", self.goal_pause, 0.0, 60, unit="s"))
        _set(self, "crowd", _integer("crowd", self.crowd, 0, 500))
        _set(self, "crowd_speed", _number("crowd_speed", self.crowd_speed, 0.0, 2.0,
                                          lo_open=True, unit="m/s"))
        for name, value in kind.check(self).items():
            _set(self, name, value)
        self._check_replay()

    def _check_replay(self) -> None:
        """The replayed crowd's fields (``crowd_file`` ... ``crowd_scale``); the file is
        read and checked here, its path resolved."""
        from boids_env.world.crowd_files import CROWD_FORMATS

        if self.crowd_format not in CROWD_FORMATS:
            raise ValueError(f"crowd_format must be one of {CROWD_FORMATS}, got "
                             f"{self.crowd_format!r}")
        _set(self, "crowd_frame_step", _number("crowd_frame_step", self.crowd_frame_step,
                                               0.0, 10_000, lo_open=True))
        _set(self, "crowd_rate", _number("crowd_rate", self.crowd_rate, 0.0, 1000,
                                         lo_open=True, unit="Hz"))
        _set(self, "crowd_time", _number("crowd_time", self.crowd_time, 0.0, 86_400,
                                         unit="s"))
        if not (_pair_sequence(self.crowd_offset) and len(self.crowd_offset) == 2):
            raise ValueError(f"crowd_offset must be an (x, y) offset in metres, got "
                             f"{self.crowd_offset!r}")
        _set(self, "crowd_offset", _waypoints((self.crowd_offset,), "crowd_offset")[0])
        _set(self, "crowd_rotation", _number("crowd_rotation", self.crowd_rotation, -360, 360,
                                             unit="degrees"))
        _set(self, "crowd_scale", _number("crowd_scale", self.crowd_scale, 0.0, 100,
                                          lo_open=True))
        if self.crowd_file is None:
            return
        if not isinstance(self.crowd_file, str) or not self.crowd_file:
            raise ValueError(f"crowd_file must be the path of a crowd file (ETH/UCY or "
                             f"TrajNet++), got {self.crowd_file!r}")
        if self.crowd:
            raise ValueError(f"crowd_file replays a recorded crowd; give crowd=0 with it "
                             f"(got crowd={self.crowd})")
        if self.leader_kind.walks(self):
            raise ValueError(f"crowd_file: the pedestrian model walking leader="
                             f"{self.leader!r} would not see the replayed pedestrians; use "
                             f"leader='robot' or leader='trajectory' (a recorded walk)")
        from pathlib import Path

        from boids_env.world.crowd_replay import crowd_tracks

        _set(self, "crowd_file", str(Path(self.crowd_file).resolve()))
        crowd_tracks(self)  # read and checked now: a bad file is refused before anything

    @property
    def leader_kind(self) -> LeaderKind:
        """The leader's kind (:mod:`~boids_env.world.leader_kinds`): what every caller asks
        about who leads."""
        return LEADER_KINDS[self.leader]

    @property
    def leader_radius(self) -> float | None:
        """The leader's body radius (m) when it is not a robot (a person, a walk); None for
        the study's robot leader, which is a follower-sized robot."""
        return self.leader_kind.radius(self)


MAX_PAUSE = 3600.0
"""Longest leader pause, and latest pause start (s of driving time)."""


def _pauses(value: Any, path: str) -> tuple[tuple[float, float], ...]:
    """``leader_pauses`` as ((when, how long), ...): finite, when in [0, MAX_PAUSE] and
    increasing, how long in (0, MAX_PAUSE]; none for the external leader."""
    if _pair_sequence(value) and len(value) == 0:
        return ()
    pairs = _pause_pairs(value)
    for when, length in pairs:
        if not 0.0 <= when <= MAX_PAUSE or not 0.0 < length <= MAX_PAUSE:
            raise ValueError(f"leader_pauses must be (when, how long) pairs in seconds with "
                             f"when in [0, {MAX_PAUSE:g}] and how long in (0, {MAX_PAUSE:g}], "
                             f"got {value!r}")
    whens = [when for when, _ in pairs]
    if any(b <= a for a, b in itertools.pairwise(whens)):
        raise ValueError(f"leader_pauses must be in increasing order of when, got {value!r}")
    if path == "external":
        raise ValueError("leader_pauses do not apply to path='external' (its commands come "
                         "from outside); give () or another path")
    return pairs


def _pause_pairs(value: Any) -> tuple[tuple[float, float], ...]:
    try:
        return _waypoints(value, "leader_pauses")  # a sequence of finite number pairs
    except ValueError:
        raise ValueError(f"leader_pauses must be a sequence of (when, how long) pairs of "
                         f"finite numbers in seconds, got {value!r}") from None


def _waypoints(value: Any, name: str = "waypoints") -> tuple[tuple[float, float], ...]:
    """``value`` as ((x, y), ...) if it is a sequence of pairs of real numbers; a string is not
    a pair (``"34"`` is not (3, 4)) and strings, bools and complex numbers are not coordinates
    (``float()`` would take them)."""
    message = f"{name} must be a sequence of (x, y) pairs of numbers in metres, got {value!r}"
    if not _pair_sequence(value):
        raise ValueError(message)
    points = []
    for point in value:
        if not _pair_sequence(point) or len(point) != 2 or not all(_real(c) for c in point):
            raise ValueError(message)
        points.append((float(point[0]), float(point[1])))
    if not all(math.isfinite(c) for p in points for c in p):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return tuple(points)


def _pair_sequence(value: Any) -> bool:
    """A list, tuple or numpy array (not a string, bytes or mapping, which also iterate)."""
    return isinstance(value, list | tuple) or (isinstance(value, np.ndarray) and value.ndim >= 1)


def _real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


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




def initial_positions(scenario: ScenarioConfig, rng: np.random.Generator | None,
                      heading: float | None = None) -> npt.NDArray[np.float64]:
    """Initial positions (N, 2) in metres, the leader first at ``scenario.start``.

    The study's cells for N = 7, 13, 19 at 0.5 m spacing; the grid extension otherwise; turned
    with the path by ``path_rotation`` / ``path_mirror``, or, with ``heading`` (rad, the
    direction the leader faces), turned so that the grid lies behind the leader. Every
    follower gets a uniform jitter of ±``init_jitter`` per coordinate from ``rng``.
    """
    cells = follower_cells(scenario.robots, scenario.layout_spacing)
    if heading is not None:
        turn = rotation_matrix(heading - math.pi / 2)
        if scenario.path_mirror:
            turn = turn * np.array([-1.0, 1.0])  # turn @ diag(-1, 1), exact
        cells = times_matrix(cells, turn.T)
    elif scenario.path_rotation or scenario.path_mirror:
        cells = times_matrix(cells, scene_matrix(scenario).T)
    if rng is not None and scenario.init_jitter > 0:
        cells = cells + rng.uniform(-scenario.init_jitter, scenario.init_jitter, cells.shape)
    positions = np.concatenate([np.zeros((1, 2)), cells])
    start = np.asarray(scenario.start, dtype=float)
    return positions + start if np.any(start != 0.0) else positions


def rotation_matrix(angle: float) -> npt.NDArray[np.float64]:
    """The matrix (2, 2) turning vectors by ``angle`` (rad) counter-clockwise."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def layout_heading(scenario: ScenarioConfig, scene_name: str,
                   reference_path: npt.NDArray[np.float64] | None) -> float | None:
    """The direction (rad) the initial grid faces: ``start_heading``; None (the study's rule,
    the grid behind in −y turned with the path) in the study's arena; else the direction from
    the start to the path's first distinct point."""
    if scenario.start_heading is not None:
        return math.radians(scenario.start_heading)
    if scene_name == "arena" or reference_path is None:
        return None
    offsets = reference_path - np.asarray(scenario.start, dtype=float)
    far = np.flatnonzero(np.hypot(offsets[:, 0], offsets[:, 1]) > 1e-9)
    if not len(far):
        return None
    dx, dy = offsets[far[0]]
    return math.atan2(dy, dx)


def holding(time: float, startup_time: float) -> bool:
    """Whether the followers are held still at episode time ``time`` (s): the first
    ``startup_time`` seconds after reset, the study's start-up. The one rule of the
    env's ``startup_hold``, the ROS controller's and the Reynolds policy's hold."""
    return time < startup_time - 1e-9


def step_limit(scenario: ScenarioConfig, nominal_path_time: float | None, dt: float) -> int:
    """Hard step limit: ``max_cycles`` if set, else 3× the nominal episode (1000 steps for an
    external leader, whose path never ends)."""
    if scenario.max_cycles is not None:
        return scenario.max_cycles
    if nominal_path_time is None:
        return 1000
    nominal = scenario.startup_time + nominal_path_time + scenario.tail_time
    # the config refuses a limit past MAX_STEPS (boids_env.config.clock); the bound here
    # only keeps a random path a little longer than that check's from overflowing
    return max(1, math.ceil(min(3 * nominal / dt, 10**9)))
