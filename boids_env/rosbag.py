"""Recordings to and from ROS bags, as the original ROS system recorded its runs: ROS 1 bags
(the original's format) and ROS 2 bags with MCAP storage, both through the same library.

Topics ``/robot_k/odom`` (nav_msgs/Odometry: position and measured velocity) and
``/robot_k/cmd_vel`` (geometry_msgs/Twist: the commanded velocity), robot 0 the leader, one
message per robot per control step, stamped with the episode time. Pure Python through the
``rosbags`` package (``pip install 'boids-env[ros]'``); no ROS install needed.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np

from boids_env.config import EnvConfig
from boids_env.recording import Recording

try:
    from rosbags import rosbag1, rosbag2
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2.enums import StoragePlugin
    from rosbags.typesys import Stores, get_typestore
except ImportError as exc:  # pragma: no cover - depends on the install
    raise ImportError("ROS bag support needs rosbags: pip install 'boids-env[ros]'") from exc

ODOM = "nav_msgs/msg/Odometry"
TWIST = "geometry_msgs/msg/Twist"
_TOPIC = re.compile(r"^/robot_(\d+)/(odom|cmd_vel)$")


FORMATS = ("ros1", "mcap")


def write_bag(recording: Recording, path: str | Path, *, format: str = "ros1",
              start: float | None = None) -> None:
    """Writes ``recording`` at ``path`` (which must not exist): ``ros1``, a ROS 1 bag file
    (Noetic message definitions), or ``mcap``, a ROS 2 bag folder with MCAP storage (Humble
    definitions, CDR)."""
    path = Path(path)
    if format not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, got {format!r}")
    if path.exists():
        raise FileExistsError(f"bag already exists: {path}")
    ros1 = format == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    t = store.types
    zero36 = np.zeros(36, dtype=np.float64)
    quat = t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    n = recording.positions.shape[1]
    writer_cm = rosbag1.Writer(path) if ros1 else rosbag2.Writer(
        path, version=9, storage_plugin=StoragePlugin.MCAP)
    with writer_cm as writer:
        odom = [writer.add_connection(f"/robot_{k}/odom", ODOM, typestore=store)
                for k in range(n)]
        cmd = [writer.add_connection(f"/robot_{k}/cmd_vel", TWIST, typestore=store)
               for k in range(n)]
        origin = round((time.time() if start is None else start) * 1e9)
        for step, offset in enumerate(recording.time):
            ns = origin + round(float(offset) * 1e9)
            stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            for k in range(n):
                x, y = (float(v) for v in recording.positions[step, k])
                vx, vy = (float(v) for v in recording.velocities[step, k])
                cx, cy = (float(v) for v in recording.commanded[step, k])
                header = (t["std_msgs/msg/Header"](seq=step, stamp=stamp, frame_id="map") if ros1
                          else t["std_msgs/msg/Header"](stamp=stamp, frame_id="map"))
                pose = t["geometry_msgs/msg/Pose"](
                    position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=quat)
                twist = _twist(t, vx, vy)
                msg = t[ODOM](
                    header=header, child_frame_id=f"robot_{k}",
                    pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=zero36),
                    twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist,
                                                                     covariance=zero36))
                writer.write(odom[k], ns, serialize(msg, ODOM))
                writer.write(cmd[k], ns, serialize(_twist(t, cx, cy), TWIST))


def _twist(types: dict, vx: float, vy: float) -> object:
    vec = types["geometry_msgs/msg/Vector3"]
    return types[TWIST](linear=vec(x=vx, y=vy, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0))


def read_bag(path: str | Path, config: EnvConfig | None = None) -> Recording:
    """Reads a bag (ROS 1 file, or ROS 2 folder: MCAP or SQLite) with ``/robot_k/odom`` and
    ``/robot_k/cmd_vel`` topics into a Recording.

    Samples are aligned by message order per robot (the k-th odom of every robot is sample k);
    ``config`` gives the thresholds and dt for the metrics (default: the study's, with the
    group size taken from the bag). Raises ``ValueError`` for a file that is not such a bag.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"bag not found: {path}")
    store = get_typestore(Stores.ROS1_NOETIC if path.is_file() else Stores.ROS2_HUMBLE)
    odom: dict[int, list[tuple[int, float, float, float, float]]] = {}
    cmd: dict[int, list[tuple[float, float]]] = {}
    try:
        with AnyReader([path], default_typestore=store) as reader:
            for conn, stamp, raw in reader.messages():
                match = _TOPIC.match(conn.topic)
                if not match:
                    continue
                k = int(match.group(1))
                msg = reader.deserialize(raw, conn.msgtype)
                if match.group(2) == "odom":
                    p, v = msg.pose.pose.position, msg.twist.twist.linear
                    odom.setdefault(k, []).append((stamp, p.x, p.y, v.x, v.y))
                else:
                    cmd.setdefault(k, []).append((msg.linear.x, msg.linear.y))
    except FileNotFoundError:
        raise
    except Exception as exc:
        raise ValueError(f"cannot read ROS bag {path}: {exc}") from exc
    robots = sorted(odom)
    if not robots or robots != list(range(len(robots))):
        raise ValueError(f"{path} has no /robot_0../robot_k odom topics (found {robots})")
    steps = min(len(odom[k]) for k in robots)
    o = np.array([odom[k][:steps] for k in robots], dtype=np.float64)  # (N, T, 5)
    c = np.zeros((len(robots), steps, 2))
    for k in robots:
        got = np.array(cmd.get(k, [])[:steps], dtype=np.float64).reshape(-1, 2)
        c[k, : len(got)] = got
    base = config if config is not None else EnvConfig()
    if base.scenario.robots != len(robots):
        base = base.replace(robots=len(robots), arena_half_size=max(
            base.world.arena_half_size, float(np.abs(o[:, :, 1:3]).max()) + 1.0))
    # robot 0's odometry stamps (exact integers, ns): times from the first
    stamps = np.array([row[0] for row in odom[0][:steps]], dtype=np.int64)
    return Recording(base, (stamps - stamps[0]) / 1e9, o[:, :, 1:3].transpose(1, 0, 2),
                     o[:, :, 3:5].transpose(1, 0, 2), c.transpose(1, 0, 2))
