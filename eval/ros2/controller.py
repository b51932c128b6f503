"""``boids ros2 controller``: any policy (:class:`~boids_env.eval.graph.controller.
ControllerCore`) as a ROS 2 node over Zenoh, rmw_zenoh's way (no ROS install).

Reads the simulator's config from the latched ``/boids/env_config`` (or takes ``--robots``
for another odometry source) and its episodes from ``/boids/episode``; subscribes to every
``/robot_k/odom``; publishes every follower's ``/robot_k/cmd_vel`` (Twist, or TwistStamped
stamped with the tick it answers) and, for a policy with rule forces, their arrows on
``/<node>/markers``. ``sync`` as in ROS 1: ``stamp`` answers each tick exactly once, in order
(lockstep relies on it); ``rate`` every ``dt`` from the latest odometry.
"""

from __future__ import annotations

import threading
from typing import Any

from boids_env.config import EnvConfig
from boids_env.eval.graph.controller import (
    ControllerCore,
    ControllerOptions,
    base_config,
    controller_policy,
)
from boids_env.eval.graph.protocol import (
    CONFIG_TOPIC,
    EPISODE_TOPIC,
    EpisodeInfo,
    Tick,
    base_frame,
    cmd_topic,
    odom_topic,
    pedestrian_topic,
)
from boids_env.eval.ros2.options import TWIST, Ros2Options
from boids_env.eval.ros2.sim import MARKERS, ODOM, STRING, stop_on_signals
from boids_env.eval.ros2.wire import LATCHED

EPISODE_WAIT = 1.0
"""Seconds a tick that starts an episode waits for the episode's announcement."""


class Ros2Controller:
    """The controller node over Zenoh; :meth:`spin` answers ticks until stopped (or
    ``max_ticks``)."""

    def __init__(self, options: ControllerOptions, ros2: Ros2Options) -> None:
        from boids_env.eval.ros2.node import Node
        from boids_env.rosmsgs import Messages

        self.options, self.ros2 = options, ros2
        policy = controller_policy(options)  # a bad policy fails before the network
        self.stop = threading.Event()
        node = self.node = Node(options.node_name, domain=ros2.domain,
                                distribution=ros2.distribution, endpoints=ros2.endpoints())
        self.name = node.fqn
        self._config_text: str | None = None
        self._episode: EpisodeInfo | None = None
        self._lock = threading.Condition()
        node.subscribe(EPISODE_TOPIC, STRING, self._on_episode, LATCHED)
        if not options.env_fields:
            node.subscribe(CONFIG_TOPIC, STRING, self._on_config, LATCHED)
        try:
            base = self._base_config()
            self.core = ControllerCore(options, policy, base, self.name, self._episode_info)
            self.msgs = Messages(node.codec.store, False, self.core.config.world.robot_radius)
            robots = self.core.robots
            self.cmd_pubs = [node.publisher(cmd_topic(k), ros2.cmd_type)
                             for k in range(1, robots)]
            self.marker_pub = (node.publisher(f"{self.name}/markers", MARKERS)
                               if options.markers and hasattr(policy, "forces") else None)
            for k in range(robots):
                node.subscribe(odom_topic(k), ODOM,
                               lambda msg, robot=k: self._on_odom(msg, robot))
            for k in range(self.core.pedestrians):  # the crowd: sources after the robots
                node.subscribe(pedestrian_topic(k), ODOM,
                               lambda msg, source=robots + k: self._on_odom(msg, source))
        except BaseException:
            node.close()
            raise

    # ---------------------------------------------------------------------------- config
    def _on_config(self, msg: Any) -> None:
        with self._lock:
            self._config_text = msg.data

    def _on_episode(self, msg: Any) -> None:
        info = EpisodeInfo.from_json(msg.data)  # a ValueError drops it, counted as malformed
        with self._lock:
            self._episode = info
            self._lock.notify_all()

    def _episode_info(self, stamp: int) -> EpisodeInfo | None:
        """The latest announced episode; at a tick that starts one (with ``boids ros2 sim``'s
        config and ``sync="stamp"``, stamps jump only there), waits (at most
        :data:`EPISODE_WAIT`) for its announcement. The simulator announces an episode before
        its tick 0, but the announcement and the odometry are different publishers: should
        they take different routes (a router, then a direct link), tick 0 may come first."""
        with self._lock:
            if self.options.sync == "stamp" and not self.options.env_fields:
                self._lock.wait_for(lambda: self._episode is not None
                                    and self._episode.start_ns == stamp, EPISODE_WAIT)
            return self._episode

    def _base_config(self) -> EnvConfig:
        """The odometry source's env config: the given fields, else the simulator's."""
        def read() -> str | None:
            with self._lock:
                return self._config_text

        ros2 = self.ros2
        return base_config(self.options, self.name, read, self.stop.is_set,
                           source=f"{CONFIG_TOPIC} message", command="boids ros2 sim",
                           poll=0.05, where=f" (domain {ros2.domain}, {ros2.distribution}, "
                           f"connect {list(ros2.connect)})")

    # ------------------------------------------------------------------------- odometry
    def _on_odom(self, msg: Any, robot: int) -> None:
        p, v = msg.pose.pose.position, msg.twist.twist.linear
        q = msg.pose.pose.orientation
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        self.core.odometry(robot, stamp, p.x, p.y, v.x, v.y, q.z, q.w)

    # -------------------------------------------------------------------------- answers
    def answer(self, tick: Tick) -> Any:
        """Publishes the followers' commands for one tick (and the force markers)."""
        core, m = self.core, self.msgs
        commands = core.answer(tick)
        heading = core.heading
        for k, (pub, command) in enumerate(zip(self.cmd_pubs, commands, strict=True)):
            fields = core.twist_fields(command, heading)
            if self.ros2.cmd_type == TWIST:
                pub.publish(m.twist(*fields))
            else:  # stamped with the tick it answers, in the robot's own frame
                pub.publish(m.twist_stamped(m.header(tick.stamp_ns, 0, base_frame(k + 1)),
                                            *fields))
        world = core.world_forces()
        if world and self.marker_pub is not None:
            self.marker_pub.publish(m.force_markers(tick.stamp_ns, 0, tick.positions[1:],
                                                    world))
        return commands

    def stopped(self) -> bool:
        return self.stop.is_set()

    def spin(self) -> int:
        """Answers ticks until stopped or ``max_ticks`` are answered; returns how many."""
        return self.core.spin(self)

    def close(self) -> None:
        """Prints the malformed samples dropped (if any) and leaves the graph."""
        summary = self.node.dropped.summary()
        if summary is not None:
            print(summary, flush=True)
        self.node.close()


def run_controller(options: ControllerOptions, ros2: Ros2Options) -> int:
    """Runs ``boids ros2 controller`` until stopped (SIGINT, SIGTERM) or ``max_ticks``;
    returns the ticks answered."""
    node = Ros2Controller(options, ros2)
    try:
        with stop_on_signals(node.stop):
            if not options.quiet:
                print(f"{node.name}: policy {options.policy} · {node.core.robots} robots · "
                      f"sync {options.sync} · {ros2.distribution} · domain {ros2.domain} · "
                      f"cmd_vel {ros2.cmd_type}", flush=True)
            return node.spin()
    finally:
        node.close()
