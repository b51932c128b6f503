"""rmw_zenoh's conventions (:mod:`boids_env.eval.ros2.wire`) against rmw_zenoh's own
examples (its ``docs/design.md``) and rosbags' type hashes, and the messages our nodes publish
against rosbags' CDR, for every distribution we claim. No Zenoh needed."""

from __future__ import annotations

import numpy as np
import pytest

from boids_env.eval.ros2 import wire

# Verbatim from ros2/rmw_zenoh docs/design.md (a listener's node token and a talker's
# publisher token with depth 7) and the key expression of its talker's /chatter.
DESIGN_NODE = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
DESIGN_PUB = ("@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
              "std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021"
              "743503259e948f6b1a18/::,7:,:,:,,")
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"

# every type the nodes publish or subscribe to
TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped",
         "tf2_msgs/msg/TFMessage", "rosgraph_msgs/msg/Clock", "nav_msgs/msg/OccupancyGrid",
         "visualization_msgs/msg/MarkerArray", "std_msgs/msg/String",
         "sensor_msgs/msg/LaserScan")


def test_rmw_zenohs_own_tokens_parse():
    node = wire.parse_token(DESIGN_NODE)
    assert (node.domain, node.kind, node.node, node.namespace, node.node_id,
            node.entity_id) == (0, "NN", "listener", "/", 0, 0)
    assert node.fqn == "/listener"
    pub = wire.parse_token(DESIGN_PUB)
    assert (pub.kind, pub.node, pub.topic, pub.msgtype, pub.type_hash) == (
        "MP", "talker", "/chatter", "std_msgs/msg/String", STRING_HASH)
    assert pub.qos == wire.Qos(depth=7)
    assert pub.key() == DESIGN_PUB and node.key() == DESIGN_NODE  # and back, unchanged


def test_key_expression_and_hash_of_the_design_docs_talker():
    from rosbags.typesys import Stores, get_typestore

    for distribution in wire.DISTRIBUTIONS:
        store = get_typestore(getattr(Stores, f"ROS2_{distribution.upper()}"))
        h = store.hash_rihs01("std_msgs/msg/String")
        assert h == STRING_HASH, distribution
        assert wire.topic_key(0, "/chatter", "std_msgs/msg/String", h) == \
            f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    assert wire.topic_key(7, "/robot_1/odom", "nav_msgs/msg/Odometry", STRING_HASH) \
        .startswith("7/robot_1/odom/nav_msgs::msg::dds_::Odometry_/")


@pytest.mark.parametrize("distribution", wire.DISTRIBUTIONS)
def test_the_codec_hashes_every_type_as_rosbags_does(distribution):
    from rosbags.typesys import Stores, get_typestore

    from boids_env.eval.ros2.node import Codec

    store = get_typestore(getattr(Stores, f"ROS2_{distribution.upper()}"))
    codec = Codec(distribution)
    for msgtype in TYPES:
        assert codec.type_hash(msgtype) == store.hash_rihs01(msgtype), (distribution, msgtype)


def test_qos_chunks_keep_defaults_empty():
    assert wire.Qos().to_key() == "::,:,:,:,,"
    assert wire.LATCHED.to_key() == ":1:,1:,:,:,,"
    assert wire.Qos(reliability=wire.BEST_EFFORT, history=wire.KEEP_ALL).to_key() == \
        "2::2,:,:,:,,"
    for qos in (wire.Qos(), wire.LATCHED, wire.Qos(depth=7), wire.Qos(history=wire.KEEP_ALL)):
        assert wire.Qos.from_key(qos.to_key()) == qos
    with pytest.raises(ValueError, match="QoS chunk"):
        wire.Qos.from_key("1:2")
    with pytest.raises(ValueError, match="durability"):
        wire.Qos(durability=5)


def test_bad_tokens_and_names_are_refused_by_name():
    with pytest.raises(ValueError, match="not an rmw_zenoh liveliness token"):
        wire.parse_token("@ros2_lv/0/abc")
    with pytest.raises(ValueError, match="entity kind"):
        wire.parse_token(DESIGN_NODE.replace("/NN/", "/XX/"))
    with pytest.raises(ValueError, match="13 chunks"):
        wire.parse_token(DESIGN_PUB.rsplit("/", 2)[0])
    with pytest.raises(ValueError, match="domain must be"):
        wire.topic_key(233, "/a", "std_msgs/msg/String", STRING_HASH)
    with pytest.raises(ValueError, match="topic must be"):
        wire.topic_key(0, "robot/odom", "std_msgs/msg/String", STRING_HASH)
    with pytest.raises(ValueError, match="type_hash"):
        wire.topic_key(0, "/a", "std_msgs/msg/String", "RIHS01_xyz")


def test_our_tokens_round_trip_through_the_grammar():
    token = wire.Token(3, "1f2e", 0, 4, "MS", "", "/", "boids_sim", "/robot_1/cmd_vel",
                       "geometry_msgs/msg/TwistStamped", STRING_HASH, wire.LATCHED)
    key = token.key()
    assert key == ("@ros2_lv/3/1f2e/0/4/MS/%/%/boids_sim/%robot_1%cmd_vel/"
                   f"geometry_msgs::msg::dds_::TwistStamped_/{STRING_HASH}/:1:,1:,:,:,,")
    assert wire.parse_token(key) == token


def test_the_attachment_is_rmw_zenohs_33_bytes():
    gid = bytes(range(16))
    data = wire.attachment(1, 0x0102030405060708, gid)
    expected = (b"\x01" + b"\x00" * 7 + bytes([8, 7, 6, 5, 4, 3, 2, 1]) + b"\x10" + gid)
    assert data == expected and len(data) == 33
    assert wire.parse_attachment(data) == (1, 0x0102030405060708, gid)
    with pytest.raises(ValueError, match="33 bytes"):
        wire.parse_attachment(data[:-1])


@pytest.mark.parametrize("distribution", wire.DISTRIBUTIONS)
def test_every_message_the_nodes_build_is_rosbags_cdr(distribution):
    """The messages of a simulator tick, built by the one message module
    (:mod:`boids_env.rosmsgs`) with the distribution's types, serialise, read back and
    serialise to the same bytes."""
    from boids_env.eval.ros2.node import Codec
    from boids_env.rosmsgs import Messages
    from boids_env.world.scenes import load_scene

    codec = Codec(distribution)
    m = Messages(codec.store, False, 0.036)
    pos = np.array([[0.5, -1.25], [1.0, 2.0]])
    q = np.array([[0.1, 0.99498743710662], [0.0, 1.0]])
    scene = load_scene("lab")
    built = {
        "nav_msgs/msg/Odometry": m.odometry(m.header(1_500_000_000, 0, "robot_1/odom"), 1,
                                            pos[1], pos[0], 0.0, 0.3,
                                            child="robot_1/base_footprint",
                                            quaternion=(q[0, 0], q[0, 1])),
        "tf2_msgs/msg/TFMessage": m.transforms(10, 0, ["a/odom", "b/odom"], ["a", "b"], pos,
                                               q),
        "geometry_msgs/msg/TwistStamped": m.twist_stamped(m.header(5, 0, "x"), 0.2, 0.0, 1.0),
        "geometry_msgs/msg/Twist": m.twist(0.2, 0.1),
        "rosgraph_msgs/msg/Clock": m.clock(123),
        "nav_msgs/msg/OccupancyGrid": m.occupancy_grid(0, scene.occupancy()),
        "visualization_msgs/msg/MarkerArray": m.obstacle_markers(0, scene),
        "std_msgs/msg/String": m.string('{"index": 0}'),
        "sensor_msgs/msg/LaserScan": m.laser_scan(m.header(7, 0, "robot_1/base_footprint"),
                                                  np.array([0.5, 3.0, 1.25, 2.0]), 3.0),
    }
    for msgtype, msg in built.items():
        data = codec.encode(msg, msgtype)
        assert data[:4] == wire.CDR_LE_HEADER
        assert codec.encode(codec.decode(data, msgtype), msgtype) == data, msgtype
    odom = codec.decode(codec.encode(built["nav_msgs/msg/Odometry"], "nav_msgs/msg/Odometry"),
                        "nav_msgs/msg/Odometry")
    assert (odom.pose.pose.orientation.z, odom.pose.pose.orientation.w) == (q[0, 0], q[0, 1])
    assert odom.child_frame_id == "robot_1/base_footprint"
