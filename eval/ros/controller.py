"""``boids ros controller``: any policy as the study's ``reynolds_controller`` node.

Subscribes to every ``/robot_k/odom``, builds each follower's observation with
:class:`~boids_env.observations.Observer` (the env's own builder, with the env's config: the
same observations as in-process), asks the policy, and publishes every follower's
``/robot_k/cmd_vel`` (world frame; for robots with a heading, e.g. a TurtleBot3, the robot's
own (linear.x, angular.z) from its driver's law, as a real TurtleBot3 takes it, with the
odometry read as REP 105 gives it: oriented, the twist in the robot's frame). A policy with
rule forces (the Reynolds controller) also gets them drawn in RViz as arrows (``~markers``,
visualization_msgs/MarkerArray), and a policy with Reynolds parameters gets them as ROS
parameters (``~leader_weight`` …) changeable live through dynamic_reconfigure (see
:mod:`boids_env.eval.ros.reconfigure`).

Synchronisation (``sync``): ``stamp`` (default) answers a tick once every robot's odometry with
that stamp has arrived (the simulator and Stage stamp all robots of a step alike): each tick
exactly once, in order, which the simulator's lockstep mode relies on. ``rate`` answers every
``dt`` of wall time from each robot's latest odometry, for sources whose robots are not
stamped together (real robots).
"""

from __future__ import annotations

import json
import queue
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from boids_env.config import EnvConfig
from boids_env.eval.episode import bind_policy, env_fields_for
from boids_env.eval.ros import reconfigure
from boids_env.eval.ros.messages import Messages, publisher
from boids_env.eval.ros.protocol import (
    CONFIG_PARAM,
    EPISODE_PARAM,
    QUEUE_SIZE,
    EpisodeInfo,
    Tick,
    TickAssembler,
    cmd_topic,
    finite_commands,
    is_continuation,
    odom_topic,
)
from boids_env.observations import INITIAL_HEADING, Observer
from boids_env.policies.base import Policy
from boids_env.policies.registry import load_policy, split_preset
from boids_env.vectors import clip_speed
from boids_env.world.realism import StaleObservations
from boids_env.world.robots import make_model, quaternion_headings, to_world
from boids_env.world.scenario import holding

SYNC_MODES = ("stamp", "rate")
FIRST_CONNECTION_WAIT = 1.0
"""Seconds a command publisher may wait, once, for the odometry source's node to connect to
it before its first message (a message published before a subscriber connects is lost, and a
lockstep simulator would then wait for it forever)."""


@dataclass(frozen=True)
class ControllerOptions:
    """How ``boids ros controller`` runs."""

    policy: str = "reynolds"
    """A policy spec of :func:`~boids_env.policies.registry.load_policy`."""
    preset: str = "paper"
    """Reynolds parameter preset (unless ``policy`` names one)."""
    leader_weight: float | None = None
    """Reynolds leader weight override."""
    env_fields: Mapping[str, Any] = field(default_factory=dict)
    """Env config fields (``robots`` …) of the odometry source. Empty: the simulator's config
    (its ``/boids/env_config`` parameter), waited for up to ``config_wait`` seconds."""
    sync: str = "stamp"
    """``stamp`` or ``rate`` (see the module's docstring)."""
    seed: int = 0
    """Seed for ``policy.reset`` when the simulator announces no episode."""
    config_wait: float = 30.0
    """Seconds to wait for the simulator's config parameter."""
    max_ticks: int | None = None
    """Stop after answering this many ticks (None: run until shut down)."""
    markers: bool = True
    """Publish the rule-force markers when the policy has forces."""
    quiet: bool = False
    node_name: str = "reynolds_controller"
    trust_model: bool = False
    """A model zip may load through SB3's own load, which runs code stored in the file."""

    def __post_init__(self) -> None:
        if self.sync not in SYNC_MODES:
            raise ValueError(f"sync must be one of {SYNC_MODES}, got {self.sync!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        if not (isinstance(self.config_wait, int | float) and 0 <= self.config_wait <= 3600):
            raise ValueError(f"config_wait must be in [0, 3600] s, got {self.config_wait!r}")
        if self.max_ticks is not None and (isinstance(self.max_ticks, bool) or not isinstance(
                self.max_ticks, int) or self.max_ticks < 1):
            raise ValueError(f"max_ticks must be a positive integer or None, got "
                             f"{self.max_ticks!r}")
        if not isinstance(self.trust_model, bool):
            raise TypeError(f"trust_model must be True or False, got {self.trust_model!r}")
        split_preset(self.policy, self.preset)  # a bad spec or preset fails before ROS starts


def controller_policy(options: ControllerOptions) -> Policy:
    """The policy the node runs (loaded before the node touches ROS)."""
    overrides = {} if options.leader_weight is None else {
        "leader_weight": options.leader_weight}
    spec, preset = split_preset(options.policy, options.preset)
    return load_policy(spec, preset=preset, trust=options.trust_model, **overrides)


class ControllerNode:
    """The controller node; :meth:`spin` answers ticks until shut down (or ``max_ticks``).

    Args:
        options: how to run.
        argv: the command line, for ROS remapping arguments (``_leader_weight:=1.1`` sets a
            private parameter, ``__name:=other`` renames the node).
    """

    def __init__(self, options: ControllerOptions, argv: Sequence[str] | None = None) -> None:
        self.options = options
        self.policy = controller_policy(options)
        self.msgs = Messages()
        rospy = self.rospy = self.msgs.rospy
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from visualization_msgs.msg import MarkerArray

        rospy.init_node(options.node_name, argv=list(argv) if argv is not None else None,
                        disable_signals=True)
        self.name = rospy.get_name()
        base = self._base_config()
        self.config = base.replace(**env_fields_for(self.policy, {}))
        self.observer = Observer(self.config)
        self.layout = self.observer.layout
        bind_policy(self.policy, self)  # the layout, the scene, the robots' top speed: as an env
        self.model = make_model(self.config.world)
        """The robots' model: for robots with a heading, the driver's law the env applies
        in-process is applied here, and (v, ω) goes out on cmd_vel."""
        self.stale: StaleObservations | None = None
        self.robots = self.config.scenario.robots
        self.dt = self.config.world.dt
        self.agents = [f"follower_{i}" for i in range(1, self.robots)]
        rospy.set_param("~policy", options.policy)
        self.cmd_pubs = [publisher(rospy, cmd_topic(k), Twist) for k in range(1, self.robots)]
        self.marker_pub = (rospy.Publisher("~markers", MarkerArray, queue_size=10)
                           if options.markers else None)
        self._lock = threading.Lock()
        self._pending_params: Any = None
        self.server = None
        params = getattr(self.policy, "params", None)
        if params is not None:
            from dynamic_reconfigure.server import Server

            self.server = Server(reconfigure.config_type(
                params, self.config.observation.horizon), self._on_reconfigure)
            self._apply_params()
            # dynamic_reconfigure starts from the values already on the parameter server
            # (this run's _name:=value arguments, a launch file's, or a crashed run's): say so
            differ = {k: v for k, v in reconfigure.values(self.policy.params).items()
                      if v != reconfigure.values(params)[k]}
            if differ and not options.quiet:
                print(f"{self.name}: from the parameter server: "
                      + ", ".join(f"{k} = {v:g}" for k, v in differ.items())
                      + f" (rosparam delete {self.name} to start from the preset)", flush=True)
        self.assembler = TickAssembler(self.robots)
        self.ticks: queue.Queue[Tick] = queue.Queue()
        self._source: str | None = None
        self._deaf: set[str] = set()
        self._last_stamp: int | None = None
        self.episode: EpisodeInfo | None = None
        self._episode_start: int | None = None
        self.answered = 0
        self.nonfinite = 0
        """Commands sent as a stop because they were not finite (non-finite odometry)."""
        self.odom_subs = [rospy.Subscriber(odom_topic(k), Odometry, self._on_odom,
                                           callback_args=k, queue_size=QUEUE_SIZE,
                                           tcp_nodelay=True) for k in range(self.robots)]

    # ---------------------------------------------------------------------------- config
    def _base_config(self) -> EnvConfig:
        """The odometry source's env config: the given fields, else the simulator's."""
        if self.options.env_fields:
            return EnvConfig().replace(**dict(self.options.env_fields))
        waited, announced = 0.0, False
        while not self.rospy.has_param(CONFIG_PARAM):
            if waited >= self.options.config_wait or self.rospy.is_shutdown():
                raise ValueError(
                    f"no {CONFIG_PARAM} parameter after {self.options.config_wait:g} s: start "
                    f"boids ros sim first, or give the robots of another odometry source "
                    f"(--robots N)")
            if not announced and not self.options.quiet:
                print(f"{self.name}: waiting for {CONFIG_PARAM} (boids ros sim)", flush=True)
                announced = True
            time.sleep(0.2)
            waited += 0.2
        return EnvConfig.from_dict(json.loads(self.rospy.get_param(CONFIG_PARAM)))

    def _on_reconfigure(self, config: dict[str, Any], level: int) -> dict[str, Any]:
        """dynamic_reconfigure's callback (a service thread): validates the new values and
        hands them to the loop, which applies them before the next tick."""
        with self._lock:
            current = self._pending_params or self.policy.params
            applied, error = reconfigure.apply(current, config)
            if error is not None:
                self.rospy.logwarn(f"{self.name}: refused parameters: {error}")
            self._pending_params = applied
        config.update(reconfigure.values(applied))
        return config

    def _apply_params(self) -> None:
        with self._lock:
            if self._pending_params is not None:
                self.policy.params = self._pending_params
                self._pending_params = None

    # ------------------------------------------------------------------------- odometry
    def _on_odom(self, msg: Any, robot: int) -> None:
        if self._source is None:
            self._source = msg._connection_header.get("callerid")
        p, v = msg.pose.pose.position, msg.twist.twist.linear
        q = msg.pose.pose.orientation
        tick = self.assembler.add(robot, msg.header.stamp.to_nsec(), p.x, p.y, v.x, v.y, q.z,
                                  q.w)
        if tick is not None and self.options.sync == "stamp":
            self.ticks.put(tick)

    # -------------------------------------------------------------------------- answers
    def _episode_param(self) -> EpisodeInfo | None:
        try:
            return EpisodeInfo.from_json(self.rospy.get_param(EPISODE_PARAM))
        except KeyError:
            return None

    def _maybe_reset(self, stamp: int) -> None:
        """Resets the policy (and the observer) at the first tick of every episode."""
        if is_continuation(self._last_stamp, stamp, self.dt):
            return
        info = self._episode_param()
        if self._last_stamp is None:
            fresh = True
        elif info is not None:
            fresh = self.episode is None or info.index != self.episode.index
        else:
            fresh = stamp < self._last_stamp  # the source's clock restarted
        if not fresh:
            return
        if info is not None and info.start_ns > stamp:
            info = None  # announced for a later tick: not this episode's
        self.episode = info
        self._episode_start = info.start_ns if info is not None else stamp
        seed = info.seed if info is not None else self.options.seed
        self.policy.reset(seed)
        self.observer.reset(np.random.default_rng(seed),
                            info.initial_heading if info is not None else INITIAL_HEADING)
        p = self.config.realism.resolved()["stale_observations"]
        self.stale = StaleObservations(p, seed) if p > 0 else None  # as the env draws them
        if not self.options.quiet:
            which = f"episode {info.index}, seed {seed}" if info else f"seed {seed}"
            print(f"{self.name}: new episode ({which}) at stamp {stamp / 1e9:.1f} s",
                  flush=True)

    def _holding(self, stamp: int) -> bool:
        """Whether the followers are held still at ``stamp``: the first ``startup_time``
        seconds of an episode when the config (a learned model's env fields) asks for
        ``startup_hold``, as the env holds them in-process."""
        sc = self.config.scenario
        if not sc.startup_hold or self._episode_start is None:
            return False
        return holding((stamp - self._episode_start) / 1e9, sc.startup_time)

    def _await_listener(self) -> None:
        """Before the first command to a node that sends odometry, waits (once, at most
        :data:`FIRST_CONNECTION_WAIT`) until it is connected to every command topic."""
        source = self._source
        if source is None or source in self._deaf:
            return
        waited = 0.0
        while any(source not in {c.endpoint_id for c in pub.impl.connections}
                  for pub in self.cmd_pubs):
            if waited >= FIRST_CONNECTION_WAIT:
                self._deaf.add(source)  # it does not listen to commands: do not wait again
                return
            time.sleep(0.005)
            waited += 0.005

    def answer(self, tick: Tick) -> np.ndarray:
        """The commands (F, 2) for one tick, published (world frame; (v, ω) for robots with
        a heading); also the markers."""
        self._maybe_reset(tick.stamp_ns)
        self._last_stamp = tick.stamp_ns
        self._apply_params()
        velocities, headings = tick.velocities, None
        if self.model.has_heading:  # REP 105 odometry, read back as the env observes it
            assert tick.quaternions is not None
            headings = quaternion_headings(tick.quaternions[:, 0], tick.quaternions[:, 1])
            velocities = to_world(velocities, headings)
        obs = self.observer(tick.positions, velocities, headings=headings)
        if self.stale is not None:
            obs = self.stale(obs)
        actions = self.policy.act(dict(zip(self.agents, obs, strict=True)))
        raw = np.array([actions[a] for a in self.agents], dtype=np.float64)
        if headings is None:
            # as the env parses them: float64, then into the world frame (no speed clip here:
            # the robot, or the simulator, limits the speed, as the env does)
            commands = self.observer.to_world(raw)
        elif self.config.observation.action == "unicycle":  # (v, ω) from the policy itself
            w = self.config.world
            commands = np.clip(raw, [-w.max_speed, -w.max_turn_rate],
                               [w.max_speed, w.max_turn_rate])
        else:  # the robot's driver: its law from the speed-limited world-frame command
            world = clip_speed(self.observer.to_world(raw), self.config.world.max_speed)
            commands = self.model.native(world, headings[1:])
        if self._holding(tick.stamp_ns):
            commands = np.zeros_like(commands)
        commands, bad = finite_commands(commands)
        if bad:
            self.nonfinite += bad
            self.rospy.logwarn_throttle(5.0, f"{self.name}: {bad} non-finite command(s) (from "
                                        f"non-finite odometry?) sent as a stop")
        self._await_listener()
        for pub, (a, b) in zip(self.cmd_pubs, commands.tolist(), strict=True):
            pub.publish(self.msgs.twist(a, b) if headings is None
                        else self.msgs.twist(a, 0.0, b))
        forces = getattr(self.policy, "forces", None)
        if forces and self.marker_pub is not None:
            stamp = self.msgs.time(tick.stamp_ns)
            world = {rule: self.observer.to_world(np.asarray(f, dtype=np.float64))
                     for rule, f in forces.items()}
            self.marker_pub.publish(self.msgs.force_markers(stamp, tick.positions, world))
        self.answered += 1
        return commands

    def spin(self) -> int:
        """Answers ticks until the node shuts down or ``max_ticks`` are answered; returns
        the number answered."""
        limit = self.options.max_ticks
        deadline = time.monotonic()
        last_answered: int | None = None
        while not self.rospy.is_shutdown() and (limit is None or self.answered < limit):
            if self.options.sync == "stamp":
                try:
                    tick = self.ticks.get(timeout=0.1)
                except queue.Empty:
                    continue
            else:
                deadline += self.dt
                time.sleep(max(0.0, deadline - time.monotonic()))
                tick = self.assembler.snapshot()
                if tick is None or tick.stamp_ns == last_answered:
                    continue
                last_answered = tick.stamp_ns
            self.answer(tick)
        return self.answered

    def shutdown(self) -> None:
        """Leaves the graph; its Reynolds parameters leave the parameter server with it, so
        the next run starts from its preset and arguments again."""
        names = ["policy", *(reconfigure.TUNABLE if self.server is not None else ())]
        for name in names:
            try:
                self.rospy.delete_param(f"~{name}")
            except (KeyError, OSError):
                pass
        self.rospy.signal_shutdown("boids ros controller finished")


def run_controller(options: ControllerOptions, argv: Sequence[str] | None = None) -> int:
    """Runs ``boids ros controller`` until shut down; returns the ticks answered."""
    node = ControllerNode(options, argv)
    if not options.quiet:
        print(f"{node.name}: policy {options.policy} · {node.robots} robots · sync "
              f"{options.sync}" + (" · dynamic_reconfigure on ~set_parameters"
                                   if node.server is not None else ""), flush=True)
    try:
        return node.spin()
    finally:
        node.shutdown()
