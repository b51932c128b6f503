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

import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from boids_env.config import EnvConfig
from boids_env.eval.graph.controller import (
    SYNC_MODES,
    ControllerCore,
    ControllerOptions,
    base_config,
    controller_policy,
)
from boids_env.eval.graph.malformed import MalformedInput
from boids_env.eval.graph.protocol import (
    CONFIG_PARAM,
    EPISODE_PARAM,
    QUEUE_SIZE,
    EpisodeInfo,
    Tick,
    cmd_topic,
    odom_topic,
    pedestrian_topic,
)
from boids_env.eval.ros import reconfigure
from boids_env.eval.ros.messages import publisher, ros1_messages
from boids_env.eval.ros.rospy_path import import_rospy

__all__ = ["SYNC_MODES", "ControllerNode", "ControllerOptions", "controller_policy",
           "run_controller"]

ODOMETRY = "nav_msgs/Odometry"
FIRST_CONNECTION_WAIT = 1.0
"""Seconds a command publisher may wait, once, for the odometry source's node to connect to
it before its first message (a message published before a subscriber connects is lost, and a
lockstep simulator would then wait for it forever)."""


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
        rospy = self.rospy = import_rospy()
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from visualization_msgs.msg import MarkerArray

        rospy.init_node(options.node_name, argv=list(argv) if argv is not None else None,
                        disable_signals=True)
        self.name = rospy.get_name()
        base = self._base_config()
        core = self.core = ControllerCore(options, self.policy, base, self.name,
                                          self._episode_param)
        self.config, self.observer, self.model = core.config, core.observer, core.model
        self.robots, self.dt, self.agents = core.robots, core.dt, core.agents
        self.msgs = ros1_messages(rospy, self.config.world.robot_radius)
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
        self._source: str | None = None
        self._deaf: set[str] = set()
        self.dropped = MalformedInput(self.name, rospy.logwarn)
        """Odometry whose handling raised (rospy decodes the wire itself and drops what it
        cannot read): counted by topic and reason, the first of each logged."""
        # the robots, then the crowd's pedestrians: the assembler's sources in that order
        topics = [*(odom_topic(k) for k in range(self.robots)),
                  *(pedestrian_topic(k) for k in range(core.pedestrians))]
        self.odom_subs = [rospy.Subscriber(topic, Odometry, self._guarded(topic, source),
                                           queue_size=QUEUE_SIZE, tcp_nodelay=True)
                          for source, topic in enumerate(topics)]

    # ---------------------------------------------------------------------------- config
    def _base_config(self) -> EnvConfig:
        """The odometry source's env config: the given fields, else the simulator's."""
        rospy = self.rospy

        def read() -> str | None:
            return rospy.get_param(CONFIG_PARAM) if rospy.has_param(CONFIG_PARAM) else None

        return base_config(self.options, self.name, read, rospy.is_shutdown,
                           source=f"{CONFIG_PARAM} parameter", command="boids ros sim",
                           poll=0.2)

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
    def _guarded(self, topic: str, source: int) -> Any:
        """:meth:`_on_odom` of ``source`` under :meth:`MalformedInput.guard`: what it raises
        on a message is counted and logged once, not a traceback per message from rospy."""
        return lambda msg: self.dropped.guard(topic, ODOMETRY, lambda m: self._on_odom(
            m, source), msg)

    @property
    def malformed(self) -> dict[str, dict[str, int]]:
        """The odometry dropped as malformed so far, by topic and reason."""
        return self.dropped.counts

    def _on_odom(self, msg: Any, robot: int) -> None:
        if self._source is None:
            self._source = msg._connection_header.get("callerid")
        p, v = msg.pose.pose.position, msg.twist.twist.linear
        q = msg.pose.pose.orientation
        self.core.odometry(robot, msg.header.stamp.to_nsec(), p.x, p.y, v.x, v.y, q.z, q.w)

    # -------------------------------------------------------------------------- answers
    def _episode_param(self, stamp: int | None = None) -> EpisodeInfo | None:
        try:
            return EpisodeInfo.from_json(self.rospy.get_param(EPISODE_PARAM))
        except KeyError:
            return None

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

    @property
    def answered(self) -> int:
        """Ticks answered so far."""
        return self.core.answered

    def answer(self, tick: Tick) -> np.ndarray:
        """The commands (F, 2) for one tick, published (world frame; (v, ω) for robots with
        a heading); also the markers."""
        self._apply_params()
        before = self.core.nonfinite
        commands = self.core.answer(tick)
        if self.core.nonfinite > before:
            self.rospy.logwarn_throttle(5.0, f"{self.name}: {self.core.nonfinite - before} "
                                        f"non-finite command(s) (from non-finite odometry?) "
                                        f"sent as a stop")
        self._await_listener()
        heading = self.core.heading
        for pub, command in zip(self.cmd_pubs, commands, strict=True):
            pub.publish(self.msgs.twist(*self.core.twist_fields(command, heading)))
        # built only for a subscriber (RViz): rospy drops what nobody receives anyway
        if self.marker_pub is not None and self.marker_pub.get_num_connections():
            world = self.core.world_forces()
            if world:
                self.marker_pub.publish(self.msgs.force_markers(tick.stamp_ns, 0,
                                                                tick.positions[1:], world))
        return commands

    def stopped(self) -> bool:
        return bool(self.rospy.is_shutdown())

    def spin(self) -> int:
        """Answers ticks until the node shuts down or ``max_ticks`` are answered; returns
        the number answered."""
        return self.core.spin(self)

    def shutdown(self) -> None:
        """Leaves the graph; its Reynolds parameters leave the parameter server with it, so
        the next run starts from its preset and arguments again."""
        summary = self.dropped.summary()
        if summary is not None:
            print(summary, flush=True)
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
