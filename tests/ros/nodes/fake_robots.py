"""A bare scripted "robot" driver for the tests: no simulator of ours.

Publishes ``/robot_k/odom`` for ``--robots`` robots at 10 Hz of wall time (one stamp per tick
for all robots, as Stage does; ``--unsynced`` stamps each robot on its own), drives robot 0
(the leader) along +x at 0.3 m/s after 1 s, and moves every follower by its latest
``/robot_k/cmd_vel`` (perfect kinematics: p += v·dt). Records every tick's positions, the
commands received and the controller's rule-force markers; ``--reconfigure-at T`` changes the
controller's ``leader_weight`` to ``--leader-weight`` at tick T through dynamic_reconfigure's
client (what rqt_reconfigure and dynparam use). Writes everything to ``--out`` (JSON).
"""

from __future__ import annotations

import argparse
import json
import threading
import time

import numpy as np

from boids_env.eval.ros.rospy_path import import_rospy


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--ticks", type=int, default=60)
    parser.add_argument("--out", required=True)
    parser.add_argument("--unsynced", action="store_true")
    parser.add_argument("--reconfigure-at", type=int, default=None)
    parser.add_argument("--leader-weight", type=float, default=0.3)
    parser.add_argument("--wait-controller", type=float, default=30.0)
    args = parser.parse_args()

    rospy = import_rospy()
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    from visualization_msgs.msg import MarkerArray

    rospy.init_node("fake_robots", disable_signals=True)
    n, dt = args.robots, 0.1
    lock = threading.Lock()
    commands = np.zeros((n, 2))
    received = np.zeros(n, dtype=int)
    markers: list[dict] = []

    def on_cmd(msg, k):
        with lock:
            commands[k] = (msg.linear.x, msg.linear.y)
            received[k] += 1

    def on_markers(msg):
        arrows = {}
        for m in msg.markers:
            if not m.points:  # a zero force: its arrow is deleted
                arrows.setdefault(m.ns, {})[m.id] = [0.0, 0.0]
                continue
            (a, b) = m.points
            arrows.setdefault(m.ns, {})[m.id] = [b.x - a.x, b.y - a.y]
        with lock:
            markers.append({"stamp": msg.markers[0].header.stamp.to_nsec() if msg.markers
                            else 0, "arrows": arrows})

    pubs = [rospy.Publisher(f"/robot_{k}/odom", Odometry, queue_size=100) for k in range(n)]
    subs = [rospy.Subscriber(f"/robot_{k}/cmd_vel", Twist, on_cmd, callback_args=k,
                             queue_size=100, tcp_nodelay=True) for k in range(1, n)]
    rospy.Subscriber("/reynolds_controller/markers", MarkerArray, on_markers, queue_size=100)
    # wait for a controller: a publisher on every follower's command topic
    end = time.monotonic() + args.wait_controller
    while any(s.get_num_connections() == 0 for s in subs) and time.monotonic() < end:
        time.sleep(0.05)
    while any(p.get_num_connections() == 0 for p in pubs) and time.monotonic() < end:
        time.sleep(0.05)

    positions = np.array([[0.0, 0.0]] + [[-0.6 - 0.3 * k, -0.4 * (k % 2)]
                                         for k in range(1, n)])
    velocities = np.zeros((n, 2))
    log = {"positions": [], "received_before": [], "stamps": [], "reconfigured": None}
    start = time.monotonic()
    for tick in range(args.ticks):
        stamp_ns = 10**9 + tick * 10**8
        log["positions"].append(positions.tolist())
        log["stamps"].append(stamp_ns)
        with lock:
            log["received_before"].append(received.tolist())
        order = list(range(n))
        for k in order:
            msg = Odometry()
            own = stamp_ns + (k * 1_000_000 if args.unsynced else 0)
            msg.header.stamp = rospy.Time(own // 10**9, own % 10**9)
            msg.header.frame_id = "map"
            msg.child_frame_id = f"robot_{k}"
            msg.pose.pose.orientation.w = 1.0
            msg.pose.pose.position.x, msg.pose.pose.position.y = positions[k]
            msg.twist.twist.linear.x, msg.twist.twist.linear.y = velocities[k]
            pubs[k].publish(msg)
        if args.reconfigure_at is not None and tick == args.reconfigure_at:
            from dynamic_reconfigure.client import Client

            client = Client("/reynolds_controller", timeout=10)
            result = client.update_configuration({"leader_weight": args.leader_weight})
            log["reconfigured"] = {"tick": tick, "leader_weight": result["leader_weight"],
                                   "param": rospy.get_param("/reynolds_controller/"
                                                            "leader_weight")}
        time.sleep(max(0.0, start + (tick + 1) * dt - time.monotonic()))
        with lock:
            velocities[1:] = commands[1:]
        velocities[0] = (0.3, 0.0) if tick * dt >= 1.0 else (0.0, 0.0)
        positions = positions + velocities * dt
    time.sleep(0.3)
    with lock:
        log["received"] = received.tolist()
        log["markers"] = markers
    with open(args.out, "w") as fh:
        json.dump(log, fh)
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
