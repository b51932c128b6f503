"""One message builder: the live ROS 1 nodes' messages are :class:`boids_env.rosmsgs.Messages`'
made of rospy's classes, and put the same bytes on the wire as the bags' ROS 1 messages (the
same content, the same look: :mod:`boids_env.style`'s colours and arrows)."""

from __future__ import annotations

import io

import numpy as np
import pytest

from boids_env.config import EnvConfig
from boids_env.eval.ros.messages import ros1_messages
from boids_env.rosmsgs import Messages

pytest.importorskip("rosbags")

NS = 1_234_567_890_123


def _bags_store():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from boids_env.rosbag import _TF_ROS1, TF

    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(_TF_ROS1, TF))
    return store


def _cases(m: Messages) -> dict[str, object]:
    positions = np.array([[0.0, 1.0], [2.0, -3.5], [4.25, 5.0]])
    quaternions = np.array([[0.0, 1.0], [0.6, 0.8], [-0.28, 0.96]])
    forces = {"separation": np.array([[0.1, 0.0], [0.0, 0.0]]),  # a zero force: DELETE
              "leader": np.array([[1.0, 2.0], [0.3, -0.1]]), "other": np.ones((2, 2))}
    grid = EnvConfig.from_kwargs(scene="lab").scene.occupancy()
    return {
        "nav_msgs/msg/Odometry": m.odometry(m.header(NS, 3, "map"), 2, positions[1],
                                            np.array([0.1, 0.3]), 0.0, 0.5, child="robot_2",
                                            quaternion=(0.6, 0.8)),
        "rosgraph_msgs/msg/Clock": m.clock(NS),
        "geometry_msgs/msg/Twist": m.twist(0.1, -0.2, 0.3),
        "tf2_msgs/msg/TFMessage": m.transforms(NS, 0, ["map"] * 3, ["a", "b", "c"],
                                               positions, quaternions),
        "visualization_msgs/msg/MarkerArray": m.force_markers(NS, 0, positions[1:], forces),
        "nav_msgs/msg/OccupancyGrid": m.occupancy_grid(NS, grid),
    }


def test_the_live_ros1_messages_are_the_bags_byte_for_byte(rospy):
    store = _bags_store()
    live = _cases(ros1_messages(rospy, 0.04))
    bag = _cases(Messages(store, True, 0.04))
    for msgtype, msg in live.items():
        wire = io.BytesIO()
        msg.serialize(wire)
        assert wire.getvalue() == bytes(store.serialize_ros1(bag[msgtype], msgtype)), msgtype
    info = live["nav_msgs/msg/OccupancyGrid"].info  # /map_metadata
    wire = io.BytesIO()
    info.serialize(wire)
    assert wire.getvalue() == bytes(store.serialize_ros1(
        bag["nav_msgs/msg/OccupancyGrid"].info, "nav_msgs/msg/MapMetaData"))


def test_the_live_ros1_markers_have_the_shared_look(rospy):
    from boids_env import style

    markers = _cases(ros1_messages(rospy, 0.04))["visualization_msgs/msg/MarkerArray"].markers
    leader = [m for m in markers if m.ns == "leader"]
    assert [m.id for m in leader] == [1, 2]
    c = leader[0].color
    assert (c.r, c.g, c.b, c.a) == pytest.approx(style.rgb01(style.RULE_COLOURS["leader"]))
    (tail, head) = leader[0].points
    drawn = style.arrow_vectors(np.array([[1.0, 2.0]]))[0]  # 0.5 m a unit, at most 0.25 m
    assert (head.x - tail.x, head.y - tail.y) == pytest.approx(tuple(drawn))
    separation = [m for m in markers if m.ns == "separation"]
    assert separation[1].action == 2 and not separation[1].points  # a zero force: deleted
