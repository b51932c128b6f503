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

import time
from collections.abc import Sequence
from typing import Any

from boids_env.eval.graph.protocol import (
    CLOCK_START,
    CONFIG_PARAM,
    EPISODE_PARAM,
    QUEUE_SIZE,
    EpisodeInfo,
    cmd_topic,
    config_json,
    odom_topic,
    pedestrian_topic,
    period_ns,
)
from boids_env.eval.graph.sim import (
    SimCore,
    SimEpisode,
    SimFrame,
    SimOptions,
    run_episodes,
    write_outputs,
)
from boids_env.eval.ros.messages import Messages, publisher

__all__ = ["SimEpisode", "SimNode", "SimOptions", "run_sim", "write_outputs"]

WARN_EVERY = 5.0
"""Seconds between the notes of a simulator waiting for its graph."""
POLL = 0.05
"""Seconds between checks of the graph while waiting for nodes to connect."""


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
        # the crowd's pedestrians, which the followers observe (a tick waits for them)
        self.pedestrian_pubs = [publisher(rospy, pedestrian_topic(k), Odometry, latch=True)
                                for k in range(core.pedestrians)]
        self.leader_pub = None
        if self.external:
            self.leader_sub = rospy.Subscriber(cmd_topic(0), Twist, self._on_leader,
                                               queue_size=QUEUE_SIZE, tcp_nodelay=True)
        elif not core.person:  # a walking person takes no cmd_vel
            self.leader_pub = publisher(rospy, cmd_topic(0), Twist)
        self.cmd_subs = [rospy.Subscriber(cmd_topic(k), Twist, self._on_command,
                                          callback_args=k - 1, queue_size=QUEUE_SIZE,
                                          tcp_nodelay=True)
                         for k in range(1, self.robots)]

    # ------------------------------------------------------------------------ callbacks
    def _on_command(self, msg: Any, index: int) -> None:
        if not self.core.post_command(index, msg.linear.x, msg.linear.y, msg.angular.z):
            self.rospy.logwarn_throttle(5.0, f"{self.name}: dropped a non-finite command for "
                                        f"{self.agents[index]}")

    def _on_leader(self, msg: Any) -> None:
        if not self.core.post_leader_command(msg.linear.x, msg.linear.y):
            self.rospy.logwarn_throttle(5.0, f"{self.name}: dropped a non-finite command for "
                                        f"the leader")

    # -------------------------------------------------------------------------- waiting
    def controllers(self) -> list[str]:
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
                for node in self.controllers():
                    deaf = [p.resolved_name for p in self.odom_pubs + self.pedestrian_pubs
                            if node not in {c.endpoint_id for c in p.impl.connections}]
                    if deaf:
                        missing.append(f"{node} to subscribe to {len(deaf)} odometry topics")
        if self.options.wait_for:
            wanted = {odom_topic(k) for k in range(self.robots)}
            wanted |= {pedestrian_topic(k) for k in range(self.core.pedestrians)}
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

    def wait_ready(self, core: SimCore) -> None:
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
                self.clock_pub.publish(self.msgs.clock(core.next_start_ns + steps * period))
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
        core.next_start_ns += (shown + 1) * period

    # ------------------------------------------------------------------ the transport
    def shutdown_requested(self) -> bool:
        return bool(self.rospy.is_shutdown())

    def announce(self, info: EpisodeInfo) -> None:
        self.rospy.set_param(EPISODE_PARAM, info.to_json())

    def publish(self, frame: SimFrame) -> None:
        """Publishes one tick: ``/clock``, every ``/robot_k/odom``, every
        ``/pedestrian_k/odom`` of a crowd, ``/tf`` and the scripted leader's ``cmd_vel``."""
        stamp = self.msgs.time(frame.stamp_ns)
        self.clock_pub.publish(self.msgs.Clock(clock=stamp))
        q = frame.quaternions
        for k, pub in enumerate(self.odom_pubs):
            pub.publish(self.msgs.odometry(k, stamp, frame.positions[k], frame.velocities[k],
                                           None if q is None else q[k], frame.turn_rates[k]))
        if frame.crowd is not None:
            for k, pub in enumerate(self.pedestrian_pubs):
                pub.publish(self.msgs.pedestrian_odometry(
                    k, stamp, frame.crowd.positions[k], frame.crowd.velocities[k]))
        self.tf_pub.publish(self.msgs.transforms(stamp, frame.positions, q))
        if self.leader_pub is not None and frame.leader_command is not None:
            self.leader_pub.publish(self.msgs.twist(*frame.leader_command))

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
        self.rospy.signal_shutdown("boids ros sim finished")


def run_sim(options: SimOptions, argv: Sequence[str] | None = None) -> list[SimEpisode]:
    """Runs ``boids ros sim``: the episodes, each one's metrics table printed and, with
    ``options.out``, its files written."""
    node = SimNode(options, argv)
    try:
        return run_episodes(node.core, node, "ros sim")
    finally:
        node.shutdown()
