"""Bags that play in RViz / Foxglove: start stamps, /clock, /tf with headings, markers, the
leader's path, ROS 2 metadata that Humble reads, checked with the official readers."""

import importlib.util
import math
import subprocess
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from boids_env import parallel_env, style
from boids_env.eval.episode import run_episode
from boids_env.policies import ReynoldsPolicy
from boids_env.rosbag import METADATA_VERSION, read_bag, write_bag
from boids_env.rosmsgs import headings

START = 1_700_000_000.25
START_NS = 1_700_000_000_250_000_000


@pytest.fixture(scope="module")
def recording():
    return run_episode(parallel_env(robots=5, max_cycles=40), ReynoldsPolicy(), seed=0).recording


@pytest.fixture(scope="module")
def bags(recording, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bags")
    write_bag(recording, folder / "ep.bag", start=START)
    write_bag(recording, folder / "ep_mcap", format="mcap", start=START)
    return folder


def _messages(path):
    """{topic: [(stamp ns, message)]} through rosbags' reader."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out = {}
    store = get_typestore(Stores.ROS1_NOETIC if path.is_file() else Stores.ROS2_HUMBLE)
    with AnyReader([path], default_typestore=store) as reader:
        for conn, stamp, raw in reader.messages():
            out.setdefault(conn.topic, []).append((stamp, reader.deserialize(raw, conn.msgtype)))
    return out


def test_headings_follow_the_command_then_the_velocity_and_are_kept_when_still():
    cmd = np.array([[[0, 0]], [[0, 0.3]], [[0, 0]], [[0, 0]], [[-0.2, 0]]], dtype=float)
    vel = np.array([[[0, 0]], [[0, 0]], [[0.4, 0.4]], [[0, 1e-5]], [[0, 0]]], dtype=float)
    got = headings(cmd, vel)[:, 0]
    want = [0.0, math.pi / 2, math.pi / 4, math.pi / 4, math.pi]
    np.testing.assert_allclose(got, want, err_msg="0 at first; the command's direction; the "
                               "velocity's without a command; kept while still")


@pytest.mark.parametrize("name", ["ep.bag", "ep_mcap"])
def test_every_topic_at_10_hz_from_the_given_start(bags, recording, name):
    msgs = _messages(bags / name)
    steps, n = recording.positions.shape[:2]
    once = {"/map", "/markers/obstacles", "/tf_static"}
    topics = {"/clock", "/tf", "/markers/robots", "/markers/forces", "/leader/path", *once,
              *(f"/robot_{k}/{kind}" for k in range(n) for kind in ("odom", "cmd_vel"))}
    assert set(msgs) == topics, set(msgs) ^ topics
    for topic in once:
        assert [s for s, _ in msgs[topic]] == [START_NS], f"{topic}: latched, once, at start"
    for topic in topics - {"/leader/path"} - once:
        stamps = np.array([s for s, _ in msgs[topic]])
        assert len(stamps) == steps, topic
        assert stamps[0] == START_NS, f"{topic} starts at --bag-start, not 1970"
        np.testing.assert_allclose(np.diff(stamps), 1e8, atol=2, err_msg=topic)
    clock = [m.clock for _, m in msgs["/clock"]]
    assert (clock[3].sec, clock[3].nanosec) == (1_700_000_000, 550_000_000), "to the ns"
    assert len(msgs["/leader/path"]) == 5, "the path once a second (41 samples; latched)"


@pytest.mark.parametrize("name", ["ep.bag", "ep_mcap"])
def test_tf_odometry_and_markers_show_the_flock(bags, recording, name):
    msgs = _messages(bags / name)
    step = 30
    yaw = headings(recording.commanded, recording.velocities)[step]
    # REP 105: map -> robot_k/odom (static, identity) -> robot_k/base_footprint (the pose)
    (_, static), = msgs["/tf_static"]
    assert [(t.header.frame_id, t.child_frame_id) for t in static.transforms] == [
        ("map", f"robot_{k}/odom") for k in range(5)]
    assert all((t.transform.translation.x, t.transform.translation.y, t.transform.rotation.w)
               == (0.0, 0.0, 1.0) for t in static.transforms)
    tf = msgs["/tf"][step][1].transforms
    assert [(t.header.frame_id, t.child_frame_id) for t in tf] == [
        (f"robot_{k}/odom", f"robot_{k}/base_footprint") for k in range(5)]
    for k, t in enumerate(tf):
        pos = recording.positions[step, k]
        assert (t.transform.translation.x, t.transform.translation.y) == tuple(pos), k
        q = t.transform.rotation
        assert math.isclose(2 * math.atan2(q.z, q.w), yaw[k], abs_tol=1e-9), k
    odom = msgs["/robot_2/odom"][step][1]
    assert (odom.header.frame_id, odom.child_frame_id) == ("robot_2/odom",
                                                           "robot_2/base_footprint")
    q = odom.pose.pose.orientation
    assert math.isclose(2 * math.atan2(q.z, q.w), yaw[2], abs_tol=1e-9), "heading, not identity"
    cmd = recording.commanded[step, 2]
    assert math.isclose(yaw[2], math.atan2(cmd[1], cmd[0])), "the commanded direction"
    spheres = msgs["/markers/robots"][step][1].markers
    assert [m.type for m in spheres] == [2] * 5 and spheres[0].scale.x == pytest.approx(0.072)
    colour = spheres[0].color
    assert (colour.r, colour.g, colour.b) == pytest.approx(style.rgb01(style.LEADER)[:3])
    arrows = {(m.ns, m.id): m for m in msgs["/markers/forces"][step][1].markers}
    assert {ns for ns, _ in arrows} == set(style.RULE_COLOURS) - {"obstacle"}, "arena: no avoidance"
    sep = arrows[("separation", 3)]
    vec = style.arrow_vectors(recording.forces["separation"][step])[2]
    start, end = sep.points
    assert (start.x, start.y) == tuple(recording.positions[step, 3])
    assert (end.x - start.x, end.y - start.y) == pytest.approx(tuple(vec))
    path = msgs["/leader/path"][0][1]
    np.testing.assert_array_equal([(p.pose.position.x, p.pose.position.y) for p in path.poses],
                                  recording.leader_path)


def test_ros2_metadata_is_humbles_version_5(bags):
    from ruamel.yaml import YAML

    folder = bags / "ep_mcap"
    assert sorted(p.name for p in folder.iterdir()) == ["ep_mcap.mcap", "metadata.yaml"]
    info = YAML(typ="safe").load((folder / "metadata.yaml").read_text())[
        "rosbag2_bagfile_information"]
    assert info["version"] == METADATA_VERSION == 5
    assert info["relative_file_paths"] == ["ep_mcap.mcap"]
    assert info["starting_time"]["nanoseconds_since_epoch"] == START_NS
    assert "custom_data" not in info and "ros_distro" not in info
    for topic in info["topics_with_message_count"]:
        meta = topic["topic_metadata"]
        # Humble reads offered_qos_profiles as a YAML string (version 9 made it a list)
        assert isinstance(meta["offered_qos_profiles"], str), meta
        qos = YAML(typ="safe").load(meta["offered_qos_profiles"])
        latched = meta["name"] in ("/leader/path", "/map", "/markers/obstacles", "/tf_static")
        assert qos[0]["durability"] == (1 if latched else 2), meta
        assert "type_description_hash" not in meta


def test_the_default_start_is_the_wall_clock(recording, tmp_path):
    before = time.time()
    write_bag(recording, tmp_path / "now.bag")
    first = _messages(tmp_path / "now.bag")["/clock"][0][0] / 1e9
    assert before - 1 <= first <= time.time() + 1


def test_bad_start_is_a_clear_error(recording, tmp_path):
    for bad in (-1.0, float("nan"), 2.0**33):
        with pytest.raises(ValueError, match="start must be a Unix time"):
            write_bag(recording, tmp_path / "x.bag", start=bad)
    assert not list(tmp_path.iterdir()), "nothing written"


@pytest.mark.skipif(importlib.util.find_spec("mcap_ros2") is None,
                    reason="mcap-ros2-support (test extra) not installed")
def test_the_official_mcap_reader_decodes_every_message(bags, recording):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    counts = {}
    with open(bags / "ep_mcap" / "ep_mcap.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        assert {s.encoding for s in reader.get_summary().schemas.values()} == {"ros2msg"}
        for _, channel, message, decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/robot_1/odom" and counts[channel.topic] == 11:
                assert decoded.pose.pose.position.x == recording.positions[10, 1, 0]
                assert message.log_time == START_NS + 10**9
    assert counts["/tf"] == counts["/markers/forces"] == len(recording.time)


def _has_ros1_reader() -> bool:
    """Debian's python3-rosbag lives in the system Python, not in a virtualenv."""
    return Path("/usr/bin/python3").is_file() and subprocess.run(
        ["/usr/bin/python3", "-c", "import rosbag"], capture_output=True, check=False
    ).returncode == 0


ROS1 = _has_ros1_reader()


@pytest.mark.skipif(not ROS1, reason="Debian's python3-rosbag (the ROS 1 reader) not installed")
def test_the_ros1_reader_reads_every_topic_with_the_official_md5sums(bags):
    script = textwrap.dedent(f"""
        import rosbag
        bag = rosbag.Bag({str(bags / "ep.bag")!r})
        for c in sorted({{(c.topic, c.datatype, c.md5sum) for c in bag._connections.values()}}):
            print(*c)
        for topic, msg, t in bag.read_messages():
            pass
        print("start", bag.get_start_time())
    """)
    out = subprocess.run(["/usr/bin/python3", "-c", script], capture_output=True, text=True,
                         check=True, timeout=120).stdout
    official = {"/tf": "94810edda583a504dfda3829e70d7eec",
                "/clock": "a9c97c1d230cfc112e270351a944ee47",
                "/markers/robots": "d155b9ce5188fbaf89745847fd5882d7",
                "/leader/path": "6227e2b7e9cce15051f669a5e197bbf7",
                "/map": "3381f2d731d4076ec5c71b0759edbe4e",
                "/markers/obstacles": "d155b9ce5188fbaf89745847fd5882d7",
                "/robot_0/odom": "cd5e73d190d741a2f92e81eda573aca7"}
    rows = {line.split()[0]: line.split()[2] for line in out.splitlines()
            if line.startswith("/")}
    for topic, md5 in official.items():
        assert rows[topic] == md5, (topic, out)
    assert f"start {START}" in out, out


def test_a_bag_read_back_gives_every_metric_exactly(bags, recording):
    want = recording.metrics()
    for name in ("ep.bag", "ep_mcap"):
        got = read_bag(bags / name).metrics()
        assert got == want, (name, {k: (got[k], want[k]) for k in want if got[k] != want[k]})


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_a_lidar_gives_laser_scans_and_twist_stamped_reads_back_alike(fmt, tmp_path):
    """With a lidar every follower's /robot_k/scan is in the bag (its own base_footprint
    frame, a full turn of rays, nothing hit = +inf); with twist_stamped, cmd_vel is
    TwistStamped and read_bag gives the same commands as from the Twist bag."""
    rec = run_episode(parallel_env(robots=4, max_cycles=30, lidar_rays=8), ReynoldsPolicy(),
                      seed=0).recording
    name = "ep.bag" if fmt == "ros1" else "ep_mcap"
    (tmp_path / "plain").mkdir()
    (tmp_path / "stamped").mkdir()
    write_bag(rec, tmp_path / "plain" / name, format=fmt, start=START)
    write_bag(rec, tmp_path / "stamped" / name, format=fmt, start=START, twist_stamped=True)
    msgs = _messages(tmp_path / "stamped" / name)
    scans = msgs["/robot_3/scan"]
    assert len(scans) == 31 and "/robot_0/scan" not in msgs
    first = scans[0][1]
    assert first.header.frame_id == "robot_3/base_footprint"
    assert len(first.ranges) == 8 and first.angle_increment == pytest.approx(math.pi / 4)
    assert first.range_max == 3.0
    ranges = np.array([m.ranges for _, m in scans])
    x = rec.positions[:, 3, 0]
    hit = np.isfinite(ranges[:, 0])  # ray 0 along +x (a Sphero's frame is the world's)
    assert hit.any() or (x < 2.0).all()
    assert (ranges[hit, 0] <= 5.0 - x[hit] + 1e-6).all(), "farther than the east wall"
    assert (ranges[np.isfinite(ranges)] <= 3.0).all()
    cmd = msgs["/robot_2/cmd_vel"][5][1]
    assert cmd.header.frame_id == "robot_2/base_footprint"
    assert (cmd.twist.linear.x, cmd.twist.linear.y) == tuple(rec.commanded[5, 2])
    np.testing.assert_array_equal(read_bag(tmp_path / "stamped" / name).commanded,
                                  read_bag(tmp_path / "plain" / name).commanded)
