"""``boids ros sim``: the pymunk world (:class:`~boids_env.environment.BoidsEnv`) as a ROS 1
node in place of the study's Stage simulator.

Publishes the scene as ``map_server`` does (``/map``, ``/map_metadata``, latched, once) and,
for every robot k, ``/robot_k/odom`` (latched) once per control period, ``/tf``
(``map`` → ``robot_k``), ``/clock`` (sets ``/use_sim_time``), and the scripted leader's command
on ``/robot_0/cmd_vel`` (as the study's leader controller did; with ``--path external`` the
sim subscribes to it instead, for a teleop). Subscribes to every follower's
``/robot_k/cmd_vel``. See :mod:`boids_env.eval.ros.protocol` for the timing (lockstep or real
time, the 0.5 s command timeout, stamps and episodes).

Each episode's samples are recorded exactly as ``boids run`` records them, so its metrics,
``metrics.json`` and ``trajectory.parquet`` are those of an in-process run given the same
commands.
"""

from __future__ import annotations

import copy
import json
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from boids_env.environment import BoidsEnv
from boids_env.eval.ros.messages import Messages, publisher
from boids_env.eval.ros.protocol import (
    CLOCK_START,
    CMD_TIMEOUT,
    CONFIG_PARAM,
    EPISODE_GAP,
    EPISODE_PARAM,
    QUEUE_SIZE,
    CommandBoard,
    EpisodeInfo,
    cmd_topic,
    config_json,
    finite_leader_command,
    odom_topic,
    period_ns,
    stamp_ns,
)
from boids_env.eval.run import metrics_table
from boids_env.files import atomic_path, write_json
from boids_env.recording import Recorder, Recording
from boids_env.world.robots import quaternion_headings, to_body

WARN_EVERY = 5.0
"""Seconds between the warnings of a lockstep simulator waiting for commands."""
POLL = 0.05
"""Seconds between checks of the graph while waiting for nodes to connect."""
DRAIN = 1.0
"""Seconds (at most) the simulator waits after an episode for the answers to its last tick."""


@dataclass(frozen=True)
class SimOptions:
    """How ``boids ros sim`` runs (the world itself is given by env config fields)."""

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
    tick (``extra_commands``) or not finite (``rejected_commands``); the controllers seen."""


class SimNode:
    """The simulator node: builds the env (config errors raise before any ROS call), joins
    the graph as ``options.node_name`` and runs episodes with :meth:`run_episode`.

    Args:
        options: how to run.
        argv: the command line, for ROS remapping arguments (``name:=value``).
    """

    def __init__(self, options: SimOptions, argv: Sequence[str] | None = None) -> None:
        self.options = options
        self.env = BoidsEnv(**dict(options.env_fields))
        config = self.config = self.env.config
        sc = config.scenario
        if (sc.leader == "person" and sc.path != "external") or sc.crowd:
            # the sim publishes the leader's next command ahead of stepping, which a
            # pedestrian model only knows once it has stepped
            raise ValueError("boids ros sim: a walking person (leader='person' with a path) "
                             "and crowds are not supported; use leader='trajectory' (a "
                             "recorded walk) or --path external with --leader person")
        self.robots = config.scenario.robots
        self.dt = config.world.dt
        self.agents = list(self.env.possible_agents)
        self.external = config.scenario.path == "external"
        self.heading = config.world.drive == "unicycle"
        if self.heading:
            # cmd_vel carries (v, ω) in the robot's frame: the world takes it as it is
            if self.external:
                raise ValueError("boids ros sim drives a robot with a heading from body-frame "
                                 "cmd_vel; an external leader of such a robot is not supported "
                                 "yet: give a scripted --path")
            if config.realism.active:
                raise ValueError("boids ros sim with a robot that has a heading applies cmd_vel "
                                 "(v, ω) as it comes; realism acts on world-frame velocities: "
                                 "leave --realism out")
            self.env = BoidsEnv(config, action="unicycle")
        self.msgs = Messages()
        rospy = self.rospy = self.msgs.rospy
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock
        from tf2_msgs.msg import TFMessage

        rospy.init_node(options.node_name, argv=list(argv) if argv is not None else None,
                        disable_signals=True)
        self.name = rospy.get_name()
        # This node is the clock (as Stage is): the nodes started after it run on sim time.
        rospy.set_param("/use_sim_time", True)
        rospy.set_param(CONFIG_PARAM, config_json(config.to_dict()))
        self.board = CommandBoard(self.robots - 1, options.cmd_timeout)
        self._leader_command = np.zeros(2)
        self.clock_pub = publisher(rospy, "/clock", Clock, latch=True)
        # the scene as map_server publishes a map: latched, once
        from nav_msgs.msg import MapMetaData, OccupancyGrid

        grid, meta = self.msgs.occupancy_grid(config.scene.occupancy(), period_ns(CLOCK_START))
        self.map_pub = publisher(rospy, "/map", OccupancyGrid, latch=True)
        self.map_meta_pub = publisher(rospy, "/map_metadata", MapMetaData, latch=True)
        self.map_pub.publish(grid)
        self.map_meta_pub.publish(meta)
        self.tf_pub = publisher(rospy, "/tf", TFMessage)
        self.odom_pubs = [publisher(rospy, odom_topic(k), Odometry, latch=True)
                          for k in range(self.robots)]
        self.leader_pub = None
        if self.external:
            self.leader_sub = rospy.Subscriber(cmd_topic(0), Twist, self._on_leader,
                                               queue_size=QUEUE_SIZE, tcp_nodelay=True)
        else:
            self.leader_pub = publisher(rospy, cmd_topic(0), Twist)
        self.cmd_subs = [rospy.Subscriber(cmd_topic(k), Twist, self._on_command,
                                          callback_args=k - 1, queue_size=QUEUE_SIZE,
                                          tcp_nodelay=True)
                         for k in range(1, self.robots)]
        self._next_start_ns = period_ns(CLOCK_START)
        self._graph_ready = False

    # ------------------------------------------------------------------------ callbacks
    def _on_command(self, msg: Any, index: int) -> None:
        second = msg.angular.z if self.heading else msg.linear.y
        if not self.board.post(index, msg.linear.x, second, time.monotonic()):
            self.rospy.logwarn_throttle(5.0, f"{self.name}: dropped a non-finite command for "
                                        f"{self.agents[index]}")

    def _on_leader(self, msg: Any) -> None:
        self._leader_command, ok = finite_leader_command(msg.linear.x, msg.linear.y,
                                                         self._leader_command)
        if not ok:
            self.board.reject()
            self.rospy.logwarn_throttle(5.0, f"{self.name}: dropped a non-finite command for "
                                        f"the leader")

    # -------------------------------------------------------------------------- waiting
    def _controllers(self) -> list[str]:
        """Nodes publishing the followers' commands."""
        names = {c.callerid_pub for sub in self.cmd_subs for c in sub.impl.connections}
        return sorted(names)

    def _graph_missing(self) -> list[str]:
        """What tick 0 still waits for (empty when everything is connected)."""
        missing = []
        if self.options.lockstep or self.options.wait_controller:
            idle = [cmd_topic(k + 1) for k, sub in enumerate(self.cmd_subs)
                    if sub.get_num_connections() == 0]
            if idle:
                missing.append(f"a publisher on {', '.join(idle[:3])}"
                               + (f" (+{len(idle) - 3})" if len(idle) > 3 else ""))
            else:  # the controllers must also receive every odometry from tick 0 on
                for node in self._controllers():
                    deaf = [p.resolved_name for p in self.odom_pubs
                            if node not in {c.endpoint_id for c in p.impl.connections}]
                    if deaf:
                        missing.append(f"{node} to subscribe to {len(deaf)} odometry topics")
        if self.options.wait_for:
            wanted = {odom_topic(k) for k in range(self.robots)}
            wanted |= {cmd_topic(k) for k in range(0 if self.leader_pub else 1, self.robots)}
            wanted |= {"/clock", "/tf"}
            links = self._outbound_links(wanted)
            for node in self.options.wait_for:
                node = "/" + node.strip("/")
                absent = [t for t in wanted if not links.get(t) or any(
                    node not in peers for peers in links[t])]
                if absent:
                    missing.append(f"{node} on {len(absent)} topics")
        return missing

    def _outbound_links(self, topics: set[str]) -> dict[str, list[set[str]]]:
        """For each topic, one set per publisher: the nodes that publisher is connected to.

        Asked of the publishers themselves (the ROS slave API's ``getBusInfo``): rospy and
        roscpp publishers list a subscriber only once its connection's handshake is done, from
        when on it receives every message; the master, or the subscriber's own side, knows of
        a subscription earlier, and messages published in between would be lost to it."""
        import xmlrpc.client

        import rosgraph

        master = rosgraph.Master(self.name)
        try:
            publishers, _, _ = master.getSystemState()
        except (rosgraph.MasterError, OSError):
            return {}
        by_topic = {topic: nodes for topic, nodes in publishers if topic in topics}
        bus: dict[str, set[tuple[str, str]]] = {}
        for node in {n for nodes in by_topic.values() for n in nodes}:
            try:
                code, _, info = xmlrpc.client.ServerProxy(master.lookupNode(node)).getBusInfo(
                    self.name)
            except (rosgraph.MasterError, OSError, xmlrpc.client.Error):
                code, info = 0, []
            # entries: (connection id, peer, direction, transport, topic, connected, …)
            bus[node] = {(e[4], e[1]) for e in info if e[2] == "o"} if code == 1 else set()
        return {topic: [{peer for t, peer in bus[node] if t == topic} for node in nodes]
                for topic, nodes in by_topic.items()}

    def wait_for_graph(self) -> None:
        """Holds tick 0 until the controller and the ``wait_for`` nodes are connected, the
        latched ``/clock`` running meanwhile at real time in steps of ``dt`` (from
        :data:`CLOCK_START`); the first episode then starts at the next step."""
        last_note = -WARN_EVERY
        start = time.monotonic()
        period = period_ns(self.dt)
        shown = -1
        while not self.rospy.is_shutdown():
            now = time.monotonic()
            steps = int((now - start) / self.dt)
            if steps != shown:
                self.clock_pub.publish(self.msgs.clock(self._next_start_ns + steps * period))
                shown = steps
            missing = self._graph_missing()
            if not missing:
                break
            if now - last_note >= WARN_EVERY and not self.options.quiet:
                print(f"{self.name}: waiting for {'; '.join(missing)} "
                      f"({now - start:.0f} s)", flush=True)
                last_note = now
            time.sleep(POLL)
        time.sleep(self.options.settle)
        self._next_start_ns += (shown + 1) * period
        self._graph_ready = True

    # ------------------------------------------------------------------------ publishing
    def _publish_tick(self, tick: int, start: int) -> None:
        snap = self.env.snapshot()
        stamp = self.msgs.time(stamp_ns(start, tick, self.dt))
        self.clock_pub.publish(self.msgs.Clock(clock=stamp))
        velocities, quaternions = snap.velocities, snap.quaternions
        turn = np.zeros(self.robots) if snap.angular_velocities is None \
            else snap.angular_velocities
        if quaternions is not None:  # REP 105: the twist in the robot's own frame
            velocities = to_body(velocities, quaternion_headings(quaternions[:, 0],
                                                                 quaternions[:, 1]))
        for k, pub in enumerate(self.odom_pubs):
            pub.publish(self.msgs.odometry(k, stamp, snap.positions[k], velocities[k],
                                           None if quaternions is None else quaternions[k],
                                           turn[k]))
        self.tf_pub.publish(self.msgs.transforms(stamp, snap.positions, quaternions))
        if self.leader_pub is not None:
            # The command the scripted leader will execute next, computed on a copy (the
            # env computes the same one, from the same state, when it steps): published with
            # the odometry, as the study's leader controller answered its own odometry.
            vx, vy = copy.deepcopy(self.env.leader).command(tick * self.dt, snap.positions[0])
            if quaternions is None:
                self.leader_pub.publish(self.msgs.twist(vx, vy))
            else:  # as the leader's driver takes it: (v, ω) in its own frame
                h = quaternion_headings(quaternions[:1, 0], quaternions[:1, 1])
                v, w = self.env.robot_model.native(np.array([[vx, vy]]), h)[0]
                self.leader_pub.publish(self.msgs.twist(v, 0.0, w))

    # -------------------------------------------------------------------------- episode
    def _lockstep_commands(self, tick: int) -> np.ndarray | None:
        """Waits for every follower's answer to ``tick``; None if the node shut down."""
        waited = 0.0
        while not self.board.wait_all(WARN_EVERY):
            if self.rospy.is_shutdown():
                return None
            waited += WARN_EVERY
            if not self.options.quiet:
                names = [self.agents[i] for i in self.board.missing()]
                print(f"{self.name}: tick {tick} waits for {', '.join(names[:4])}"
                      f"{' …' if len(names) > 4 else ''} ({waited:.0f} s; the world is "
                      f"paused)", flush=True)
        return self.board.current()

    def run_episode(self, index: int) -> SimEpisode:
        """Runs one whole episode (seed ``options.seed + index``) and returns it."""
        opts = self.options
        seed = opts.seed + index
        self.env.reset(seed=seed)
        recorder = Recorder()
        recorder.capture(self.env)
        if not self._graph_ready:
            self.wait_for_graph()
        start = self._next_start_ns
        info = EpisodeInfo(index, seed, start, float(self.env.leader.initial_heading))
        self.rospy.set_param(EPISODE_PARAM, info.to_json())
        stats = {"late_ticks": 0, "timed_out": 0, "stale": 0}
        extra0, rejected0 = self.board.extra, self.board.rejected
        self.board.open_tick(new_episode=True)
        began = time.monotonic()
        deadline = began
        self._publish_tick(0, start)
        tick = 0
        while self.env.agents and not self.rospy.is_shutdown():
            if opts.lockstep:
                commands = self._lockstep_commands(tick)
                if commands is None:
                    break
            else:
                deadline += self.dt
                now = time.monotonic()
                if now > deadline + self.dt:  # more than a period late: re-anchor
                    stats["late_ticks"] += 1
                    deadline = now
                time.sleep(max(0.0, deadline - now))
                commands, timed_out, stale = self.board.latest(time.monotonic())
                stats["timed_out"] += int(timed_out.sum())
                stats["stale"] += int(stale.sum())
            if self.external:
                self.env.set_leader_command(self._leader_command)
            self.env.step(dict(zip(self.agents, commands, strict=True)))
            recorder.capture(self.env)
            tick += 1
            self.board.open_tick()
            self._publish_tick(tick, start)
        wall = time.monotonic() - began
        # Let the answers to the last tick arrive now, so that none of them is taken for an
        # answer to the next episode's tick 0 (the controller answers every tick).
        if opts.lockstep:
            self.board.wait_all(DRAIN)
        else:
            time.sleep(min(DRAIN, self.dt))
        self._next_start_ns = stamp_ns(start, tick, self.dt) + period_ns(EPISODE_GAP)
        stats.update(extra_commands=self.board.extra - extra0,
                     rejected_commands=self.board.rejected - rejected0,
                     controllers=self._controllers())
        recording = recorder.recording(self.env, seed=seed)
        # the graph's config (a robot with a heading steps with its cmd_vel's (v, ω) inside)
        recording.config = self.config
        recording.extra.update(source="boids ros sim", controllers=stats["controllers"],
                               mode="lockstep" if opts.lockstep else "real time")
        return SimEpisode(info, recording, recording.metrics(), wall, stats)

    def shutdown(self) -> None:
        """Leaves the graph, removing the parameters that describe this run (a controller
        started later must wait for the next simulator, not read this one's config);
        ``/use_sim_time`` stays, as Stage leaves it."""
        for name in (CONFIG_PARAM, EPISODE_PARAM):
            try:
                self.rospy.delete_param(name)
            except (KeyError, OSError):
                pass
        self.rospy.signal_shutdown("boids ros sim finished")


def write_outputs(out: str | Path, episode: SimEpisode, options: SimOptions,
                  config: dict[str, Any]) -> Path:
    """Writes ``metrics.json``, ``trajectory.parquet`` and ``config.json`` (as ``boids run``
    does) to ``out``, each atomically; returns the folder."""
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
                **{k: v for k, v in episode.stats.items() if k != "controllers"}}})
    return folder


def run_sim(options: SimOptions, argv: Sequence[str] | None = None) -> list[SimEpisode]:
    """Runs ``boids ros sim``: the episodes, each one's metrics table printed and, with
    ``options.out``, its files written."""
    node = SimNode(options, argv)
    cfg = node.config
    episodes = []
    try:
        for index in range(options.episodes):
            episode = node.run_episode(index)
            if node.rospy.is_shutdown() and node.env.agents:
                print(f"{node.name}: shut down during episode {index}", flush=True)
                break
            episodes.append(episode)
            if not options.quiet:
                mode = "lockstep" if options.lockstep else "real time"
                print(f"ros sim · {mode} · robots {cfg.scenario.robots} · leader "
                      f"{cfg.scenario.leader_speed} m/s · seed {episode.info.seed} · "
                      f"{episode.wall_time:.2f} s wall · controllers "
                      f"{', '.join(episode.stats['controllers']) or 'none'}")
                print(metrics_table(episode.metrics))
                print(json.dumps({k: v for k, v in episode.stats.items()
                                  if k != "controllers"}), flush=True)
            if options.out is not None:
                out = Path(options.out)
                folder = out if options.episodes == 1 else out / f"episode_{index:03d}"
                write_outputs(folder, episode, options, cfg.to_dict())
                if not options.quiet:
                    print(f"wrote metrics.json, trajectory.parquet, config.json to {folder}",
                          flush=True)
    finally:
        node.shutdown()
    return episodes
