"""The simulator node's logic, transport-free: the pymunk world
(:class:`~boids_env.environment.BoidsEnv`) stepped tick by tick, each tick handed to a
:class:`SimTransport` to publish, the followers' commands collected on a
:class:`~boids_env.eval.graph.protocol.CommandBoard` (lockstep or real time).

Each episode's samples are recorded exactly as ``boids run`` records them, so its metrics,
``metrics.json`` and ``trajectory.parquet`` are those of an in-process run given the same
commands. ``boids ros sim`` (ROS 1) and ``boids ros2 sim`` (ROS 2 over Zenoh) are this loop
under two transports.
"""

from __future__ import annotations

import copy
import json
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from boids_env.environment import BoidsEnv
from boids_env.eval.graph.malformed import Counts, since
from boids_env.eval.graph.protocol import (
    CLOCK_START,
    CMD_TIMEOUT,
    EPISODE_GAP,
    CommandBoard,
    EpisodeInfo,
    cmd_topic,
    finite_leader_command,
    odometry_topics,
    period_ns,
    stamp_ns,
)
from boids_env.eval.run import metrics_table
from boids_env.files import atomic_path, write_json
from boids_env.observations import Crowd, Observer, lidar_scans
from boids_env.recording import Recorder, Recording
from boids_env.world.robots import quaternion_headings, to_body

FloatArray = npt.NDArray[np.float64]

WARN_EVERY = 5.0
"""Seconds between the notes of a simulator waiting for its graph (before tick 0) or, in
lockstep, for commands."""
DRAIN = 1.0
"""Seconds (at most) the simulator waits after an episode for the answers to its last tick."""


@dataclass(frozen=True)
class SimOptions:
    """How the simulator node runs (the world itself is given by env config fields)."""

    env_fields: Mapping[str, Any] = field(default_factory=dict)
    """Env config fields by flat name (``robots``, ``leader_speed``, ``path``, …)."""
    lockstep: bool = False
    """Advance only when every follower answered the tick (deterministic); else real time."""
    episodes: int = 1
    """Episodes to run, seeds ``seed``, ``seed + 1``, …"""
    seed: int = 0
    """Seed of the first episode."""
    cmd_timeout: float = CMD_TIMEOUT
    """At real time, a follower whose latest command is older than this (s) gets (0, 0)."""
    wait_controller: bool = True
    """Hold tick 0 until every follower's ``cmd_vel`` has a publisher (always on in
    lockstep)."""
    wait_for: tuple[str, ...] = ()
    """Nodes (e.g. ``/recorder``) that must subscribe to every topic of the graph before
    tick 0."""
    settle: float = 0.0
    """Seconds waited after the ``wait_for`` nodes are connected, before tick 0."""
    out: str | None = None
    """Folder for ``metrics.json``, ``trajectory.parquet``, ``config.json`` (one subfolder per
    episode when there are several)."""
    quiet: bool = False
    node_name: str = "boids_sim"

    def __post_init__(self) -> None:
        if isinstance(self.episodes, bool) or not isinstance(self.episodes, int) or not (
                1 <= self.episodes <= 10_000):
            raise ValueError(f"episodes must be an integer in [1, 10000], got {self.episodes!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        if not (isinstance(self.cmd_timeout, int | float) and 0 < self.cmd_timeout <= 60):
            raise ValueError(f"cmd_timeout must be in (0, 60] s, got {self.cmd_timeout!r}")
        if not (isinstance(self.settle, int | float) and 0 <= self.settle <= 60):
            raise ValueError(f"settle must be in [0, 60] s, got {self.settle!r}")
        for name in self.wait_for:
            if not isinstance(name, str) or not name.strip("/"):
                raise ValueError(f"wait_for must hold node names such as /recorder, got "
                                 f"{name!r}")


@dataclass
class SimEpisode:
    """One simulated episode."""

    info: EpisodeInfo
    recording: Recording
    metrics: dict[str, Any]
    wall_time: float
    """Seconds from tick 0 to the last tick."""
    stats: dict[str, Any]
    """Diagnostics (real time): ticks the simulator itself was late for (``late_ticks``),
    follower-ticks that got the zero command of the timeout (``timed_out``) or a command that
    did not answer the tick just published (``stale``); commands beyond one per follower and
    tick (``extra_commands``) or not finite (``rejected_commands``); samples dropped as
    malformed since the previous episode, by topic and reason (``malformed``, see
    :mod:`boids_env.eval.graph.malformed`); the controllers seen."""


@dataclass(frozen=True)
class SimFrame:
    """Everything the simulator publishes for one tick, as plain arrays (a transport turns
    it into its messages)."""

    tick: int
    stamp_ns: int
    positions: FloatArray
    """(N, 2) m, the leader first."""
    velocities: FloatArray
    """(N, 2) m/s as odometry carries them: world frame, or each robot's own frame for robots
    with a heading (REP 105)."""
    quaternions: FloatArray | None
    """(N, 2) the orientation's (z, w) for robots with a heading, else None (identity)."""
    turn_rates: FloatArray
    """(N,) rad/s (zero for robots without a heading)."""
    leader_command: tuple[float, float, float] | None
    """The scripted leader's next command as its ``cmd_vel`` carries it (linear.x, linear.y,
    angular.z), or None (an external leader is commanded from outside; a walking person
    takes no command)."""
    scans: FloatArray | None = None
    """(F, R) each follower's lidar ranges (m) in its own frame when the config has a lidar
    (``lidar_rays``), else None."""
    lidar_range: float = 0.0
    crowd: Crowd | None = None
    """The crowd's pedestrians (positions and world-frame velocities), or None."""


class SimTransport(Protocol):
    """What a middleware provides to :class:`SimCore`: publishing, and the graph as the
    simulator node sees it (who publishes, who receives), from which :meth:`SimCore.
    wait_ready` tells when tick 0 may start."""

    name: str
    """The node's name on the graph (for messages)."""
    poll: float
    """Seconds between two looks at the graph while tick 0 waits."""
    wait_for_topics: Sequence[str]
    """The topics a ``wait_for`` node (a recorder) must receive before tick 0."""

    def stopped(self) -> bool:
        """Whether the node is shutting down."""

    def publish_clock(self, stamp_ns: int) -> None:
        """Publishes ``/clock`` alone (while tick 0 waits)."""

    def publishers(self, topic: str) -> set[str]:
        """The nodes publishing on ``topic``, one the simulator subscribes to (a follower's
        ``cmd_vel``), connected to it."""

    def receivers(self, topics: Sequence[str]) -> dict[str, set[str]]:
        """For each of ``topics``, the nodes that receive it from every publisher on it
        (none where nobody publishes it)."""

    def announce(self, info: EpisodeInfo) -> None:
        """Tells the graph that an episode starts (before its tick 0 is published)."""

    def publish(self, frame: SimFrame) -> None:
        """Publishes one tick."""

    @property
    def malformed(self) -> Counts:
        """The samples the node dropped so far as malformed, by topic and reason."""


class SimCore:
    """The simulator: builds the env (config errors raise before any transport starts) and
    runs episodes over a transport with :meth:`run_episode`.

    Args:
        options: how to run.
        label: the command's name, for error messages and recordings.
    """

    def __init__(self, options: SimOptions, label: str = "boids ros sim") -> None:
        self.options = options
        self.label = label
        self.env = BoidsEnv(**dict(options.env_fields))
        config = self.config = self.env.config
        sc = config.scenario
        self.robots = sc.robots
        self.dt = config.world.dt
        self.agents = list(self.env.possible_agents)
        self.external = sc.path == "external"
        self.person = sc.leader_kind.walks(sc)
        """A person walked by the pedestrian model leads: it takes no ``cmd_vel`` (its next
        step is known only once the model has stepped)."""
        self.pedestrians = sc.crowd
        """The crowd's size: the pedestrians published with every tick."""
        self.heading = config.world.has_heading
        if self.heading:
            # cmd_vel carries (v, ω) in the robot's frame: the world takes it as it is
            if self.external:
                raise ValueError(f"{label} drives a robot with a heading from body-frame "
                                 "cmd_vel; an external leader of such a robot is not supported "
                                 "yet: give a scripted --path")
            if config.realism.active:
                raise ValueError(f"{label} with a robot that has a heading applies cmd_vel "
                                 "(v, ω) as it comes; realism acts on world-frame velocities: "
                                 "leave --realism out")
            self.env = BoidsEnv(config, action="unicycle")
        self.board = CommandBoard(self.robots - 1, options.cmd_timeout)
        self.leader_command = np.zeros(2)
        """An external leader's latest command (world frame)."""
        self.next_start_ns = period_ns(CLOCK_START)
        """The stamp of the next episode's tick 0."""
        obs = config.observation
        self._sensors = Observer(config).sensors if obs.lidar_rays > 0 else None
        self.ready = False
        self._malformed: Counts = {}
        """The transport's malformed counts at the end of the last episode."""

    # ---------------------------------------------------------------------------- graph
    def controllers(self, transport: SimTransport) -> list[str]:
        """The nodes publishing the followers' commands."""
        return sorted({name for k in range(1, self.robots)
                       for name in transport.publishers(cmd_topic(k))})

    def graph_missing(self, transport: SimTransport) -> list[str]:
        """What tick 0 still waits for (empty when everything is connected): a publisher on
        every follower's ``cmd_vel`` whose nodes receive every odometry (in lockstep, or
        with ``wait_controller``), and each ``wait_for`` node on every topic it must
        receive."""
        options, missing = self.options, []
        if options.lockstep or options.wait_controller:
            idle = [cmd_topic(k) for k in range(1, self.robots)
                    if not transport.publishers(cmd_topic(k))]
            if idle:
                missing.append(f"a publisher on {', '.join(idle[:3])}"
                               + (f" (+{len(idle) - 3})" if len(idle) > 3 else ""))
            odoms = odometry_topics(self.robots, self.pedestrians)
            heard = transport.receivers(odoms)
            for name in self.controllers(transport):
                deaf = [t for t in odoms if name not in heard[t]]
                if deaf:
                    missing.append(f"{name} to subscribe to {len(deaf)} odometry topics")
        if options.wait_for:
            topics = transport.wait_for_topics
            heard = transport.receivers(topics)
            for name in options.wait_for:
                name = "/" + name.strip("/")
                absent = [t for t in topics if name not in heard[t]]
                if absent:
                    missing.append(f"{name} on {len(absent)} topics")
        return missing

    def wait_ready(self, transport: SimTransport) -> None:
        """Holds tick 0 until :meth:`graph_missing` is empty (then ``settle`` seconds more),
        ``/clock`` running meanwhile at real time in steps of ``dt`` (from
        :attr:`next_start_ns`, as Stage's clock runs before anything moves: sim-time nodes
        such as ``rosbag record -a`` need it to advance); the first episode then starts at
        the next step."""
        last_note, start, period, shown = -WARN_EVERY, time.monotonic(), period_ns(self.dt), -1
        while not transport.stopped():
            now = time.monotonic()
            steps = int((now - start) / self.dt)
            if steps != shown:
                transport.publish_clock(self.next_start_ns + steps * period)
                shown = steps
            missing = self.graph_missing(transport)
            if not missing:
                break
            if now - last_note >= WARN_EVERY and not self.options.quiet:
                print(f"{transport.name}: waiting for {'; '.join(missing)} ({now - start:.0f} s)",
                      flush=True)
                last_note = now
            time.sleep(transport.poll)
        time.sleep(self.options.settle)
        self.next_start_ns += (shown + 1) * period

    # ------------------------------------------------------------------------- commands
    def post_command(self, index: int, linear_x: float, linear_y: float, angular_z: float,
                     now: float | None = None) -> bool:
        """Records follower ``index``'s ``cmd_vel`` (world-frame (x, y), or (v, ω) for robots
        with a heading); False for a non-finite one (dropped)."""
        second = angular_z if self.heading else linear_y
        return self.board.post(index, linear_x, second,
                               time.monotonic() if now is None else now)

    def post_leader_command(self, linear_x: float, linear_y: float) -> bool:
        """Records the external leader's command (``--path external``); a non-finite one is
        dropped (False) and counted with the followers' (:meth:`CommandBoard.reject`): the
        last finite command holds."""
        self.leader_command, ok = finite_leader_command(linear_x, linear_y, self.leader_command)
        if not ok:
            self.board.reject()
        return ok

    # ----------------------------------------------------------------------------- ticks
    def frame(self, tick: int, start: int) -> SimFrame:
        """The current state as tick ``tick`` of an episode whose tick 0 is at ``start``."""
        snap = self.env.snapshot()
        velocities, quaternions = snap.velocities, snap.quaternions
        turn = np.zeros(self.robots) if snap.angular_velocities is None \
            else np.asarray(snap.angular_velocities, dtype=np.float64)
        if quaternions is not None:  # REP 105: the twist in the robot's own frame
            velocities = to_body(velocities, quaternion_headings(quaternions[:, 0],
                                                                 quaternions[:, 1]))
        leader: tuple[float, float, float] | None = None
        if not (self.external or self.person):
            # The command the scripted leader will execute next, computed on a copy (the
            # env computes the same one, from the same state, when it steps): published with
            # the odometry, as the study's leader controller answered its own odometry.
            vx, vy = copy.deepcopy(self.env.leader).command(tick * self.dt, snap.positions[0])
            if quaternions is None:
                leader = (float(vx), float(vy), 0.0)
            else:  # as the leader's driver takes it: (v, ω) in its own frame
                h = quaternion_headings(quaternions[:1, 0], quaternions[:1, 1])
                v, w = self.env.robot_model.native(np.array([[vx, vy]]), h)[0]
                leader = (float(v), 0.0, float(w))
        scans = None
        if self._sensors is not None:
            headings = None if quaternions is None else quaternion_headings(
                quaternions[:, 0], quaternions[:, 1])
            scans = lidar_scans(snap.positions, self.config.observation.lidar_rays,
                                self._sensors, headings)
        return SimFrame(tick, stamp_ns(start, tick, self.dt), snap.positions, velocities,
                        quaternions, turn, leader, scans, self.config.observation.lidar_range,
                        self.env.crowd)

    def _lockstep_commands(self, tick: int, transport: SimTransport) -> np.ndarray | None:
        """Waits for every follower's answer to ``tick``; None if the node shut down."""
        waited = 0.0
        while not self.board.wait_all(WARN_EVERY):
            if transport.stopped():
                return None
            waited += WARN_EVERY
            if not self.options.quiet:
                names = [self.agents[i] for i in self.board.missing()]
                print(f"{transport.name}: tick {tick} waits for {', '.join(names[:4])}"
                      f"{' …' if len(names) > 4 else ''} ({waited:.0f} s; the world is "
                      f"paused)", flush=True)
        return self.board.current()

    def _real_time_commands(self, deadline: float, stats: dict[str, Any]
                            ) -> tuple[np.ndarray, float]:
        deadline += self.dt
        now = time.monotonic()
        if now > deadline + self.dt:  # more than a period late: re-anchor
            stats["late_ticks"] += 1
            deadline = now
        time.sleep(max(0.0, deadline - now))
        commands, timed_out, stale = self.board.latest(time.monotonic())
        stats["timed_out"] += int(timed_out.sum())
        stats["stale"] += int(stale.sum())
        return commands, deadline

    def run_episode(self, index: int, transport: SimTransport) -> SimEpisode:
        """Runs one whole episode (seed ``options.seed + index``) and returns it."""
        opts = self.options
        seed = opts.seed + index
        self.env.reset(seed=seed)
        recorder = Recorder()
        recorder.capture(self.env)
        if not self.ready:
            self.wait_ready(transport)
            self.ready = True
        start = self.next_start_ns
        info = EpisodeInfo(index, seed, start, float(self.env.leader.initial_heading))
        transport.announce(info)
        stats = {"late_ticks": 0, "timed_out": 0, "stale": 0}
        extra0, rejected0 = self.board.extra, self.board.rejected
        self.board.open_tick(new_episode=True)
        began = time.monotonic()
        deadline = began
        transport.publish(self.frame(0, start))
        tick = 0
        while self.env.agents and not transport.stopped():
            if opts.lockstep:
                commands = self._lockstep_commands(tick, transport)
                if commands is None:
                    break
            else:
                commands, deadline = self._real_time_commands(deadline, stats)
            if self.external:
                self.env.set_leader_command(self.leader_command)
            self.env.step(dict(zip(self.agents, commands, strict=True)))
            recorder.capture(self.env)
            tick += 1
            self.board.open_tick()
            transport.publish(self.frame(tick, start))
        wall = time.monotonic() - began
        # Let the answers to the last tick arrive now, so that none of them is taken for an
        # answer to the next episode's tick 0 (the controller answers every tick).
        if opts.lockstep:
            self.board.wait_all(DRAIN)
        else:
            time.sleep(min(DRAIN, self.dt))
        self.next_start_ns = stamp_ns(start, tick, self.dt) + period_ns(EPISODE_GAP)
        controllers = self.controllers(transport)
        malformed = transport.malformed
        stats.update(extra_commands=self.board.extra - extra0,
                     rejected_commands=self.board.rejected - rejected0,
                     malformed=since(malformed, self._malformed), controllers=controllers)
        self._malformed = malformed
        recording = recorder.recording(self.env, seed=seed)
        # the graph's config (a robot with a heading steps with its cmd_vel's (v, ω) inside)
        recording.config = self.config
        recording.extra.update(source=self.label, controllers=controllers,
                               mode="lockstep" if opts.lockstep else "real time")
        return SimEpisode(info, recording, recording.metrics(), wall, stats)


def write_outputs(out: str | Path, episode: SimEpisode, options: SimOptions,
                  config: dict[str, Any], transport: dict[str, Any] | None = None) -> Path:
    """Writes ``metrics.json``, ``trajectory.parquet`` and ``config.json`` (as ``boids run``
    does) to ``out``, each atomically; returns the folder. ``transport`` adds fields to the
    ``ros`` table of ``config.json`` (the ROS 2 distribution, domain …)."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    write_json(folder / "metrics.json", episode.metrics)
    with atomic_path(folder / "trajectory.parquet") as tmp:
        episode.recording.to_parquet(tmp)
    write_json(folder / "config.json", {
        "env": config, "policy": None, "preset": None, "policy_params": None,
        "seed": episode.info.seed,
        "ros": {"node": options.node_name, "mode": "lockstep" if options.lockstep
                else "real time", "cmd_timeout": options.cmd_timeout,
                "controllers": episode.stats["controllers"],
                "clock_start_ns": episode.info.start_ns, "wall_time": episode.wall_time,
                **{k: v for k, v in episode.stats.items() if k != "controllers"},
                **(transport or {})}})
    return folder


def run_episodes(core: SimCore, transport: SimTransport, title: str,
                 out_fields: dict[str, Any] | None = None) -> list[SimEpisode]:
    """Runs ``core.options.episodes`` episodes over ``transport``: each one's metrics table
    printed and, with ``options.out``, its files written. ``title`` heads the printed
    summary (``ros sim``)."""
    options, cfg = core.options, core.config
    episodes = []
    for index in range(options.episodes):
        episode = core.run_episode(index, transport)
        if transport.stopped() and core.env.agents:
            print(f"{transport.name}: shut down during episode {index}", flush=True)
            break
        episodes.append(episode)
        if not options.quiet:
            mode = "lockstep" if options.lockstep else "real time"
            print(f"{title} · {mode} · robots {cfg.scenario.robots} · leader "
                  f"{cfg.scenario.leader_speed} m/s · seed {episode.info.seed} · "
                  f"{episode.wall_time:.2f} s wall · controllers "
                  f"{', '.join(episode.stats['controllers']) or 'none'}")
            print(metrics_table(episode.metrics))
            print(json.dumps({k: v for k, v in episode.stats.items()
                              if k != "controllers"}), flush=True)
        if options.out is not None:
            out = Path(options.out)
            folder = out if options.episodes == 1 else out / f"episode_{index:03d}"
            write_outputs(folder, episode, options, cfg.to_dict(), out_fields)
            if not options.quiet:
                print(f"wrote metrics.json, trajectory.parquet, config.json to {folder}",
                      flush=True)
    return episodes
