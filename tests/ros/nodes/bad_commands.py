"""A node that puts bad commands on ``/robot_1/cmd_vel`` (issue 55): ``--count`` messages of
3 bytes under Twist's type and md5 (a message cut short), each followed by a good Twist,
and as many Odometry messages on ``/robot_2/cmd_vel`` (the wrong type). Prints ``done``."""

from __future__ import annotations

import argparse
import time

from boids_env.eval.ros.rospy_path import import_rospy


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--count", type=int, default=20)
    args = parser.parse_args()
    rospy = import_rospy()
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry

    class CutShort(Twist):
        """A Twist whose wire bytes are 3 (rospy serialises what ``serialize`` writes)."""

        __slots__ = ()

        def serialize(self, buff) -> None:
            buff.write(b"\x01\x02\x03")

    rospy.init_node("bad_commands", disable_signals=True)
    short = rospy.Publisher("/robot_1/cmd_vel", Twist, queue_size=100)
    wrong = rospy.Publisher("/robot_2/cmd_vel", Odometry, queue_size=100)
    deadline = time.monotonic() + 30
    while not short.get_num_connections() and time.monotonic() < deadline:
        time.sleep(0.05)
    good = Twist()
    good.linear.x = 0.1
    for _ in range(args.count):
        short.publish(CutShort())
        wrong.publish(Odometry())
        time.sleep(0.05)
        short.publish(good)
        time.sleep(0.05)
    print("done", flush=True)
    time.sleep(1.0)


if __name__ == "__main__":
    main()
