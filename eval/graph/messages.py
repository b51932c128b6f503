"""A simulator's tick (:class:`~boids_env.eval.graph.sim.SimFrame`) as the messages every
transport publishes, built by the graph's one builder, :class:`boids_env.rosmsgs.Messages`
(rospy's objects for ROS 1, rosbags' for ROS 2); the transports choose only the frames."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from boids_env.eval.graph.protocol import MAP_FRAME, pedestrian_frame
from boids_env.eval.graph.sim import SimFrame
from boids_env.rosmsgs import Messages


def robot_odometry(m: Messages, frame: SimFrame, parents: Sequence[str],
                   children: Sequence[str]) -> list[Any]:
    """Every robot's nav_msgs/Odometry of the tick: robot k in ``parents[k]`` with child
    frame ``children[k]``; identity orientation for holonomic robots, else oriented by the
    robot's quaternion with the twist in its own frame and its turn rate (REP 105)."""
    ns, q = frame.stamp_ns, frame.quaternions
    return [m.odometry(m.header(ns, 0, parents[k]), k, frame.positions[k],
                       frame.velocities[k], 0.0, float(frame.turn_rates[k]), child=children[k],
                       quaternion=None if q is None else (q[k, 0], q[k, 1]))
            for k in range(len(frame.positions))]


def crowd_odometry(m: Messages, frame: SimFrame) -> list[Any]:
    """Every pedestrian's nav_msgs/Odometry of the tick (in ``map``, child
    ``pedestrian_k``, the velocity in the twist): none without a crowd."""
    crowd = frame.crowd
    if crowd is None:
        return []
    return [m.odometry(m.header(frame.stamp_ns, 0, MAP_FRAME), k, crowd.positions[k],
                       crowd.velocities[k], 0.0, child=pedestrian_frame(k))
            for k in range(len(crowd.positions))]


def transforms(m: Messages, frame: SimFrame, parents: Sequence[str],
               children: Sequence[str]) -> Any:
    """The tick's ``/tf``: ``parents[k]`` -> ``children[k]`` at robot k's pose."""
    return m.transforms(frame.stamp_ns, 0, list(parents), list(children), frame.positions,
                        frame.quaternions)
