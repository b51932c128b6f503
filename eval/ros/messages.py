"""Building and reading the graph's ROS messages (rospy's message classes, imported through
:func:`~boids_env.eval.ros.rospy_path.import_rospy` when a node starts)."""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.eval.graph.protocol import MAP_FRAME, pedestrian_frame, robot_frame
from boids_env.eval.ros.rospy_path import import_rospy

FloatArray = npt.NDArray[np.float64]

RULE_COLOURS = {  # RGB in [0, 1], as the original RViz view and our renderer
    "separation": (0.9, 0.0, 0.0), "cohesion": (0.0, 0.67, 0.0),
    "alignment": (0.0, 0.0, 1.0), "leader": (0.47, 0.78, 1.0)}
FORCE_ARROW_SCALE = 1.0
"""Marker arrows are ``force × FORCE_ARROW_SCALE`` metres long (N, or m for the leader term,
as :mod:`boids_env.render` draws them), from the robot's position."""


def publisher(rospy: Any, topic: str, data_class: Any, *, latch: bool = False) -> Any:
    """A publisher that writes synchronously (``queue_size=None``): rospy's queued publisher
    hands every message to a thread and yields the GIL (``time.sleep(0)``), 0.2–0.3 ms a
    message, which doubled a lockstep tick; a synchronous write also means back-pressure
    instead of dropped messages when a subscriber (a recorder) is slow. rospy's warning about
    the missing queue size is silenced: no queue is the choice."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SyntaxWarning)
        return rospy.Publisher(topic, data_class, queue_size=None, latch=latch,
                               tcp_nodelay=True)


class Messages:
    """The message classes the nodes use, and builders that reuse one message object per
    robot (rospy serialises in ``publish``, so reusing them is safe)."""

    def __init__(self) -> None:
        self.rospy = import_rospy()
        from geometry_msgs.msg import Point, TransformStamped, Twist
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock
        from tf2_msgs.msg import TFMessage
        from visualization_msgs.msg import Marker, MarkerArray

        self.Odometry, self.Twist, self.Clock = Odometry, Twist, Clock
        self.TFMessage, self.TransformStamped = TFMessage, TransformStamped
        self.Marker, self.MarkerArray, self.Point = Marker, MarkerArray, Point
        self._odom: dict[int, Any] = {}
        self._walkers: dict[int, Any] = {}
        self._transforms: dict[int, Any] = {}
        self._markers: dict[tuple[str, int], Any] = {}

    def time(self, stamp_ns: int) -> Any:
        """A ``rospy.Time`` of ``stamp_ns`` nanoseconds (exact)."""
        return self.rospy.Time(stamp_ns // 10**9, stamp_ns % 10**9)

    def clock(self, stamp_ns: int) -> Any:
        return self.Clock(clock=self.time(stamp_ns))

    def occupancy_grid(self, grid: Any, stamp_ns: int) -> tuple[Any, Any]:
        """``/map`` and ``/map_metadata`` of a scene's cells (an
        :class:`~boids_env.world.scene.OccupancyGrid`), as ``map_server`` publishes them."""
        import math

        from geometry_msgs.msg import Pose
        from nav_msgs.msg import MapMetaData, OccupancyGrid

        h, w = grid.cells.shape
        x0, y0, yaw = grid.origin
        info = MapMetaData(map_load_time=self.time(stamp_ns), resolution=grid.resolution,
                           width=w, height=h, origin=Pose())
        info.origin.position.x, info.origin.position.y = float(x0), float(y0)
        info.origin.orientation.z, info.origin.orientation.w = math.sin(yaw / 2), math.cos(
            yaw / 2)
        msg = OccupancyGrid(info=info, data=grid.cells.reshape(-1).tolist())
        msg.header.stamp, msg.header.frame_id = self.time(stamp_ns), MAP_FRAME
        return msg, info

    def odometry(self, robot: int, stamp: Any, position: FloatArray, velocity: FloatArray,
                 quaternion: FloatArray | None = None, turn_rate: float = 0.0) -> Any:
        """``robot``'s Odometry, zero covariances: position and measured velocity in the map
        frame with identity orientation (a holonomic Sphero does not turn), or, for a robot
        with a heading, oriented by ``quaternion`` (z, w) with ``velocity`` the twist in its
        own frame and ``turn_rate`` its angular.z (REP 105)."""
        msg = self._odom.get(robot)
        if msg is None:
            msg = self._odom[robot] = self.Odometry()
            msg.header.frame_id = MAP_FRAME
            msg.child_frame_id = robot_frame(robot)
            msg.pose.pose.orientation.w = 1.0
        msg.header.stamp = stamp
        msg.pose.pose.position.x = float(position[0])
        msg.pose.pose.position.y = float(position[1])
        if quaternion is not None:
            msg.pose.pose.orientation.z = float(quaternion[0])
            msg.pose.pose.orientation.w = float(quaternion[1])
            msg.twist.twist.angular.z = float(turn_rate)
        msg.twist.twist.linear.x = float(velocity[0])
        msg.twist.twist.linear.y = float(velocity[1])
        return msg

    def pedestrian_odometry(self, pedestrian: int, stamp: Any, position: FloatArray,
                            velocity: FloatArray) -> Any:
        """Pedestrian ``pedestrian``'s Odometry: position and velocity in the map frame,
        identity orientation, child frame ``pedestrian_k``."""
        msg = self._walkers.get(pedestrian)
        if msg is None:
            msg = self._walkers[pedestrian] = self.Odometry()
            msg.header.frame_id = MAP_FRAME
            msg.child_frame_id = pedestrian_frame(pedestrian)
            msg.pose.pose.orientation.w = 1.0
        msg.header.stamp = stamp
        msg.pose.pose.position.x = float(position[0])
        msg.pose.pose.position.y = float(position[1])
        msg.twist.twist.linear.x = float(velocity[0])
        msg.twist.twist.linear.y = float(velocity[1])
        return msg

    def transforms(self, stamp: Any, positions: FloatArray,
                   quaternions: FloatArray | None = None) -> Any:
        """One ``/tf`` message: ``map`` → ``robot_k`` for every robot (turned by its
        quaternion (z, w) when it has a heading)."""
        out = []
        for robot, (x, y) in enumerate(positions.tolist()):
            tf = self._transforms.get(robot)
            if tf is None:
                tf = self._transforms[robot] = self.TransformStamped()
                tf.header.frame_id = MAP_FRAME
                tf.child_frame_id = robot_frame(robot)
                tf.transform.rotation.w = 1.0
            tf.header.stamp = stamp
            tf.transform.translation.x = x
            tf.transform.translation.y = y
            if quaternions is not None:
                tf.transform.rotation.z = float(quaternions[robot, 0])
                tf.transform.rotation.w = float(quaternions[robot, 1])
            out.append(tf)
        return self.TFMessage(transforms=out)

    def twist(self, vx: float, vy: float, turn_rate: float = 0.0) -> Any:
        """A velocity command: world-frame (vx, vy), or for a robot with a heading its own
        frame's (linear.x, 0) and angular.z ``turn_rate``."""
        msg = self.Twist()
        msg.linear.x = float(vx)
        msg.linear.y = float(vy)
        msg.angular.z = float(turn_rate)
        return msg

    def force_markers(self, stamp: Any, positions: FloatArray,
                      forces: dict[str, FloatArray]) -> Any:
        """Arrows of each rule's weighted force per follower (namespace = rule, id = robot
        index), ``FORCE_ARROW_SCALE`` metres per unit, from the follower's position."""
        markers = []
        for rule, vectors in forces.items():
            r, g, b = RULE_COLOURS.get(rule, (0.5, 0.5, 0.5))
            for i, (start, vector) in enumerate(zip(positions[1:].tolist(),
                                                    np.asarray(vectors, dtype=float).tolist(),
                                                    strict=True)):
                m = self._markers.get((rule, i))
                if m is None:
                    m = self._markers[(rule, i)] = self.Marker()
                    m.header.frame_id = MAP_FRAME
                    m.ns = rule
                    m.id = i + 1
                    m.type = self.Marker.ARROW
                    m.action = self.Marker.ADD
                    m.pose.orientation.w = 1.0
                    m.points = [self.Point(), self.Point()]
                    m.scale.x, m.scale.y, m.scale.z = 0.02, 0.04, 0.05  # shaft, head
                    m.color.r, m.color.g, m.color.b, m.color.a = r, g, b, 1.0
                m.header.stamp = stamp
                tail, head = m.points
                tail.x, tail.y = start
                head.x = start[0] + FORCE_ARROW_SCALE * vector[0]
                head.y = start[1] + FORCE_ARROW_SCALE * vector[1]
                markers.append(m)
        return self.MarkerArray(markers=markers)
