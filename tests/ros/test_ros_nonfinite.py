"""Issue 39: a NaN on a command or odometry topic never stops the ROS graph or goes back out:
the simulator drops an external leader's non-finite Twist (counted, as a follower's is), and
the controller sends a stop where a non-finite odometry made a command non-finite. The
handling is pure (no ROS needed); the node callbacks are called with stand-ins for rospy."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from boids_env.eval.graph.protocol import CommandBoard, finite_commands, finite_leader_command
from boids_env.eval.graph.sim import SimCore
from boids_env.eval.ros.sim import SimNode


def _twist(x, y):
    return SimpleNamespace(linear=SimpleNamespace(x=x, y=y, z=0.0),
                           angular=SimpleNamespace(x=0.0, y=0.0, z=0.0))


class _Rospy:
    def __init__(self):
        self.warnings = []

    def logwarn_throttle(self, period, text):
        self.warnings.append(text)


def test_a_nan_leader_twist_is_dropped_and_counted():
    core = SimpleNamespace(board=CommandBoard(2), leader_command=np.zeros(2))
    core.post_leader_command = lambda x, y: SimCore.post_leader_command(core, x, y)
    node = SimpleNamespace(name="sim", core=core, rospy=_Rospy())
    SimNode._on_leader(node, _twist(0.3, -0.1))
    assert core.leader_command.tolist() == [0.3, -0.1]
    SimNode._on_leader(node, _twist(math.nan, 0.2))
    SimNode._on_leader(node, _twist(0.1, math.inf))
    assert core.leader_command.tolist() == [0.3, -0.1], "the last finite command holds"
    assert core.board.rejected == 2
    assert node.rospy.warnings and "leader" in node.rospy.warnings[0]


def test_finite_leader_command_keeps_the_previous_one():
    previous = np.array([0.1, 0.2])
    out, ok = finite_leader_command(math.nan, 0.0, previous)
    assert not ok and out is previous
    out, ok = finite_leader_command(0.5, 0.0, previous)
    assert ok and out.tolist() == [0.5, 0.0]


def test_non_finite_commands_go_out_as_a_stop():
    commands = np.array([[0.1, 0.2], [math.nan, 0.3], [0.4, -math.inf], [0.0, 0.5]])
    out, bad = finite_commands(commands)
    assert bad == 2
    assert out.tolist() == [[0.1, 0.2], [0.0, 0.0], [0.0, 0.0], [0.0, 0.5]]
    same, none = finite_commands(out)
    assert none == 0 and same is out
