"""Recordings to and from ROS bags, as the original ROS system recorded its runs: ROS 1 bags
(the original's format) and ROS 2 bags with MCAP storage, both through the same library.

Topics ``/robot_k/odom`` (nav_msgs/Odometry: position and measured velocity) and
``/robot_k/cmd_vel`` (geometry_msgs/Twist: the commanded velocity), robot 0 the leader, one
message per robot per control step, stamped with the episode time. Pure Python through the
``rosbags`` package (``pip install 'boids-env[ros]'``); no ROS install needed.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from boids_env.config import EnvConfig
from boids_env.layout import follower_cells
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


def write_bag(recording: Recording, path: str | Path, *, format: str = "ros1") -> None:
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
        for step, time in enumerate(recording.time):
            ns = round(float(time) * 1e9)
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


def read_bag(path: str | Path, config: EnvConfig | None = None, *,
             odometry_only: bool = False) -> Recording:
    """Reads a bag (ROS 1 file, or ROS 2 folder: MCAP or SQLite) with ``/robot_k/odom`` and
    ``/robot_k/cmd_vel`` topics into a Recording.

    Samples are aligned by message order per robot (the k-th odom of every robot is sample k),
    so every robot must have as many odom messages as the others, and as many cmd_vel as odom
    messages; otherwise a ``ValueError`` names the robots and their counts (nothing is cut).
    ``config`` gives the thresholds and dt for the metrics (default: the study's), with the
    group size taken from the bag; when the bag's robots or coordinates do not fit that
    config (many robots, an arena larger than 10 m), a config that holds them is derived: the
    initial grid is packed tighter and the arena grows to the data (so wall contacts count
    only at the data's extent). Raises ``ValueError`` for a file that is not such a bag or
    holds invalid data (non-finite values, robots missing from the ``robot_0..robot_k``
    sequence, coordinates beyond the largest arena the env models).

    Args:
        path: the bag file (ROS 1) or folder (ROS 2).
        config: thresholds, dt and arena for the metrics.
        odometry_only: read a bag without ``cmd_vel`` topics, taking each robot's measured
            velocity (odometry twist) as its command, so ``V_align`` compares the robots'
            actual headings rather than their commands. Off by default: a bag without
            commands is an error rather than silently zero commands.
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
    robots = _check_topics(path, odom, cmd, odometry_only)
    o = np.array([odom[k] for k in robots], dtype=np.float64)  # (N, T, 5)
    c = o[:, :, 3:5] if odometry_only else np.array([cmd[k] for k in robots], dtype=np.float64)
    for name, values in (("odom", o), ("cmd_vel", c)):
        bad = sorted({int(k) for k in np.nonzero(~np.isfinite(values))[0]})
        if bad:
            raise ValueError(f"{path}: non-finite values in the {name} messages of "
                             f"{_robots(bad)}")
    base = _fit_config(path, config if config is not None else EnvConfig(), len(robots),
                       float(np.abs(o[:, :, 1:3]).max()))
    time = o[0, :, 0] / 1e9  # stamps (ns) of robot 0's odometry
    return Recording(base, time, o[:, :, 1:3].transpose(1, 0, 2), o[:, :, 3:5].transpose(1, 0, 2),
                     np.ascontiguousarray(c.transpose(1, 0, 2)))


def _robots(ks: list[int], limit: int = 10) -> str:
    names = ", ".join(f"robot_{k}" for k in ks[:limit])
    return names + (f" and {len(ks) - limit} more" if len(ks) > limit else "")


def _counts(counts: dict[int, int], limit: int = 10) -> str:
    """``robot_0: 50, robot_3: 3`` for the robots whose count is not the most common one
    (and one that is, for comparison)."""
    values = list(counts.values())
    common = max(set(values), key=values.count)
    odd = [k for k, v in counts.items() if v != common][:limit]
    usual = next(k for k, v in counts.items() if v == common)
    shown = sorted({usual, *odd})
    rest = len(counts) - len(shown)
    return (", ".join(f"robot_{k}: {counts[k]}" for k in shown)
            + (f" (the other {rest}: {common})" if rest else ""))


def _check_topics(path: Path, odom: dict[int, list], cmd: dict[int, list],
                  odometry_only: bool) -> list[int]:
    """The robots 0..N-1 of a bag whose topics align message by message; ``ValueError``
    naming the robots otherwise."""
    robots = sorted(odom)
    if not robots:
        raise ValueError(f"{path} has no /robot_k/odom topics (robot 0 the leader)")
    missing = sorted(set(range(robots[-1] + 1)) - set(robots))
    if missing:
        raise ValueError(f"{path}: robots must be numbered robot_0..robot_{robots[-1]} without "
                         f"gaps; no odom for {_robots(missing)}")
    if len(robots) < 2:
        raise ValueError(f"{path} holds one robot; the metrics need the leader (robot_0) and "
                         f"at least one follower")
    counts = {k: len(odom[k]) for k in robots}
    if len(set(counts.values())) > 1:
        raise ValueError(f"{path}: the robots have different numbers of odom messages "
                         f"({_counts(counts)}); samples are aligned by message order, so each "
                         f"robot needs one per step")
    if odometry_only:
        return robots
    if not cmd:
        raise ValueError(f"{path} has no /robot_k/cmd_vel topics, so the commanded velocities "
                         f"(and V_align) are unknown; read_bag(..., odometry_only=True) takes "
                         f"the measured velocities as the commands")
    lacking = [k for k in robots if k not in cmd]
    stray = sorted(set(cmd) - set(robots))
    if lacking or stray:
        raise ValueError(f"{path}: cmd_vel and odom topics disagree: no cmd_vel for "
                         f"{_robots(lacking) or 'none'}; cmd_vel without odom for "
                         f"{_robots(stray) or 'none'}")
    differ = {k: len(cmd[k]) for k in robots if len(cmd[k]) != counts[k]}
    if differ:
        raise ValueError(f"{path}: each robot needs as many cmd_vel as odom messages "
                         f"({counts[robots[0]]}); cmd_vel counts differ for "
                         + ", ".join(f"robot_{k}: {v}" for k, v in list(differ.items())[:10]))
    return robots


def _fit_config(path: Path, base: EnvConfig, robots: int, extent: float) -> EnvConfig:
    """``base`` with the bag's group size, made to hold ``robots`` robots and coordinates up to
    ``extent`` metres: the arena grows when the data leave it, the initial grid (which a
    recording never uses) is packed tighter when it does not fit."""
    world = base.world
    if base.scenario.robots == robots and extent + world.robot_radius < world.arena_half_size:
        return base
    halves = [world.arena_half_size]
    if extent + world.robot_radius >= world.arena_half_size:
        halves = [extent + 1.0, extent + world.robot_radius + 0.01]
    reach = float(np.abs(follower_cells(robots, 1.0)).max(initial=0.0)) * math.sqrt(2)
    last: Exception | None = None
    for half in halves:
        spacing = min(base.scenario.layout_spacing,
                      max(0.1, 0.9 * (half - world.robot_radius) / max(reach, 1e-9)))
        grown = max(half, 0.1 * reach + world.robot_radius + 0.5)
        for changes in ({}, {"layout_spacing": spacing, "init_jitter": 0.0},
                        {"layout_spacing": 0.1, "init_jitter": 0.0, "arena_half_size": grown}):
            try:
                return base.replace(**{"robots": robots, "arena_half_size": half, **changes})
            except (ValueError, TypeError) as exc:
                last = exc
    raise ValueError(f"{path}: no env config holds {robots} robots with coordinates up to "
                     f"{extent:.4g} m ({last})")
