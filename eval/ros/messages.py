"""ROS 1's messages: the graph's one builder, :class:`boids_env.rosmsgs.Messages` (the bags'
and ROS 2's, with :mod:`boids_env.style`'s look), making rospy's message objects; and rospy
publishers. Nothing here imports rospy: the nodes hand it in, imported through
:func:`~boids_env.eval.ros.rospy_path.import_rospy` when they start."""

from __future__ import annotations

import importlib
import warnings
from typing import Any

import numpy as np

from boids_env.rosmsgs import Messages


def publisher(rospy: Any, topic: str, data_class: Any, *, latch: bool = False) -> Any:
    """A publisher that writes synchronously (``queue_size=None``): rospy's queued publisher
    hands every message to a thread and yields the GIL (``time.sleep(0)``), 0.2–0.3 ms a
    message, which doubled a lockstep tick; a synchronous write also means back-pressure
    instead of dropped messages when a subscriber (a recorder) is slow. rospy's warning about
    the missing queue size is silenced: no queue is the choice."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SyntaxWarning)
        return rospy.Publisher(topic, data_class, queue_size=None, latch=latch,
                               tcp_nodelay=True)


ARRAY_FIELDS = {"geometry_msgs/msg/PoseWithCovariance": "covariance",
                "geometry_msgs/msg/TwistWithCovariance": "covariance",
                "nav_msgs/msg/OccupancyGrid": "data"}
"""The numpy array fields the builder fills, which rospy takes as tuples: it serialises a
numpy array's elements one by one, several times slower."""


class RospyTypes(dict[str, Any]):
    """rosbags' type names (``nav_msgs/msg/Odometry``) to rospy's message classes, which take
    the same keyword arguments; stamps and durations become ``rospy.Time`` and
    ``rospy.Duration``, numpy array fields (:data:`ARRAY_FIELDS`) tuples. Looked up when
    first asked for."""

    def __init__(self, rospy: Any) -> None:
        super().__init__()
        self.rospy = rospy

    def __missing__(self, name: str) -> Any:
        package, _, kind = name.split("/")
        value: Any
        if name == "builtin_interfaces/msg/Time":
            value = lambda sec, nanosec: self.rospy.Time(sec, nanosec)  # noqa: E731
        elif name == "builtin_interfaces/msg/Duration":
            value = lambda sec, nanosec: self.rospy.Duration(sec, nanosec)  # noqa: E731
        else:
            value = _direct(getattr(importlib.import_module(f"{package}.msg"), kind),
                            ARRAY_FIELDS.get(name))
        self[name] = value
        return value


def _direct(data_class: Any, array: str | None) -> Any:
    """``data_class``'s constructor, made direct where every field is given (as the builder
    gives them): rospy's own fills every field's default before taking the given ones, about
    ten times the cost, which a lockstep tick of markers paid hundreds of times. ``array``:
    a field taken as a tuple of Python numbers (:data:`ARRAY_FIELDS`)."""
    slots = tuple(data_class.__slots__)

    def build(*args: Any, **fields: Any) -> Any:
        if args:
            fields = dict(zip(slots, args, strict=True))
        if array is not None:
            fields[array] = tuple(np.asarray(fields[array]).tolist())
        if len(fields) != len(slots):
            return data_class(**fields)  # rospy's defaults for the fields not given
        msg = object.__new__(data_class)
        for name, value in fields.items():
            setattr(msg, name, value)  # a name that is no field raises (slots)
        return msg

    return build


class RospyStore:
    """A stand-in for a rosbags type store (its ``types``) with rospy's classes."""

    def __init__(self, rospy: Any) -> None:
        self.types = RospyTypes(rospy)


def ros1_messages(rospy: Any, robot_radius: float) -> Messages:
    """The graph's message builder making ``rospy``'s objects (Noetic's definitions; rospy
    from :func:`~boids_env.eval.ros.rospy_path.import_rospy`) for robots of
    ``robot_radius`` (m)."""
    return Messages(RospyStore(rospy), True, robot_radius)
