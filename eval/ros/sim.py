"""``boids ros sim``: the pymunk world (:class:`~boids_env.environment.BoidsEnv`) as a ROS 1
node in place of the study's Stage simulator.

Publishes the scene as ``map_server`` does (``/map``, ``/map_metadata``, latched, once) and,
for every robot k, ``/robot_k/odom`` (latched) once per control period, ``/tf``
(``map`` → ``robot_k``), ``/clock`` (sets ``/use_sim_time``), and the scripted leader's command
on ``/robot_0/cmd_vel`` (as the study's leader controller did; with ``--path external`` the
sim subscribes to it instead, for a teleop; a person walked by the pedestrian model takes
none). With a crowd (``--crowd N``), every pedestrian's ``/pedestrian_k/odom`` (latched,
nav_msgs/Odometry in ``map``, child ``pedestrian_k``, its velocity in the twist) with each
tick: what the followers observe. Subscribes to every follower's
``/robot_k/cmd_vel``. See :mod:`boids_env.eval.graph.protocol` for the timing (lockstep or real
time, the 0.5 s command timeout, stamps and episodes).

The simulation itself (stepping, lockstep, recording) is
:class:`~boids_env.eval.graph.sim.SimCore`; this module is its ROS 1 transport. Each
episode's samples are recorded exactly as ``boids run`` records them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from boids_env.eval.graph.malformed import MalformedInput
from boids_env.eval.graph.messages import crowd_odometry, robot_odometry, transforms
from boids_env.eval.graph.protocol import (
    CLOCK_START,
    CONFIG_PARAM,
    EPISODE_PARAM,
    MAP_FRAME,
    QUEUE_SIZE,
    EpisodeInfo,
    cmd_topic,
    config_json,
    odom_topic,
    odometry_topics,
    pedestrian_topic,
    period_ns,
    robot_frame,
)
from boids_env.eval.graph.sim import (
    SimCore,
    SimEpisode,
    SimFrame,
    SimOptions,
    run_episodes,
    write_outputs,
)
from boids_env.eval.ros.messages import publisher, ros1_messages
from boids_env.eval.ros.rospy_path import import_rospy

__all__ = ["SimEpisode", "SimNode", "SimOptions", "run_sim", "write_outputs"]

TWIST = "geometry_msgs/Twist"
POLL = 0.05
"""Seconds between checks of the graph while waiting for nodes to connect (each asks the
master and the nodes over XML-RPC)."""


class SimNode:
    """The simulator node: builds the world (config errors raise before any ROS call), joins
    the graph as ``options.node_name`` and runs episodes with :meth:`run_episode`.

    Args:
        options: how to run.
        argv: the command line, for ROS remapping arguments (``name:=value``).
    """

    def __init__(self, options: SimOptions, argv: Sequence[str] | None = None) -> None:
        self.options = options
        core = self.core = SimCore(options, "boids ros sim")
        self.env, self.config, self.board = core.env, core.config, core.board
        self.robots, self.dt, self.agents = core.robots, core.dt, core.agents
        self.external, self.heading = core.external, core.heading
        config = self.config
        rospy = self.rospy = import_rospy()
        self.msgs = ros1_messages(rospy, config.world.robot_radius)
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock
        from tf2_msgs.msg import TFMessage

        rospy.init_node(options.node_name, argv=list(argv) if argv is not None else None,
                        disable_signals=True)
        self.name = rospy.get_name()
        self.dropped = MalformedInput(self.name, rospy.logwarn)
        """Commands whose handling raised (rospy decodes the wire itself and drops what it
        cannot read): counted by topic and reason, the first of each logged."""
        # This node is the clock (as Stage is): the nodes started after it run on sim time.
        rospy.set_param("/use_sim_time", True)
        rospy.set_param(CONFIG_PARAM, config_json(config.to_dict()))
        self.clock_pub = publisher(rospy, "/clock", Clock, latch=True)
        # the scene as map_server publishes a map: latched, once
        from nav_msgs.msg import MapMetaData, OccupancyGrid

        grid = self.msgs.occupancy_grid(period_ns(CLOCK_START), config.scene.occupancy())
        self.map_pub = publisher(rospy, "/map", OccupancyGrid, latch=True)
        self.map_meta_pub = publisher(rospy, "/map_metadata", MapMetaData, latch=True)
        self.map_pub.publish(grid)
        self.map_meta_pub.publish(grid.info)
        self.tf_pub = publisher(rospy, "/tf", TFMessage)
        self.odom_pubs = [publisher(rospy, odom_topic(k), Odometry, latch=True)
                          for k in range(self.robots)]
        # the crowd's pedestrians, which the followers observe (a tick waits for them)
        self.pedestrian_pubs = [publisher(rospy, pedestrian_topic(k), Odometry, latch=True)
                                for k in range(core.pedestrians)]
        self.leader_pub = None
        if self.external:
            self.leader_sub = rospy.Subscriber(cmd_topic(0), Twist, self._guarded(
                cmd_topic(0), self._on_leader), queue_size=QUEUE_SIZE, tcp_nodelay=True)
        elif not core.person:  # a walking person takes no cmd_vel
            self.leader_pub = publisher(rospy, cmd_topic(0), Twist)
        self.cmd_subs = [rospy.Subscriber(
            cmd_topic(k), Twist, self._guarded(
                cmd_topic(k), lambda msg, index=k - 1: self._on_command(msg, index)),
            queue_size=QUEUE_SIZE, tcp_nodelay=True) for k in range(1, self.robots)]
        self._subscriptions = {cmd_topic(k): sub for k, sub in enumerate(self.cmd_subs, 1)}
        self._publishers = {pub.resolved_name: pub for pub in (
            self.clock_pub, self.tf_pub, *self.odom_pubs, *self.pedestrian_pubs,
            *([self.leader_pub] if self.leader_pub is not None else []))}
        self._parents = [MAP_FRAME] * self.robots  # the study's frames: map -> robot_k
        self._children = [robot_frame(k) for k in range(self.robots)]
        self.poll = POLL
        # a recorder (rosbag record -a) needs the commands too: boids ros metrics reads them
        self.wait_for_topics = [*odometry_topics(self.robots, core.pedestrians),
                                *(cmd_topic(k) for k in range(0 if self.leader_pub else 1,
                                                              self.robots)),
                                "/clock", "/tf"]

    # ------------------------------------------------------------------------ callbacks
    def _guarded(self, topic: str, callback: Any) -> Any:
        """``callback`` under :meth:`MalformedInput.guard`: what it raises on a message is
        counted and logged once, not a traceback per message from rospy."""
        return lambda msg: self.dropped.guard(topic, TWIST, callback, msg)

    @property
    def malformed(self) -> dict[str, dict[str, int]]:
        """The commands dropped as malformed so far, by topic and reason."""
        return self.dropped.counts

    def _on_command(self, msg: Any, index: int) -> None:
        if not self.core.post_command(index, msg.linear.x, msg.linear.y, msg.angular.z):
            self.rospy.logwarn_throttle(5.0, f"{self.name}: dropped a non-finite command for "
                                        f"{self.agents[index]}")

    def _on_leader(self, msg: Any) -> None:
        if not self.core.post_leader_command(msg.linear.x, msg.linear.y):
            self.rospy.logwarn_throttle(5.0, f"{self.name}: dropped a non-finite command for "
                                        f"the leader")

    # ---------------------------------------------------------------------------- graph
    def publishers(self, topic: str) -> set[str]:
        """The nodes connected to this node's subscription to ``topic``."""
        sub = self._subscriptions.get(topic)
        return set() if sub is None else {c.callerid_pub for c in sub.impl.connections}

    def receivers(self, topics: Sequence[str]) -> dict[str, set[str]]:
        """For each topic, the nodes every publisher on it is connected to: this node's own
        publishers answer themselves, others through :meth:`_outbound_links`."""
        foreign = {t for t in topics if t not in self._publishers}
        links = self._outbound_links(foreign) if foreign else {}
        out = {}
        for topic in topics:
            pub = self._publishers.get(topic)
            if pub is not None:
                out[topic] = {c.endpoint_id for c in pub.impl.connections}
            else:
                peers = links.get(topic) or [set()]
                out[topic] = set.intersection(*peers)
        return out

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

    # ------------------------------------------------------------------ the transport
    def stopped(self) -> bool:
        return bool(self.rospy.is_shutdown())

    def publish_clock(self, stamp_ns: int) -> None:
        self.clock_pub.publish(self.msgs.clock(stamp_ns))

    def announce(self, info: EpisodeInfo) -> None:
        self.rospy.set_param(EPISODE_PARAM, info.to_json())

    def publish(self, frame: SimFrame) -> None:
        """Publishes one tick: ``/clock``, every ``/robot_k/odom``, every
        ``/pedestrian_k/odom`` of a crowd, ``/tf`` and the scripted leader's ``cmd_vel``."""
        m, parents, children = self.msgs, self._parents, self._children
        self.clock_pub.publish(m.clock(frame.stamp_ns))
        for pub, msg in zip(self.odom_pubs, robot_odometry(m, frame, parents, children),
                            strict=True):
            pub.publish(msg)
        for pub, msg in zip(self.pedestrian_pubs, crowd_odometry(m, frame), strict=False):
            pub.publish(msg)  # none without a crowd
        if self.tf_pub.get_num_connections():  # rospy drops what nobody receives anyway
            self.tf_pub.publish(transforms(m, frame, parents, children))
        if self.leader_pub is not None and frame.leader_command is not None:
            self.leader_pub.publish(m.twist(*frame.leader_command))

    def run_episode(self, index: int) -> SimEpisode:
        """Runs one whole episode (seed ``options.seed + index``) and returns it."""
        return self.core.run_episode(index, self)

    def shutdown(self) -> None:
        """Leaves the graph, removing the parameters that describe this run (a controller
        started later must wait for the next simulator, not read this one's config);
        ``/use_sim_time`` stays, as Stage leaves it."""
        for name in (CONFIG_PARAM, EPISODE_PARAM):
            try:
                self.rospy.delete_param(name)
            except (KeyError, OSError):
                pass
        summary = self.dropped.summary()
        if summary is not None:
            print(summary, flush=True)
        self.rospy.signal_shutdown("boids ros sim finished")


def run_sim(options: SimOptions, argv: Sequence[str] | None = None) -> list[SimEpisode]:
    """Runs ``boids ros sim``: the episodes, each one's metrics table printed and, with
    ``options.out``, its files written."""
    node = SimNode(options, argv)
    try:
        return run_episodes(node.core, node, "ros sim")
    finally:
        node.shutdown()
