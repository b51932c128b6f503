"""The study's graph as two ROS 2 processes over Zenoh on loopback (``boids ros2 sim`` and
``boids ros2 controller``), against ``boids run`` in-process, with what they put on the wire
checked sample by sample against rosbags (type hashes, CDR) and an independent CDR decoder
(mcap-ros2-support's, built from the message definitions)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from graph_support import assert_same_recording, wait_until

from boids_env.eval.run import run
from boids_env.recording import Recording

pytestmark = pytest.mark.slow


def _run_lockstep(ros2, *args: str, controller_args: tuple[str, ...] = (), spy: bool = False):
    out = ros2.folder / "sim_out"
    sim = ros2.boids("sim", "sim", "--lockstep", "--out", str(out), *args)
    sim.wait_for_line("waiting for", 60)
    session = wire = None
    if spy:
        session, wire = ros2.spy()
        # the spy's subscription reaches the sim before tick 0: wait for the sim's tokens
        assert wait_until(lambda: any("/MP/" in t for t in wire.tokens), 30)
    controller = ros2.boids("controller", "controller", *controller_args)
    assert sim.wait(240) == 0, sim.output()[-3000:] + controller.output()[-3000:]
    controller.stop()
    if session is not None:
        session.close()
    return out, sim, controller, wire


def test_two_ros2_processes_reproduce_boids_run_exactly_on_the_default_case(ros2):
    out, sim, _controller, wire = _run_lockstep(ros2, spy=True)
    reference = run("reynolds", out=None, seed=0, env_fields={}, quiet=True)
    ours = Recording.from_parquet(out / "trajectory.parquet")
    assert_same_recording(ours, reference.recording, "ROS 2 lockstep graph vs boids run")
    metrics = json.loads((out / "metrics.json").read_text())
    assert json.dumps(metrics, sort_keys=True) == json.dumps(reference.metrics, sort_keys=True)
    assert metrics["steps"] == 746
    config = json.loads((out / "config.json").read_text())
    assert config["ros"]["controllers"] == ["/reynolds_controller"], config["ros"]
    assert config["ros"]["extra_commands"] == 0, config["ros"]
    assert config["ros"]["ros2"] == {"transport": "zenoh", "domain": 0,
                                     "distribution": "jazzy",
                                     "cmd_vel": "geometry_msgs/msg/Twist"}
    assert f"{reference.metrics['V_sep']:.4f}" in sim.output()
    _check_wire(wire, "jazzy", ours)


def _check_samples(wire, distribution: str) -> dict[str, list[bytes]]:
    """Every sample on the wire: key expression and type hash by rmw_zenoh's rule with
    rosbags' hash of ``distribution``, payload CDR that rosbags reads back to the same bytes,
    rmw_zenoh's attachment with each publisher's sequence numbers consecutive; every token
    parses by rmw_zenoh's grammar. Returns the payloads by topic."""
    from rosbags.typesys import Stores, get_typestore

    from boids_env.eval.ros2.wire import parse_attachment, parse_token, ros_type

    store = get_typestore(getattr(Stores, f"ROS2_{distribution.upper()}"))
    sequences: dict[tuple[str, bytes], list[int]] = {}
    by_topic: dict[str, list[bytes]] = {}
    for key, payload, attachment in wire.samples:
        if key.startswith("@"):
            continue  # zenoh's own admin space and advanced-publisher queries
        domain, *topic, dds, type_hash = key.split("/")
        msgtype = ros_type(dds)
        assert domain == "0", key
        assert type_hash == store.hash_rihs01(msgtype), (key, store.hash_rihs01(msgtype))
        assert payload[:4] == b"\x00\x01\x00\x00", key  # CDR, little endian
        msg = store.deserialize_cdr(payload, msgtype)
        assert bytes(store.serialize_cdr(msg, msgtype)) == payload, key
        assert attachment is not None, key
        sequence, _stamp, gid = parse_attachment(attachment)
        sequences.setdefault((key, gid), []).append(sequence)
        by_topic.setdefault("/" + "/".join(topic), []).append(payload)
    for (key, _), seen in sequences.items():
        # each publisher counts its samples; odometry and commands start after the spy did
        first = 1 if "/odom/" in key or "/cmd_vel/" in key else seen[0]
        assert seen == list(range(first, first + len(seen))), (key, seen[:5])
    for token in wire.tokens:
        parse_token(token)
    return by_topic


def _check_wire(wire, distribution: str, recording: Recording) -> None:
    """:func:`_check_samples`, every topic of the graph present, the odometry decoded by an
    independent CDR reader (mcap-ros2-support's) equal to the recording, the nodes'
    tokens."""
    from mcap_ros2._dynamic import generate_dynamic
    from rosbags.typesys import Stores, get_typestore

    from boids_env.eval.ros2.wire import parse_token

    store = get_typestore(getattr(Stores, f"ROS2_{distribution.upper()}"))
    by_topic = _check_samples(wire, distribution)
    expected = {"/clock", "/tf", "/tf_static", "/map", "/markers/robots",
                "/markers/obstacles", "/boids/env_config", "/boids/episode",
                "/robot_0/odom", "/robot_1/cmd_vel", "/reynolds_controller/markers"}
    assert expected <= set(by_topic), sorted(expected - set(by_topic))
    # an independent CDR reader: mcap-ros2-support's, from the message definitions
    decode = generate_dynamic("nav_msgs/msg/Odometry",
                              store.generate_msgdef("nav_msgs/msg/Odometry", ros_version=2)[0])[
        "nav_msgs/msg/Odometry"]
    odom = [decode(p) for p in by_topic["/robot_3/odom"]]
    assert len(odom) == len(recording.time)
    xy = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in odom])
    assert np.array_equal(xy, recording.positions[:, 3]), "odometry on the wire != recording"
    assert odom[0].header.frame_id == "robot_3/odom"
    assert odom[0].child_frame_id == "robot_3/base_footprint"
    tokens = [parse_token(t) for t in wire.tokens]
    nodes = {t.fqn for t in tokens if t.kind == "NN"}
    assert {"/boids_sim", "/reynolds_controller"} <= nodes, nodes
    subs = {(t.fqn, t.topic) for t in tokens if t.kind == "MS"}
    assert ("/reynolds_controller", "/robot_12/odom") in subs
    assert ("/boids_sim", "/robot_12/cmd_vel") in subs


def test_a_turtlebot3_on_a_map_with_twist_stamped_equals_boids_run_exactly(ros2):
    """A TurtleBot3 with a lidar on the lab map, cmd_vel as Jazzy's TurtleBot3 takes it
    (TwistStamped, body frame), Kilted's type hashes: the lockstep run equals boids run bit
    for bit, and every follower's LaserScan is on the wire."""
    fields = ["--robot", "turtlebot3_burger", "--scene", "lab", "--robots", "5",
              "--max-cycles", "120", "--set", "lidar_rays=16"]
    net = ("--twist-stamped", "--distribution", "kilted")
    out, _sim, _controller, wire = _run_lockstep(ros2, *fields, *net, controller_args=net,
                                               spy=True)
    reference = run("reynolds", out=None, seed=0, quiet=True, env_fields=dict(
        robot="turtlebot3_burger", scene="lab", robots=5, max_cycles=120, lidar_rays=16))
    ours = Recording.from_parquet(out / "trajectory.parquet")
    assert_same_recording(ours, reference.recording, "turtlebot graph vs boids run")
    for name in ("headings", "angular_velocities", "native"):
        assert np.array_equal(getattr(ours, name), getattr(reference.recording, name)), name
    metrics = json.loads((out / "metrics.json").read_text())
    assert json.dumps(metrics, sort_keys=True) == json.dumps(reference.metrics, sort_keys=True)
    keys = {k for k, _, _ in wire.samples}
    assert any(k.startswith("0/robot_1/cmd_vel/geometry_msgs::msg::dds_::TwistStamped_/")
               for k in keys), sorted(keys)[:20]
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_KILTED)
    cmds = [store.deserialize_cdr(p, "geometry_msgs/msg/TwistStamped")
            for k, p, _ in wire.samples if k.startswith("0/robot_2/cmd_vel/")]
    assert len(cmds) == 121  # one answer per tick, the last tick's included
    # body frame: (v, 0, ω) stamped with the tick it answers, in the robot's frame
    assert all(c.twist.linear.y == 0.0 for c in cmds)
    assert cmds[0].header.frame_id == "robot_2/base_footprint"
    v = np.array([[c.twist.linear.x, c.twist.angular.z] for c in cmds[:-1]])
    # the answer to tick k is what robot 2 executes from sample k to k + 1
    assert np.array_equal(v, ours.native[1:, 2]), "cmd_vel on the wire != executed command"
    scans = [store.deserialize_cdr(p, "sensor_msgs/msg/LaserScan")
             for k, p, _ in wire.samples if k.startswith("0/robot_4/scan/")]
    assert len(scans) == 121
    scan = scans[0]
    assert scan.header.frame_id == "robot_4/base_footprint"
    assert len(scan.ranges) == 16 and scan.range_max == 3.0
    assert scan.angle_increment == pytest.approx(2 * np.pi / 16)
    finite = np.isfinite(np.concatenate([s.ranges for s in scans]))
    assert finite.any() and (np.concatenate([s.ranges for s in scans])[finite] <= 3.0).all()
    _check_samples(wire, "kilted")


def test_a_lyrical_graph_speaks_lyricals_hashes_and_equals_boids_run(ros2):
    net = ("--distribution", "lyrical")
    out, _sim, _controller, wire = _run_lockstep(
        ros2, "--robots", "4", "--max-cycles", "30", *net, controller_args=net, spy=True)
    reference = run("reynolds", out=None, seed=0, quiet=True,
                    env_fields=dict(robots=4, max_cycles=30))
    assert_same_recording(Recording.from_parquet(out / "trajectory.parquet"),
                           reference.recording, "lyrical graph vs boids run")
    by_topic = _check_samples(wire, "lyrical")
    assert len(by_topic["/robot_3/cmd_vel"]) == 31


def test_several_episodes_reset_the_controller_through_the_episode_topic(ros2):
    """Each episode is announced on the latched /boids/episode; the controller resets its
    policy with the episode's seed, so every episode equals boids run with its seed."""
    out, _sim, controller, _ = _run_lockstep(ros2, "--robots", "5", "--max-cycles", "25",
                                             "--episodes", "2", "--seed", "3")
    for index, seed in enumerate((3, 4)):
        reference = run("reynolds", out=None, seed=seed, quiet=True,
                        env_fields=dict(robots=5, max_cycles=25))
        ours = Recording.from_parquet(out / f"episode_{index:03d}" / "trajectory.parquet")
        assert_same_recording(ours, reference.recording, f"episode {index} (seed {seed})")
    assert "new episode (episode 1, seed 4)" in controller.output(), controller.output()


def test_a_walking_person_and_a_crowd_on_the_graph_equal_boids_run(ros2):
    """A person walked by JuPedSim leads through a doorway with a crowd of 3: the sim
    publishes every pedestrian's /pedestrian_k/odom with each tick, the controller's ticks
    wait for them and observe them, and the lockstep run equals boids run bit for bit."""
    fields = dict(scene="doorway", leader="person", crowd=3, robots=4, max_cycles=150)
    args = ("--scene", "doorway", "--leader", "person", "--crowd", "3", "--robots", "4",
            "--max-cycles", "150")
    out, _sim, _controller, wire = _run_lockstep(ros2, *args, spy=True)
    reference = run("reynolds", out=None, seed=0, quiet=True, env_fields=fields)
    ours = Recording.from_parquet(out / "trajectory.parquet")
    assert_same_recording(ours, reference.recording, "person and crowd graph vs boids run")
    assert np.array_equal(ours.pedestrians, reference.recording.pedestrians)
    metrics = json.loads((out / "metrics.json").read_text())
    assert json.dumps(metrics, sort_keys=True) == json.dumps(reference.metrics, sort_keys=True)
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    walks = [store.deserialize_cdr(p, "nav_msgs/msg/Odometry")
             for k, p, _ in wire.samples if k.startswith("0/pedestrian_2/odom/")]
    assert len(walks) == 151  # one per tick
    assert walks[0].header.frame_id == "map" and walks[0].child_frame_id == "pedestrian_2"
    got = np.array([[w.pose.pose.position.x, w.pose.pose.position.y] for w in walks])
    assert np.array_equal(got, ours.pedestrians[:, 2])
    speeds = np.array([[w.twist.twist.linear.x, w.twist.twist.linear.y] for w in walks])
    assert np.abs(speeds).max() > 0.1  # the crowd walks, and its velocity is on the wire
    keys = {k for k, _, _ in wire.samples}
    assert not any(k.startswith("0/robot_0/cmd_vel/") for k in keys)  # a person takes none
    assert any(k.startswith("0/markers/people/") for k in keys)
    assert any(k.startswith("0/person/odom/") for k in keys)
    _check_samples(wire, "jazzy")
