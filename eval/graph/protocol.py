"""What the simulator and controller nodes agree on, as plain Python (no ROS needed).

**Topics** (the study's): ``/robot_k/odom`` (nav_msgs/Odometry, frame ``map``, child frame
``robot_k``; position and measured velocity, world frame, identity orientation: the Spheros are
holonomic), ``/robot_k/cmd_vel`` (geometry_msgs/Twist, world frame), ``/tf`` (``map`` →
``robot_k``), ``/clock``; robot 0 is the leader. Robots with a heading (``drive="unicycle"``,
e.g. ``robot="turtlebot3_burger"``) speak as a TurtleBot3 does: odometry oriented along the
heading with the twist in the child frame (linear.x forward, angular.z the turn rate; REP 105)
and ``cmd_vel`` in the robot's own frame (linear.x, angular.z).

**Time.** The simulator is the clock (``/use_sim_time`` true), as Stage was. Tick k of an
episode is stamped ``start + k·dt``. The clock starts at :data:`CLOCK_START` (ROS reads time 0
as "no clock yet": ``rosbag record`` would wait, and refuses to write a message at time 0) and,
while the simulator waits for its controller (and ``--wait-for`` nodes) before the first tick,
runs at real time in steps of ``dt``, as Stage's clock runs before anything moves: sim-time
nodes such as ``rosbag record -a`` need it to advance to find topics advertised after they
started. Every later episode starts :data:`EPISODE_GAP` after the previous one ended. Every
robot's odometry of one tick carries the same stamp.

**Lockstep protocol** (``boids ros sim --lockstep``). The simulator publishes a tick's
odometry, then waits until every follower has sent one command *after* that publication, then
steps. The controller answers every tick exactly once, in order. ROS keeps the messages of one
connection in order, so a command that arrives between the publication of tick k and of tick
k+1 is the answer to tick k: no stamp is needed on the Twist (the study's message). Odometry is
latched, so a controller (or recorder) that connects late still receives the current tick.

**Real time** (the default, like Stage). Every ``dt`` of wall time the simulator applies each
follower's latest command and steps; a command older than ``cmd_timeout``
(:data:`CMD_TIMEOUT`, 0.5 s) is replaced by zero, as a real robot driver stops a robot whose
controller went silent.

**Episodes.** Before tick 0 of every episode the simulator sets :data:`EPISODE_PARAM` (index,
seed, the stamp of tick 0, the leader's initial heading) and :data:`CONFIG_PARAM` holds its env
config; the controller reads them when the stamps jump (a new episode) and resets its policy.
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

CMD_TIMEOUT = 0.5
"""Seconds (wall, at real time) after which a follower without a new command gets (0, 0)."""
CLOCK_START = 1.0
"""Simulated time (s) of the first episode's tick 0 (ROS time 0 means "no clock")."""
EPISODE_GAP = 1.0
"""Simulated seconds between the end of an episode and tick 0 of the next."""
CONFIG_PARAM = "/boids/env_config"
"""Parameter: the simulator's env config, ``EnvConfig.to_dict()`` as a JSON string."""
EPISODE_PARAM = "/boids/episode"
"""Parameter: the current episode as a JSON string (see :class:`EpisodeInfo`)."""
QUEUE_SIZE = 1000
"""Publisher and subscriber queues: far more than one tick's messages, so a lockstep burst is
never dropped."""
MAP_FRAME = "map"
CONFIG_TOPIC = "/boids/env_config"
"""ROS 2 (no parameter server): the simulator's env config as a latched std_msgs/String, the
JSON of :data:`CONFIG_PARAM`."""
EPISODE_TOPIC = "/boids/episode"
"""ROS 2: the current episode as a latched std_msgs/String, the JSON of
:data:`EPISODE_PARAM`, published before the episode's tick 0."""


def odom_topic(robot: int) -> str:
    """``/robot_k/odom``."""
    return f"/robot_{robot}/odom"


def odometry_topics(robots: int, pedestrians: int = 0) -> list[str]:
    """Every robot's odometry topic, then every pedestrian's of a crowd: what a controller
    subscribes to (a tick waits for all of them)."""
    return ([odom_topic(k) for k in range(robots)]
            + [pedestrian_topic(k) for k in range(pedestrians)])


def pedestrian_topic(pedestrian: int) -> str:
    """``/pedestrian_k/odom``: pedestrian k of the crowd (nav_msgs/Odometry in ``map``, its
    velocity in the twist), what a people tracker reports and the followers observe."""
    return f"/pedestrian_{pedestrian}/odom"


def pedestrian_frame(pedestrian: int) -> str:
    """Pedestrian k's frame (its odometry's child frame), ``pedestrian_k``."""
    return f"pedestrian_{pedestrian}"


def cmd_topic(robot: int) -> str:
    """``/robot_k/cmd_vel``."""
    return f"/robot_{robot}/cmd_vel"


def robot_frame(robot: int) -> str:
    """The robot's tf frame (the odometry's child frame), ``robot_k``."""
    return f"robot_{robot}"


def odom_frame(robot: int) -> str:
    """REP 105: the robot's odometry frame, ``robot_k/odom`` (a child of ``map``)."""
    return f"robot_{robot}/odom"


def base_frame(robot: int) -> str:
    """REP 105: the robot's body frame on the ground, ``robot_k/base_footprint`` (a child of
    its odometry frame, as a TurtleBot3 names it)."""
    return f"robot_{robot}/base_footprint"


def period_ns(dt: float) -> int:
    """The control period in integer nanoseconds."""
    return round(dt * 1e9)


def stamp_ns(start_ns: int, tick: int, dt: float) -> int:
    """Stamp (ns) of ``tick`` in an episode whose tick 0 is at ``start_ns``: integer
    arithmetic, so ticks are exactly ``dt`` apart."""
    return start_ns + tick * period_ns(dt)


@dataclass(frozen=True)
class EpisodeInfo:
    """One episode as the simulator announces it in :data:`EPISODE_PARAM`."""

    index: int
    """0 for the first episode of a simulator run."""
    seed: int
    """The episode's seed (the controller resets its policy with it)."""
    start_ns: int
    """The stamp of tick 0 (ns)."""
    initial_heading: float
    """The leader's heading before it first moves (rad): the leader frame's start."""

    def to_json(self) -> str:
        return json.dumps({"index": self.index, "seed": self.seed, "start_ns": self.start_ns,
                           "initial_heading": self.initial_heading})

    @classmethod
    def from_json(cls, text: str) -> EpisodeInfo:
        """Parses :meth:`to_json`'s output; ``ValueError`` for anything else."""
        try:
            data = json.loads(text)
            return cls(int(data["index"]), int(data["seed"]), int(data["start_ns"]),
                       float(data["initial_heading"]))
        except (TypeError, KeyError, ValueError) as exc:
            raise ValueError(f"{EPISODE_PARAM} must be an episode JSON object, got {text!r}"
                             ) from exc


class CommandBoard:
    """The simulator's view of the followers' commands (thread-safe: ROS callbacks post, the
    simulation loop reads).

    Every command is kept with the *tick generation* it arrived in (:meth:`open_tick` starts a
    new one just before a tick is published) and its arrival time.

    Args:
        followers: number of followers (commands are indexed 0 … followers-1).
        timeout: seconds after which :meth:`latest` replaces a command by zero.
    """

    def __init__(self, followers: int, timeout: float = CMD_TIMEOUT) -> None:
        if followers < 1:
            raise ValueError(f"followers must be >= 1, got {followers}")
        if not (isinstance(timeout, int | float) and 0 < timeout <= 60):
            raise ValueError(f"timeout must be in (0, 60] s, got {timeout!r}")
        self.followers = followers
        self.timeout = float(timeout)
        self._cond = threading.Condition()
        self._values = np.zeros((followers, 2))
        self._generation = np.full(followers, -1)
        self._arrival = np.full(followers, -math.inf)
        self._current = 0
        self._episode_start = 0
        self.rejected = 0
        """Commands refused (not finite)."""
        self.extra = 0
        """Commands beyond the first one of a follower in one tick (lockstep diagnostics)."""

    def post(self, index: int, vx: float, vy: float, now: float) -> bool:
        """Records follower ``index``'s command received at ``now`` (s, monotonic); returns
        False (and counts it in :attr:`rejected`) for a non-finite one, which is dropped."""
        if not (math.isfinite(vx) and math.isfinite(vy)):
            self.reject()
            return False
        with self._cond:
            if self._generation[index] == self._current:
                self.extra += 1
            self._values[index] = (vx, vy)
            self._generation[index] = self._current
            self._arrival[index] = now
            self._cond.notify_all()
        return True

    def reject(self) -> None:
        """Counts a non-finite command dropped (a follower's, or the external leader's)."""
        with self._cond:
            self.rejected += 1

    def open_tick(self, new_episode: bool = False) -> None:
        """Starts a new generation: call it *before* publishing a tick, so every answer to it
        counts. ``new_episode`` also marks every earlier command as stale."""
        with self._cond:
            self._current += 1
            if new_episode:
                self._episode_start = self._current

    def missing(self) -> list[int]:
        """Followers without a command in the current generation."""
        with self._cond:
            return np.flatnonzero(self._generation != self._current).tolist()

    def wait_all(self, timeout: float) -> bool:
        """Waits up to ``timeout`` seconds until every follower has a command in the current
        generation; returns whether they all have."""
        with self._cond:
            return self._cond.wait_for(lambda: bool(np.all(self._generation == self._current)),
                                       timeout)

    def current(self) -> FloatArray:
        """(F, 2) the commands of the current generation (lockstep), zero where missing."""
        with self._cond:
            fresh = self._generation == self._current
            return np.where(fresh[:, None], self._values, 0.0)

    def latest(self, now: float) -> tuple[FloatArray, npt.NDArray[np.bool_],
                                          npt.NDArray[np.bool_]]:
        """(F, 2) each follower's latest command of this episode if it arrived at most
        ``timeout`` seconds before ``now``, else zero; which followers timed out; and which
        are applied stale (not an answer to the tick published last: a late controller)."""
        with self._cond:
            live = (self._generation >= self._episode_start) & (
                now - self._arrival <= self.timeout)
            stale = live & (self._generation != self._current)
            return np.where(live[:, None], self._values, 0.0), ~live, stale


@dataclass(frozen=True)
class Tick:
    """Every robot's odometry of one stamp."""

    stamp_ns: int
    positions: FloatArray
    """(N, 2) m, the leader first."""
    velocities: FloatArray
    """(N, 2) m/s, the twist's linear part as the odometry carries it: world frame for the
    study's robots, each robot's own frame for robots with a heading (REP 105)."""
    quaternions: FloatArray | None = None
    """(N, 2) the orientation's (z, w) (rotations about z)."""
    crowd_positions: FloatArray | None = None
    """(P, 2) m, the crowd's pedestrians (None without a crowd)."""
    crowd_velocities: FloatArray | None = None
    """(P, 2) m/s, world frame."""


class TickAssembler:
    """Collects the odometry of ``robots`` robots (in any order, from several threads) into
    :class:`Tick` objects: a tick is complete when every robot has reported the same stamp.

    Ticks are returned at most once and in increasing stamp order; a stamp not newer than the
    last one returned is dropped, unless a robot's own stamps go back (its source restarted),
    which starts over.

    With ``pedestrians`` (a crowd of P), sources ``robots … robots + P - 1`` are the
    pedestrians' odometry: a tick also waits for them, and carries them apart
    (:attr:`Tick.crowd_positions`).
    """

    def __init__(self, robots: int, pedestrians: int = 0) -> None:
        if robots < 2:
            raise ValueError(f"robots must be >= 2 (a leader and a follower), got {robots}")
        if isinstance(pedestrians, bool) or not isinstance(pedestrians, int) or pedestrians < 0:
            raise ValueError(f"pedestrians must be a non-negative integer, got {pedestrians!r}")
        self.robots = robots
        self.pedestrians = pedestrians
        self.sources = robots + pedestrians
        self._lock = threading.Lock()
        self._pending: dict[int, dict[int, tuple[float, ...]]] = {}
        self._last: int | None = None
        self._epochs: dict[int, int] = {}
        self._epoch = 0
        self.latest: dict[int, tuple[Any, ...]] = {}
        """Each robot's latest odometry (stamp, x, y, vx, vy, qz, qw), for :meth:`snapshot`."""

    def add(self, robot: int, stamp: int, x: float, y: float, vx: float, vy: float,
            qz: float = 0.0, qw: float = 1.0) -> Tick | None:
        """Records one odometry message (position, twist, orientation about z); returns the
        tick it completes, if any."""
        with self._lock:
            previous = self.latest.get(robot)
            if previous is not None and stamp < previous[0]:
                # One connection's messages arrive in order, so a robot whose stamps go
                # back has a restarted source (a new simulator, a replayed bag): it enters
                # a new epoch, and the first robot to do so starts the assembly over.
                self._epochs[robot] = self._epochs.get(robot, 0) + 1
            epoch = self._epochs.get(robot, 0)
            if epoch > self._epoch:
                self._epoch, self._last = epoch, None
                self._pending.clear()
            self.latest[robot] = (stamp, x, y, vx, vy, qz, qw)
            if epoch < self._epoch:
                return None  # from the source before its restart
            if self._last is not None and stamp <= self._last:
                return None  # a tick already returned, or one passed over
            entry = self._pending.setdefault(stamp, {})
            entry[robot] = (x, y, vx, vy, qz, qw)
            if len(entry) < self.sources:
                return None
            del self._pending[stamp]
            # older incomplete stamps can never complete in order: drop them
            self._pending = {k: v for k, v in self._pending.items() if k > stamp}
            self._last = stamp
            rows = np.array([entry[k] for k in range(self.sources)], dtype=np.float64)
            return self._tick(stamp, rows)

    def snapshot(self) -> Tick | None:
        """Every robot's latest odometry as one tick (stamped with the newest stamp), or None
        until every robot has reported once: for sources whose robots are not stamped
        together (``--sync rate``)."""
        with self._lock:
            if len(self.latest) < self.sources:
                return None
            rows = np.array([self.latest[k][1:] for k in range(self.sources)], dtype=np.float64)
            stamp = max(self.latest[k][0] for k in range(self.sources))
            return self._tick(stamp, rows)

    def _tick(self, stamp: int, rows: FloatArray) -> Tick:
        """A tick of rows (x, y, vx, vy, qz, qw): the robots', then the pedestrians'."""
        n = self.robots
        robots = rows[:n]
        if not self.pedestrians:
            return Tick(stamp, robots[:, :2], robots[:, 2:4], robots[:, 4:6])
        return Tick(stamp, robots[:, :2], robots[:, 2:4], robots[:, 4:6],
                    rows[n:, :2], rows[n:, 2:4])


def is_continuation(previous_ns: int | None, stamp_ns: int, dt: float) -> bool:
    """Whether ``stamp_ns`` is the tick right after ``previous_ns`` (``dt`` later, within half
    a period): anything else (the first tick, a jump, time going back) may be a new episode."""
    if previous_ns is None:
        return False
    gap = stamp_ns - previous_ns
    return abs(gap - dt * 1e9) < dt * 0.5e9


def config_json(config_dict: dict[str, Any]) -> str:
    """An env config dict as the JSON string of :data:`CONFIG_PARAM` (XML-RPC, the parameter
    server's transport, has no ``None``)."""
    return json.dumps(config_dict)


def finite_leader_command(vx: float, vy: float, previous: npt.NDArray[np.float64]
                          ) -> tuple[npt.NDArray[np.float64], bool]:
    """The external leader's command from a Twist on ``/robot_0/cmd_vel``: ``(vx, vy)``, or
    ``previous`` unchanged (and False) when either is not finite. A NaN from a joystick
    driver is dropped as a follower's is (:meth:`CommandBoard.post`), never stepped."""
    if not (math.isfinite(vx) and math.isfinite(vy)):
        return previous, False
    return np.array([vx, vy], dtype=np.float64), True


def finite_commands(commands: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], int]:
    """``commands`` (F, 2) with every row that holds a non-finite value set to zero (that
    robot stops), and how many rows were: a NaN odometry poisons the observations of every
    follower near it, and a NaN command must never go out on ``cmd_vel``."""
    bad = ~np.isfinite(commands).all(axis=1)
    if not bad.any():
        return commands, 0
    out = np.where(bad[:, None], 0.0, commands)
    return out, int(bad.sum())
