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


def test_sample_fault_names_what_is_wrong_before_decoding():
    from boids_env.eval.graph import malformed

    key = wire.topic_key(0, "/chatter", "std_msgs/msg/String", STRING_HASH)
    att = wire.attachment(1, 2, bytes(16))
    assert wire.sample_fault(key, key, att, b"\x00\x01\x00\x00", "jazzy") is None
    other_hash = key.replace(STRING_HASH, "RIHS01_" + "0" * 64)
    reason, detail = wire.sample_fault(other_hash, key, att, b"x", "kilted")
    assert reason == malformed.WRONG_HASH and "kilted's" in detail and "--distribution" in detail
    other_type = key.replace("String_", "Bool_")
    assert wire.sample_fault(other_type, key, att, b"x", "jazzy") == (
        malformed.WRONG_TYPE, "a sample of std_msgs/msg/Bool was put on it")
    assert wire.sample_fault(key, key, None, b"x", "jazzy")[0] == malformed.NO_ATTACHMENT
    assert wire.sample_fault(key, key, att[:-1], b"x", "jazzy")[0] == malformed.BAD_ATTACHMENT
    assert wire.sample_fault(key, key, att, b"", "jazzy")[0] == malformed.EMPTY


class _Sample:
    """What a Zenoh subscriber's callback is given, without Zenoh."""

    class _Bytes:
        def __init__(self, data: bytes) -> None:
            self.data = data

        def to_bytes(self) -> bytes:
            return self.data

    def __init__(self, key: str, payload: bytes, attachment: bytes | None) -> None:
        self.key_expr = key
        self.payload = self._Bytes(payload)
        self.attachment = None if attachment is None else self._Bytes(attachment)


def test_every_sample_the_reader_is_given_is_decoded_or_counted_never_raised():
    """Fuzzing the ROS 2 wire (issue 55): samples of every type the nodes read, cut short,
    bit-flipped, given another type's body, random bytes, with and without an attachment and
    under other types and hashes. Each is handed to the callback decoded or dropped and
    counted, never raised, each within a time budget."""
    import time
    from types import SimpleNamespace

    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    from boids_env.eval.graph.malformed import MalformedInput
    from boids_env.eval.ros2.node import Codec, Node
    from boids_env.rosmsgs import Messages

    codec = Codec("jazzy")
    m = Messages(codec.store, False, 0.036)
    bodies = {"nav_msgs/msg/Odometry": m.odometry(m.header(5, 0, "robot_1/odom"), 1,
                                                  np.array([1.0, 2.0]), np.zeros(2), 0.0),
              "geometry_msgs/msg/Twist": m.twist(0.1, 0.2),
              "geometry_msgs/msg/TwistStamped": m.twist_stamped(m.header(5, 0, "x"), 0.1, 0),
              "std_msgs/msg/String": m.string('{"index": 0}')}
    good = {t: codec.encode(msg, t) for t, msg in bodies.items()}
    logged: list[str] = []
    node = SimpleNamespace(codec=codec, domain=0, dropped=MalformedInput("/n", logged.append))
    readers, received = {}, []
    for msgtype in good:
        readers[msgtype] = Node._reader(node, "/t", msgtype, received.append)
    keys = {t: wire.topic_key(0, "/t", t, codec.type_hash(t)) for t in good}

    @st.composite
    def sample(draw):
        msgtype = draw(st.sampled_from(sorted(good)))
        body = good[draw(st.sampled_from(sorted(good)))]
        cut = draw(st.integers(0, len(body)))
        payload = draw(st.sampled_from([body, body[:cut], bytes(body[:cut]) + body[cut + 1:],
                                        draw(st.binary(max_size=64))]))
        if payload and draw(st.booleans()):
            flip = draw(st.integers(0, len(payload) - 1))
            payload = payload[:flip] + bytes([payload[flip] ^ 0xFF]) + payload[flip + 1:]
        key = draw(st.sampled_from([keys[msgtype], *keys.values(),
                                    keys[msgtype][:-64] + "f" * 64]))
        attachment = draw(st.sampled_from([wire.attachment(1, 2, bytes(16)), None, b"\x00"]))
        return msgtype, key, payload, attachment

    @settings(max_examples=300, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow])
    @given(case=sample())
    def check(case):
        msgtype, key, payload, attachment = case
        before, seen = node.dropped.total, len(received)
        start = time.perf_counter()
        readers[msgtype](_Sample(key, payload, attachment))  # raises nothing
        assert time.perf_counter() - start < 0.5
        assert (node.dropped.total - before) + (len(received) - seen) == 1

    check()
    assert logged and all("Traceback" not in line for line in logged)
