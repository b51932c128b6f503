"""read_bag never reads silently wrong data: missing commands, uneven message counts and
robot gaps are errors naming the robots; valid bags beyond the default arena are read."""

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rosbags import rosbag1
from rosbags.typesys import Stores, get_typestore

from boids_env.config import EnvConfig
from boids_env.recording import Recording
from boids_env.rosbag import read_bag, write_bag

STORE = get_typestore(Stores.ROS1_NOETIC)
T = STORE.types
ODOM, TWIST = "nav_msgs/msg/Odometry", "geometry_msgs/msg/Twist"


def _twist(vx: float, vy: float):
    vec = T["geometry_msgs/msg/Vector3"]
    return T[TWIST](linear=vec(x=vx, y=vy, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0))


def _odom(step: int, x: float, y: float, vx: float, vy: float):
    stamp = T["builtin_interfaces/msg/Time"](sec=step // 10, nanosec=(step % 10) * 10**8)
    header = T["std_msgs/msg/Header"](seq=step, stamp=stamp, frame_id="map")
    pose = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    zero = np.zeros(36)
    return T[ODOM](header=header, child_frame_id="r",
                   pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=zero),
                   twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=_twist(vx, vy),
                                                                   covariance=zero))


def custom_bag(path, odom_counts: dict[int, int], cmd_counts: dict[int, int]):
    """A ROS 1 bag with the given numbers of odom and cmd_vel messages per robot."""
    with rosbag1.Writer(path) as writer:
        conns = {}
        for k in sorted(set(odom_counts) | set(cmd_counts)):
            if k in odom_counts:
                conns[k, "odom"] = writer.add_connection(f"/robot_{k}/odom", ODOM,
                                                         typestore=STORE)
            if k in cmd_counts:
                conns[k, "cmd"] = writer.add_connection(f"/robot_{k}/cmd_vel", TWIST,
                                                        typestore=STORE)
        for step in range(max([*odom_counts.values(), *cmd_counts.values()])):
            ns = step * 10**8
            for k in sorted(set(odom_counts) | set(cmd_counts)):
                if step < odom_counts.get(k, 0):
                    msg = _odom(step, 0.3 * k, -0.1 * step, 0.2, 0.1 * k)
                    writer.write(conns[k, "odom"], ns, STORE.serialize_ros1(msg, ODOM))
                if step < cmd_counts.get(k, 0):
                    writer.write(conns[k, "cmd"], ns,
                                 STORE.serialize_ros1(_twist(0.25, -0.05 * k), TWIST))
    return path


def test_a_bag_without_cmd_vel_is_an_error_unless_odometry_only(tmp_path):
    bag = custom_bag(tmp_path / "odom.bag", {0: 6, 1: 6, 2: 6}, {})
    with pytest.raises(ValueError, match=r"odom.bag has no /robot_k/cmd_vel topics.*"
                                         r"odometry_only=True"):
        read_bag(bag)
    rec = read_bag(bag, odometry_only=True)
    assert rec.positions.shape == (6, 3, 2)
    np.testing.assert_array_equal(rec.commanded, rec.velocities)
    assert rec.metrics()["V_align"] >= 0


def test_robots_with_different_message_counts_are_named(tmp_path):
    bag = custom_bag(tmp_path / "short.bag", {0: 50, 1: 50, 2: 3, 3: 50},
                     {0: 50, 1: 50, 2: 3, 3: 50})
    with pytest.raises(ValueError, match=r"different numbers of odom messages \(robot_0: 50, "
                                         r"robot_2: 3 \(the other 2: 50\)\)"):
        read_bag(bag)


def test_cmd_vel_counts_must_match_odom(tmp_path):
    bag = custom_bag(tmp_path / "cmd.bag", {0: 8, 1: 8, 2: 8}, {0: 8, 1: 5, 2: 8})
    with pytest.raises(ValueError, match=r"cmd_vel counts differ for robot_1: 5"):
        read_bag(bag)
    partial = custom_bag(tmp_path / "partial.bag", {0: 4, 1: 4, 2: 4}, {0: 4, 2: 4})
    with pytest.raises(ValueError, match=r"no cmd_vel for robot_1"):
        read_bag(partial)


def test_a_gap_in_robot_numbers_is_an_error(tmp_path):
    bag = custom_bag(tmp_path / "gap.bag", {0: 4, 1: 4, 3: 4}, {0: 4, 1: 4, 3: 4})
    with pytest.raises(ValueError, match=r"no odom for robot_2"):
        read_bag(bag)
    huge = custom_bag(tmp_path / "huge.bag", {0: 4, 1: 4, 2**40: 4}, {0: 4, 1: 4, 2**40: 4})
    with pytest.raises(ValueError, match=r"robot_0..robot_1099511627776 without gaps; no odom "
                                         r"for robot_2, .* and 1,099,511,627,764 more"):
        read_bag(huge)  # counted, never built: a set of 2**40 numbers ran out of memory
    lone = custom_bag(tmp_path / "lone.bag", {0: 4}, {0: 4})
    with pytest.raises(ValueError, match=r"one robot"):
        read_bag(lone)


def _recording(robots: int, steps: int, low: float, high: float) -> Recording:
    rng = np.random.default_rng(1)
    pos = rng.uniform(low, high, (steps, robots, 2))
    vel = rng.uniform(-0.5, 0.5, (steps, robots, 2))
    return Recording(EnvConfig(), np.arange(steps) * 0.1, pos, vel, vel * 0.5)


def test_many_robots_in_the_default_arena_are_read(tmp_path):
    rec = _recording(200, 4, -4.9, 4.9)
    write_bag(rec, tmp_path / "many.bag")
    back = read_bag(tmp_path / "many.bag")
    assert back.config.scenario.robots == 200
    assert back.config.world.arena_half_size == 5.0, "the arena of the data is kept"
    np.testing.assert_array_equal(back.positions, rec.positions)
    assert back.metrics()["steps"] == 3


def test_coordinates_beyond_the_default_arena_are_read(tmp_path):
    rec = _recording(5, 4, 998.0, 999.4)
    write_bag(rec, tmp_path / "far.bag")
    back = read_bag(tmp_path / "far.bag")
    assert back.config.world.arena_half_size > 999.4
    np.testing.assert_array_equal(back.positions, rec.positions)
    assert np.isfinite(back.metrics()["min_distance"])


def test_coordinates_no_arena_can_hold_are_a_clear_error(tmp_path):
    write_bag(_recording(5, 3, 4000.0, 5000.0), tmp_path / "huge.bag")
    with pytest.raises(ValueError, match=r"huge.bag: no env config holds 5 robots with "
                                         r"coordinates up to 4\d{3} m.*arena_half_size"):
        read_bag(tmp_path / "huge.bag")


def test_non_finite_data_are_named(tmp_path):
    rec = _recording(3, 4, -1.0, 1.0)
    rec.positions[2, 1, 0] = np.nan
    write_bag(rec, tmp_path / "nan.bag")
    with pytest.raises(ValueError, match=r"non-finite values in the odom messages of robot_1"):
        read_bag(tmp_path / "nan.bag")


def test_answers_moves_each_command_one_sample_later_and_allows_the_last_missing(tmp_path):
    # a live graph: robot 2's answer to the last odometry was never recorded
    bag = custom_bag(tmp_path / "live.bag", {0: 12, 1: 12, 2: 12}, {0: 12, 1: 12, 2: 11})
    rec = read_bag(bag, answers=True)
    assert rec.commanded.shape == (12, 3, 2)
    assert np.all(rec.commanded[0] == 0)  # the reset sample has no command yet
    assert np.all(rec.commanded[1:, 2] == [0.25, -0.1])  # robot 2's commands, one later
    with pytest.raises(ValueError, match=r"cmd_vel counts differ for robot_2: 11"):
        read_bag(bag)  # aligned (written by write_bag): one command per sample
    short = custom_bag(tmp_path / "short.bag", {0: 12, 1: 12}, {0: 12, 1: 10})
    with pytest.raises(ValueError, match=r"\(11 or 12\); cmd_vel counts differ for robot_1: 10"):
        read_bag(short, answers=True)


def test_a_bag_that_is_not_a_regular_file_within_budget_is_refused_unread(tmp_path, monkeypatch):
    """A bag is a file from elsewhere (issue 39's rules): a FIFO would block the reader,
    /dev/zero fill memory, a huge folder exhaust it."""
    import os

    from boids_env import rosbag

    fifo = tmp_path / "fifo.bag"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="not a regular file"):
        read_bag(fifo)
    (tmp_path / "zero.bag").symlink_to("/dev/zero")
    with pytest.raises(ValueError, match="not a regular file"):
        read_bag(tmp_path / "zero.bag")
    bag = custom_bag(tmp_path / "ok.bag", {0: 3, 1: 3}, {0: 3, 1: 3})
    monkeypatch.setattr(rosbag, "MAX_BAG_BYTES", 100)
    with pytest.raises(ValueError, match=r"more than the 100 allowed"):
        read_bag(bag)


def test_a_bag_with_too_many_messages_is_refused(tmp_path, monkeypatch):
    from boids_env import rosbag

    bag = custom_bag(tmp_path / "b.bag", {0: 5, 1: 5}, {0: 5, 1: 5})
    monkeypatch.setattr(rosbag, "MAX_BAG_MESSAGES", 12)
    with pytest.raises(ValueError, match=r"more than the 12 messages a bag may hold"):
        read_bag(bag)
    monkeypatch.setattr(rosbag, "MAX_BAG_MESSAGES", 20)
    assert read_bag(bag).positions.shape[0] == 5


def test_a_ros2_bag_folder_holds_plain_files_and_bounded_metadata(tmp_path):
    folder = tmp_path / "bag2"
    folder.mkdir()
    (folder / "metadata.yaml").write_text(
        'a: &a ["x","x","x","x","x","x","x","x","x"]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\n'
        'c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]\nd: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]\n'
        'e: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]\nf: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]\n')
    with pytest.raises(ValueError, match="bag metadata"):
        read_bag(folder)
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (folder / "sub").mkdir()
    with pytest.raises(ValueError, match="plain files only"):
        read_bag(folder)
