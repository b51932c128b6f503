"""Issue 55 on ROS 1: malformed input never gives a traceback per message. rospy decodes the
wire itself: a message it cannot read is dropped by rospy (its traceback goes to the node's
ROS log file, never to the terminal) and the connection to that publisher is made again; a
publisher of another type is refused at the handshake. Our callbacks run under the same
guard as the ROS 2 nodes' (:class:`~boids_env.eval.graph.malformed.MalformedInput`): what
one raises on a message is counted by topic and reason and logged once."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from boids_env.eval.graph import malformed
from boids_env.eval.graph.malformed import MalformedInput, since
from boids_env.eval.ros.controller import ControllerNode
from boids_env.eval.ros.sim import SimNode


def test_malformed_input_counts_every_sample_and_logs_each_topic_and_reason_once():
    lines: list[str] = []
    dropped = MalformedInput("/node", lines.append)
    for _ in range(4):
        dropped.drop("/a", "pkg/msg/T", malformed.EMPTY, "0 bytes")
        dropped.drop("/a", "pkg/msg/T", malformed.UNDECODABLE, "cut short")
        dropped.drop("/b", "pkg/msg/U", malformed.EMPTY)
    assert dropped.counts == {"/a": {"empty payload": 4, "undecodable": 4},
                              "/b": {"empty payload": 4}}
    assert dropped.total == 12
    assert len(lines) == 3
    assert lines[0].startswith("/node: dropped a malformed sample on /a (expected pkg/msg/T): "
                               "empty payload: 0 bytes")
    before = dropped.counts
    dropped.drop("/b", "pkg/msg/U", malformed.EMPTY)
    assert since(dropped.counts, before) == {"/b": {"empty payload": 1}}
    assert since(before, before) == {}
    head = "/node: malformed samples dropped (by topic and reason): "
    summary = dropped.summary()
    assert summary.startswith(head) and json.loads(summary[len(head):]) == dropped.counts
    assert MalformedInput("/quiet").summary() is None


def test_the_guard_counts_what_a_callback_raises_and_logs_a_bug_once_with_its_traceback():
    lines: list[str] = []
    dropped = MalformedInput("/node", lines.append)

    def refuse(msg):
        raise ValueError(f"not an episode: {msg!r}")

    def bug(msg):
        raise ZeroDivisionError("a bug")

    for k in range(5):
        dropped.guard("/boids/episode", "std_msgs/msg/String", refuse, k)
        dropped.guard("/x", "std_msgs/msg/String", bug, k)
    got = []
    dropped.guard("/x", "std_msgs/msg/String", got.append, "fine")
    assert got == ["fine"]
    assert dropped.counts == {"/boids/episode": {"rejected": 5}, "/x": {"callback error": 5}}
    assert len(lines) == 2
    assert "rejected: not an episode: 0" in lines[0] and "Traceback" not in lines[0]
    assert "ZeroDivisionError: a bug" in lines[1] and "Traceback" in lines[1]


class _Rospy:
    def __init__(self):
        self.warnings = []

    def logwarn_throttle(self, period, text):
        self.warnings.append(text)


def _twist(x):
    return SimpleNamespace(linear=SimpleNamespace(x=x, y=0.0, z=0.0),
                           angular=SimpleNamespace(x=0.0, y=0.0, z=0.0))


def test_the_ros1_nodes_callbacks_raise_nothing_into_rospy():
    """rospy logs a traceback for every message whose callback raises: ours run guarded."""
    lines: list[str] = []

    def broken(*args):
        raise RuntimeError("the board is gone")

    sim = SimpleNamespace(name="/boids_sim", rospy=_Rospy(), agents=["follower_1"],
                          core=SimpleNamespace(post_command=broken),
                          dropped=MalformedInput("/boids_sim", lines.append))
    callback = SimNode._guarded(sim, "/robot_1/cmd_vel",
                                lambda msg: SimNode._on_command(sim, msg, 0))
    for _ in range(30):
        callback(_twist(0.1))
    assert sim.dropped.counts == {"/robot_1/cmd_vel": {"callback error": 30}}
    assert len(lines) == 1 and "geometry_msgs/Twist" in lines[0]
    controller = SimpleNamespace(_source="/x", core=SimpleNamespace(odometry=broken),
                                 dropped=MalformedInput("/c", lines.append))
    controller._on_odom = lambda msg, source: ControllerNode._on_odom(controller, msg, source)
    odom = ControllerNode._guarded(controller, "/robot_2/odom", 2)
    for _ in range(30):
        odom(SimpleNamespace())  # not even an Odometry: an AttributeError, counted
    assert controller.dropped.counts == {"/robot_2/odom": {"callback error": 30}}
    assert len(lines) == 2 and "nav_msgs/Odometry" in lines[1]


@pytest.mark.slow
def test_a_cut_short_or_mistyped_command_gives_no_traceback_and_the_sim_goes_on(ros):
    out = ros.folder / "sim_out"
    sim = ros.boids("sim", "ros", "sim", "--robots", "3", "--max-cycles", "100", "--no-wait",
                    "--out", str(out))
    bad = ros.node("bad", "bad_commands.py", "--count", "20")
    assert bad.wait(90) == 0, bad.output()
    assert "done" in bad.output()
    assert sim.wait(120) == 0, sim.output()
    assert "Traceback" not in sim.output(), sim.output()[-3000:]
    # rospy dropped them before any callback of ours: nothing for the guard to count
    config = json.loads((out / "config.json").read_text())
    assert config["ros"]["malformed"] == {}, config["ros"]
    # rospy's own record of the message it could not read: the node's ROS log file
    logs = "".join(p.read_text(errors="replace")
                   for p in (ros.folder / "ros_home" / "log").rglob("boids_sim*.log"))
    assert "DeserializationError" in logs
