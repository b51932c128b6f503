"""Issue 55: malformed input on the ROS 2 wire never gives a traceback. A truncated CDR, an
empty payload, another message's body on a topic, a sample of another type or type hash on
the topic's key, a sample without rmw_zenoh's attachment: each is dropped, counted by topic
and reason (:attr:`Node.malformed <boids_env.eval.ros2.node.Node.malformed>`), logged once
per topic and reason, and the node goes on answering correct samples.

The nodes run as ``boids ros2`` processes; the bad samples are put raw on the wire by an
in-process Zenoh session, as any peer could."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest
from graph_support import wait_until

pytestmark = pytest.mark.slow

ODOM = "nav_msgs/msg/Odometry"
TWIST = "geometry_msgs/msg/Twist"
OTHER_HASH = "RIHS01_" + "ab" * 32
REPEAT = 5
"""Each bad sample is sent this often: counted every time, logged once."""


class _Peer:
    """An in-process Zenoh session that puts raw samples on the test's network and records
    the graph's tokens and the samples of ``watch``."""

    def __init__(self, zenoh, conf, watch: str) -> None:
        from boids_env.eval.ros2.node import Codec
        from boids_env.rosmsgs import Messages

        self.session = zenoh.open(conf)
        self.codec = Codec("jazzy")
        self.msgs = Messages(self.codec.store, False, 0.036)
        self.tokens: set[str] = set()
        self.seen: list[str] = []
        self.lock = threading.Lock()
        self.subs = [
            self.session.liveliness().declare_subscriber(
                "@ros2_lv/**", lambda s: self._add(self.tokens, str(s.key_expr)), history=True),
            self.session.declare_subscriber(watch, lambda s: self._add(self.seen,
                                                                        str(s.key_expr)))]
        self.sequence = 0

    def _add(self, where, value) -> None:
        with self.lock:
            where.add(value) if isinstance(where, set) else where.append(value)

    def key(self, topic: str, msgtype: str, type_hash: str | None = None) -> str:
        from boids_env.eval.ros2.wire import topic_key

        return topic_key(0, topic, msgtype, type_hash or self.codec.type_hash(msgtype))

    def put(self, key: str, payload: bytes, attached: bool = True) -> None:
        from boids_env.eval.ros2.wire import attachment

        self.sequence += 1
        extra = {"attachment": attachment(self.sequence, time.time_ns(), bytes(16))} \
            if attached else {}
        self.session.put(key, payload, **extra)

    def subscribed(self, node: str, topic: str) -> bool:
        mangled = topic.replace("/", "%")
        with self.lock:
            return any(f"/MS/%/%/{node}/{mangled}/" in t for t in self.tokens)

    def odometry(self, robot: int, stamp: int) -> bytes:
        m = self.msgs
        msg = m.odometry(m.header(stamp, 0, f"robot_{robot}/odom"), robot,
                         np.array([0.5 * robot, 0.0]), np.zeros(2), 0.0,
                         child=f"robot_{robot}/base_footprint")
        return self.codec.encode(msg, ODOM)

    def send_bad(self, topic: str, msgtype: str, good: bytes, other: bytes) -> dict[str, int]:
        """Every kind of bad sample on ``topic``, :data:`REPEAT` times each; returns what
        the node must count, by reason."""
        key = self.key(topic, msgtype)
        for _ in range(REPEAT):
            self.put(key, good[: len(good) // 2])  # truncated CDR
            self.put(key, good[:7])  # truncated within the header's first field
            self.put(key, b"")  # empty payload
            self.put(key, other)  # another message's body
            self.put(self.key(topic, msgtype, OTHER_HASH), good)  # another type hash
            self.put(self.key(topic, TWIST if msgtype != TWIST else ODOM), other)
            self.put(key, good, attached=False)  # no rmw_zenoh attachment
        return {"undecodable": 3 * REPEAT, "empty payload": REPEAT,
                "wrong type hash": REPEAT, "wrong type": REPEAT, "no attachment": REPEAT}

    def close(self) -> None:
        for sub in self.subs:
            sub.undeclare()
        self.session.close()


def _counts(output: str, node: str) -> dict:
    """The counts the node printed at shutdown."""
    head = f"{node}: malformed samples dropped (by topic and reason): "
    lines = [line for line in output.splitlines() if line.startswith(head)]
    assert lines, output[-3000:]
    return json.loads(lines[-1][len(head):])


def _no_tracebacks(output: str) -> None:
    assert "Traceback" not in output, output[-4000:]


def test_the_controller_counts_bad_odometry_and_still_answers_a_good_tick(ros2):
    import zenoh  # the ros2 fixture skips without it

    from boids_env.eval.ros2.node import Endpoints

    # the peer listens on the test's port, the controller connects to it
    peer = _Peer(zenoh, Endpoints(connect=(), listen=(ros2.endpoint,)).config(),
                 "0/*/cmd_vel/**")
    try:
        controller = ros2.boids("controller", "controller", "--robots", "3", "--max-ticks",
                                "1")
        assert wait_until(lambda: all(peer.subscribed("reynolds_controller", f"/robot_{k}/odom")
                                      for k in range(3)), 60), controller.output()
        stamp = 2_000_000_000
        good, other = peer.odometry(1, stamp), peer.codec.encode(peer.msgs.twist(0.1, 0.2),
                                                                 TWIST)
        expected = peer.send_bad("/robot_1/odom", ODOM, good, other)
        time.sleep(0.5)
        for k in range(3):  # a whole good tick: the controller answers it
            peer.put(peer.key(f"/robot_{k}/odom", ODOM), peer.odometry(k, stamp))
        assert controller.wait(60) == 0, controller.output()[-3000:]
        assert wait_until(lambda: len(peer.seen) >= 2, 10), peer.seen
        assert {k.split("/")[1] for k in peer.seen} == {"robot_1", "robot_2"}
    finally:
        peer.close()
    output = controller.output()
    _no_tracebacks(output)
    assert _counts(output, "/reynolds_controller") == {"/robot_1/odom": expected}
    # each topic and reason logged once, naming the topic, the type and what was wrong
    notes = [line for line in output.splitlines() if "/robot_1/odom" in line
             and "malformed" in line and "dropped" in line and "by topic" not in line]
    assert len(notes) == len(expected), notes
    assert all(ODOM in line for line in notes), notes
    assert any("wrong type hash" in line and OTHER_HASH in line and "--distribution" in line
               for line in notes), notes


def test_the_simulator_counts_bad_commands_in_its_stats_and_goes_on(ros2):
    import zenoh

    out = ros2.folder / "sim_out"
    sim = ros2.boids("sim", "sim", "--robots", "3", "--max-cycles", "60", "--no-wait",
                     "--out", str(out))
    from boids_env.eval.ros2.node import Endpoints

    peer = _Peer(zenoh, Endpoints(connect=(ros2.endpoint,), listen=("tcp/127.0.0.1:0",))
                 .config(), "0/robot_1/odom/**")
    try:
        assert wait_until(lambda: peer.subscribed("boids_sim", "/robot_1/cmd_vel"), 60), \
            sim.output()
        assert wait_until(lambda: len(peer.seen) > 0, 60), sim.output()  # the episode runs
        good = peer.codec.encode(peer.msgs.twist(0.1, 0.0), TWIST)
        other = peer.odometry(1, 1_000_000_000)
        expected = peer.send_bad("/robot_1/cmd_vel", TWIST, good, other)
        end = time.monotonic() + 120
        while sim.popen.poll() is None and time.monotonic() < end:  # good ones: applied
            peer.put(peer.key("/robot_1/cmd_vel", TWIST), good)
            time.sleep(0.05)
        assert sim.wait(10) == 0, sim.output()[-3000:]
    finally:
        peer.close()
    output = sim.output()
    _no_tracebacks(output)
    counts = {"/robot_1/cmd_vel": expected}
    assert _counts(output, "/boids_sim") == counts
    config = json.loads((out / "config.json").read_text())
    assert config["ros"]["malformed"] == counts, config["ros"]
    stats = [json.loads(line) for line in output.splitlines() if line.startswith('{"late_ticks"')]
    assert stats and stats[-1]["malformed"] == counts
    # robot 1's good commands after the bad ones were applied (without them both followers
    # would time out at all 60 ticks)
    assert stats[-1]["timed_out"] < 2 * 60, stats[-1]
