"""``boids ros2 sim``: the simulator (:class:`~boids_env.eval.graph.sim.SimCore`) as a ROS 2
node over Zenoh, rmw_zenoh's way (no ROS install).

Publishes, for every robot k, ``/robot_k/odom`` (nav_msgs/Odometry, frame ``robot_k/odom``,
child ``robot_k/base_footprint``), ``/tf`` (``robot_k/odom`` → ``robot_k/base_footprint``)
and ``/tf_static`` (``map`` → ``robot_k/odom``, latched): REP 105's tree, as a TurtleBot3's
odometry gives it; ``/clock``; the scene as ``/map`` (nav_msgs/OccupancyGrid, latched) and
``/markers/obstacles``; the robots as ``/markers/robots``; with a lidar
(``--set lidar_rays=N``) every follower's ``/robot_k/scan`` (sensor_msgs/LaserScan in its
``base_footprint`` frame); with a person leading (``--leader person`` or ``trajectory``)
``/person/odom`` and, with a crowd (``--set crowd=N``), every pedestrian's
``/pedestrian_k/odom`` (nav_msgs/Odometry in ``map``, child ``pedestrian_k``, the velocity
in the twist: what the followers observe), people drawn on ``/markers/people``; the scripted
leader's ``/robot_0/cmd_vel`` (a walking person takes none); the config and each episode
on ``/boids/env_config`` and ``/boids/episode`` (latched std_msgs/String, where ROS 1 used
the parameter server).
Subscribes to every follower's ``/robot_k/cmd_vel`` (Twist, or TwistStamped).

Tick 0 waits until the graph's liveliness tokens show a publisher on every follower's
``cmd_vel`` and, from the same nodes, a subscription to every ``/robot_k/odom`` and
``/pedestrian_k/odom`` (and, for
``--wait-for NODE``, that node's subscriptions to the odometry, ``/tf`` and ``/clock``).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from boids_env.eval.graph.messages import crowd_odometry, robot_odometry, transforms
from boids_env.eval.graph.protocol import (
    CLOCK_START,
    CONFIG_TOPIC,
    EPISODE_TOPIC,
    MAP_FRAME,
    EpisodeInfo,
    base_frame,
    cmd_topic,
    config_json,
    odom_frame,
    odom_topic,
    odometry_topics,
    pedestrian_topic,
    period_ns,
)
from boids_env.eval.graph.sim import SimCore, SimEpisode, SimFrame, SimOptions, run_episodes
from boids_env.eval.ros2.options import TWIST, Ros2Options
from boids_env.eval.ros2.wire import LATCHED
from boids_env.rosbag import PEOPLE_TOPIC, PERSON_TOPIC

POLL = 0.01
"""Seconds between looks at the graph's liveliness tokens while tick 0 waits."""

ODOM = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
CLOCK = "rosgraph_msgs/msg/Clock"
GRID = "nav_msgs/msg/OccupancyGrid"
MARKERS = "visualization_msgs/msg/MarkerArray"
STRING = "std_msgs/msg/String"
SCAN = "sensor_msgs/msg/LaserScan"


def scan_topic(robot: int) -> str:
    """``/robot_k/scan``: a follower's simulated lidar (with ``lidar_rays``)."""
    return f"/robot_{robot}/scan"


@contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """SIGINT and SIGTERM set ``stop`` (the node leaves the graph cleanly) while inside."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    for s in previous:
        signal.signal(s, lambda *_: stop.set())
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


class Ros2Sim:
    """The simulator's ROS 2 transport (see the module's docstring)."""

    def __init__(self, core: SimCore, ros2: Ros2Options,
                 live: dict[str, Any] | None = None) -> None:
        from boids_env.eval.ros2.node import Node
        from boids_env.rosmsgs import Messages

        self.core, self.ros2 = core, ros2
        options = core.options
        self.view = None
        self._episodes = 0
        if live is not None:  # the Foxglove live view, beside the ROS 2 topics
            from boids_env.eval.liveview import FoxgloveView

            self.view = FoxgloveView(core.config, name="boids ros2 sim", **live)
            if not options.quiet:
                print(f"live view: open ws://127.0.0.1:{self.view.port} in Foxglove",
                      flush=True)
        self.stop = threading.Event()
        node = self.node = Node(options.node_name, domain=ros2.domain,
                                distribution=ros2.distribution, endpoints=ros2.endpoints())
        self.name = node.fqn
        self.msgs = Messages(node.codec.store, False, core.config.world.robot_radius)
        robots = core.robots
        # latched: what a late subscriber (RViz, Foxglove, the controller) needs first
        self.config_pub = node.publisher(CONFIG_TOPIC, STRING, LATCHED)
        self.config_pub.publish(self.msgs.string(config_json(core.config.to_dict())))
        self.episode_pub = node.publisher(EPISODE_TOPIC, STRING, LATCHED)
        start = period_ns(CLOCK_START)
        static = node.publisher("/tf_static", TF, LATCHED)
        zero = [[0.0, 0.0]] * robots
        static.publish(self.msgs.transforms(start, 0, [MAP_FRAME] * robots,
                                            [odom_frame(k) for k in range(robots)], zero, None))
        self.static_pub = static
        scene = core.config.scene
        # kept: an undeclared publisher takes its cache (the latched sample) with it
        self.map_pub = node.publisher("/map", GRID, LATCHED)
        self.map_pub.publish(self.msgs.occupancy_grid(start, scene.occupancy()))
        self.obstacles_pub = node.publisher("/markers/obstacles", MARKERS, LATCHED)
        self.obstacles_pub.publish(self.msgs.obstacle_markers(start, scene))
        self.clock_pub = node.publisher("/clock", CLOCK)
        self.tf_pub = node.publisher("/tf", TF)
        self.robot_markers = node.publisher("/markers/robots", MARKERS)
        self.odom_pubs = [node.publisher(odom_topic(k), ODOM) for k in range(robots)]
        self.scan_pubs = [node.publisher(scan_topic(k), SCAN) for k in range(1, robots)] \
            if core.config.observation.lidar_rays > 0 else []
        self.pedestrian_pubs = [node.publisher(pedestrian_topic(k), ODOM)
                                for k in range(core.pedestrians)]
        person = core.config.scenario.leader_radius is not None
        self.person_pub = node.publisher(PERSON_TOPIC, ODOM) if person else None
        self.people_pub = (node.publisher(PEOPLE_TOPIC, MARKERS)
                           if person or core.pedestrians else None)
        self._parents = [odom_frame(k) for k in range(robots)]
        self._children = [base_frame(k) for k in range(robots)]
        cmd_type = ros2.cmd_type
        self.leader_pub = None
        if core.external:
            node.subscribe(cmd_topic(0), cmd_type, self._on_leader)
        elif not core.person:
            self.leader_pub = node.publisher(cmd_topic(0), cmd_type)
        for k in range(1, robots):
            node.subscribe(cmd_topic(k), cmd_type,
                           lambda msg, index=k - 1: self._on_command(msg, index))
        self.poll = POLL
        self.wait_for_topics = [*odometry_topics(robots, core.pedestrians), "/tf", "/clock"]

    # ------------------------------------------------------------------------ callbacks
    def _twist(self, msg: Any) -> Any:
        return msg if self.ros2.cmd_type == TWIST else msg.twist

    def _on_command(self, msg: Any, index: int) -> None:
        t = self._twist(msg)
        if not self.core.post_command(index, t.linear.x, t.linear.y, t.angular.z):
            print(f"{self.name}: dropped a non-finite command for {self.core.agents[index]}",
                  flush=True)

    def _on_leader(self, msg: Any) -> None:
        t = self._twist(msg)
        if not self.core.post_leader_command(t.linear.x, t.linear.y):
            print(f"{self.name}: dropped a non-finite command for the leader", flush=True)

    @property
    def malformed(self) -> dict[str, dict[str, int]]:
        """The samples dropped as malformed so far, by topic and reason (the node's)."""
        return self.node.malformed

    # ---------------------------------------------------------------------------- graph
    def publishers(self, topic: str) -> set[str]:
        """The nodes whose liveliness tokens show a publisher on ``topic``."""
        return {t.fqn for t in self.node.endpoints_on(topic, "MP")}

    def receivers(self, topics: Sequence[str]) -> dict[str, set[str]]:
        """For each topic, the nodes whose liveliness tokens show a subscription to it."""
        return {t: {e.fqn for e in self.node.endpoints_on(t, "MS")} for t in topics}

    # ------------------------------------------------------------------------ publishing
    def stopped(self) -> bool:
        return self.stop.is_set()

    def publish_clock(self, stamp_ns: int) -> None:
        self.clock_pub.publish(self.msgs.clock(stamp_ns))

    def announce(self, info: EpisodeInfo) -> None:
        self.episode_pub.publish(self.msgs.string(info.to_json()))
        if self.view is not None and self._episodes:
            self.view.new_episode()
        self._episodes += 1

    def publish(self, frame: SimFrame) -> None:
        ns, m, q = frame.stamp_ns, self.msgs, frame.quaternions
        self.clock_pub.publish(m.clock(ns))
        for pub, msg in zip(self.odom_pubs,
                            robot_odometry(m, frame, self._parents, self._children), strict=True):
            pub.publish(msg)
        self.tf_pub.publish(transforms(m, frame, self._parents, self._children))
        self._publish_people(frame)
        if self.leader_pub is not None and frame.leader_command is not None:
            twist = m.twist(*frame.leader_command)
            self.leader_pub.publish(twist if self.ros2.cmd_type == TWIST else
                                    m.twist_stamped(m.header(ns, 0, base_frame(0)),
                                                    *frame.leader_command))
        if frame.scans is not None:
            for k, (pub, ranges) in enumerate(zip(self.scan_pubs, frame.scans, strict=True)):
                pub.publish(m.laser_scan(m.header(ns, 0, base_frame(k + 1)), ranges,
                                         frame.lidar_range))
        yaws = self._yaws(frame)
        self.robot_markers.publish(m.robot_markers(ns, 0, frame.positions, yaws))
        if self.view is not None:
            headings = None if q is None else np.stack([np.cos(yaws), np.sin(yaws)], axis=-1)
            self.view.show(frame.tick, frame.positions, headings,
                           self.core.env.episode_metrics(), frame.scans,
                           None if frame.crowd is None else frame.crowd.positions)

    def _publish_people(self, frame: SimFrame) -> None:
        """The crowd's odometry, the person's, and the people's markers."""
        ns, m, crowd = frame.stamp_ns, self.msgs, frame.crowd
        for pub, msg in zip(self.pedestrian_pubs, crowd_odometry(m, frame), strict=False):
            pub.publish(msg)  # none without a crowd
        person = None
        if self.person_pub is not None:
            person = frame.positions[0]
            self.person_pub.publish(m.odometry(m.header(ns, 0, MAP_FRAME), 0, person,
                                               frame.velocities[0], 0.0, child="person"))
        if self.people_pub is not None:
            walkers = np.zeros((0, 2)) if crowd is None else crowd.positions
            self.people_pub.publish(m.people_markers(
                ns, 0, person, walkers, self.core.config.scenario.person_radius))

    @staticmethod
    def _yaws(frame: SimFrame) -> Any:
        if frame.quaternions is None:
            return np.zeros(len(frame.positions))
        return 2 * np.arctan2(frame.quaternions[:, 0], frame.quaternions[:, 1])

    def close(self) -> None:
        """Stops the live view, prints the malformed samples dropped (if any), leaves the
        graph."""
        if self.view is not None:
            self.view.close()
        summary = self.node.dropped.summary()
        if summary is not None:
            print(summary, flush=True)
        self.node.close()


def run_sim(options: SimOptions, ros2: Ros2Options,
            live: dict[str, Any] | None = None) -> list[SimEpisode]:
    """Runs ``boids ros2 sim``: the episodes, each one's metrics table printed and, with
    ``options.out``, its files written; ``live``: also the Foxglove live view
    (:class:`~boids_env.eval.liveview.FoxgloveView`'s keyword arguments)."""
    core = SimCore(options, "boids ros2 sim")  # config errors before the network
    transport = Ros2Sim(core, ros2, live)
    try:
        with stop_on_signals(transport.stop):
            return run_episodes(core, transport, "ros2 sim", {"ros2": ros2.summary()})
    finally:
        transport.close()
