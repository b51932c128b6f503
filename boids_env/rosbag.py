"""Recordings to and from ROS bags, as the original ROS system recorded its runs: ROS 1 bags
(the original's format) and ROS 2 bags with MCAP storage, both through the same library.

Topics, one message per control step (10 Hz) stamped ``start`` + the episode time:

- ``/robot_k/odom`` (nav_msgs/Odometry: position, heading and measured velocity) and
  ``/robot_k/cmd_vel`` (geometry_msgs/Twist: the commanded velocity), robot 0 the leader, as
  the original recorded them (:func:`read_bag` needs only these);
- ``/clock`` (rosgraph_msgs/Clock), ``/tf`` (tf2_msgs/TFMessage, ``robot_k/odom`` ->
  ``robot_k/base_footprint``) and ``/tf_static`` (``map`` -> ``robot_k/odom``, latched, once):
  REP 105's tree, as a TurtleBot3's odometry gives it (the odometry's frame is
  ``robot_k/odom``, its child ``robot_k/base_footprint``), so that RViz and Foxglove play the
  bag on its own time;
- with a lidar (``lidar_rays``), every follower's ``/robot_k/scan`` (sensor_msgs/LaserScan in
  its ``base_footprint`` frame); ``cmd_vel`` as TwistStamped on request (``twist_stamped``);
- ``/markers/robots`` (visualization_msgs/MarkerArray: spheres of the robots' true size, the
  leader red) and ``/markers/forces`` (the policy's rule forces as arrows, when recorded);
- ``/leader/path`` (nav_msgs/Path: the leader's scripted path, latched, repeated every
  second), which :func:`read_bag` reads back for the leader's path deviation;
- with a person leading, ``/person/odom`` (nav_msgs/Odometry, child frame ``person``: the
  person's own odometry, the same pose and velocity as ``/robot_0/odom``); with a person or a
  crowd, ``/markers/people`` (visualization_msgs/MarkerArray: upright cylinders of their
  body's size, the person and the pedestrians);
- ``/map`` (nav_msgs/OccupancyGrid: the scene as ``map_server`` publishes a map, latched,
  once at the start: a map scene's own cells, any other scene rasterised at 5 cm) and
  ``/markers/obstacles`` (visualization_msgs/MarkerArray: walls and blocks as lines, pillars
  as cylinders; latched, once).

Pure Python through the ``rosbags`` package (``pip install -e '.[ros]'``); no ROS
install needed. ROS 2 bags carry Humble's message definitions (Jazzy's are the same on the
wire for these types) and version 5 metadata, which Humble's ``ros2 bag`` reads and later
distributions read too.
"""

from __future__ import annotations

import math
import re
import time
from io import StringIO
from pathlib import Path
from typing import Any

import numpy as np

from boids_env.config import EnvConfig
from boids_env.files import atomic_path
from boids_env.recording import Recording
from boids_env.rosmsgs import Messages, headings
from boids_env.world.layout import follower_cells
from boids_env.world.robots import quaternion_headings, to_body, to_world

try:
    from rosbags import rosbag1, rosbag2
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )
    from rosbags.rosbag2.enums import StoragePlugin
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
except ImportError as exc:  # pragma: no cover - depends on the install
    raise ImportError("ROS bag support needs rosbags: pip install -e '.[ros]'") from exc

ODOM = "nav_msgs/msg/Odometry"
TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
SCAN = "sensor_msgs/msg/LaserScan"
CLOCK = "rosgraph_msgs/msg/Clock"
TF = "tf2_msgs/msg/TFMessage"
MARKERS = "visualization_msgs/msg/MarkerArray"
PATH = "nav_msgs/msg/Path"
PATH_TOPIC = "/leader/path"
GRID = "nav_msgs/msg/OccupancyGrid"
MAP_TOPIC = "/map"
OBSTACLES_TOPIC = "/markers/obstacles"
PERSON_TOPIC = "/person/odom"
PEOPLE_TOPIC = "/markers/people"
_TOPIC = re.compile(r"^/robot_(\d+)/(odom|cmd_vel)$")
_TF_ROS1 = "geometry_msgs/TransformStamped[] transforms\n"
"""tf2_msgs/TFMessage in ROS 1, which rosbags' Noetic store lacks."""
METADATA_VERSION = 5
"""rosbag2 metadata version of our ROS 2 bags: Humble's own (its reader expects the QoS
profiles as a YAML string, which version 9 made a list); newer readers accept it."""

FORMATS = ("ros1", "mcap")


def write_bag(recording: Recording, path: str | Path, *, format: str = "ros1",
              start: float | None = None, twist_stamped: bool = False) -> None:
    """Writes ``recording`` at ``path`` (which must not exist), atomically: ``ros1``, a ROS 1
    bag file (Noetic message definitions), or ``mcap``, a ROS 2 bag folder with MCAP storage
    (Humble definitions, CDR, version 5 metadata).

    Args:
        recording: the episode.
        path: the bag file (``ros1``) or folder (``mcap``).
        format: ``ros1`` or ``mcap``.
        start: Unix time (s) of the recording's time 0, the first stamp; None: now. The
            recording's times are offsets from it.
        twist_stamped: ``cmd_vel`` as geometry_msgs/TwistStamped (a TurtleBot3 on Jazzy and
            later), stamped, in the robot's ``base_footprint`` frame; default Twist.
    """
    path = Path(path)
    if not isinstance(twist_stamped, bool):
        raise TypeError(f"twist_stamped must be True or False, got {twist_stamped!r}")
    if format not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, got {format!r}")
    if path.exists():
        raise FileExistsError(f"bag already exists: {path}")
    origin = time.time() if start is None else start
    if not (isinstance(origin, int | float) and math.isfinite(origin)
            and 0 <= origin < 2**32 - recording.time[-1] - 1):
        raise ValueError(f"start must be a Unix time in seconds from 0 to 2^32 (ROS 1 stamps "
                         f"are unsigned 32-bit seconds), got {start!r}")
    ros1 = format == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        store.register(get_types_from_msg(_TF_ROS1, TF))
    with atomic_path(path) as tmp:
        writer_cm = rosbag1.Writer(tmp) if ros1 else rosbag2.Writer(
            tmp, version=8, storage_plugin=StoragePlugin.MCAP)
        with writer_cm as writer:
            _write_messages(writer, store, ros1, recording, _to_ns(origin), twist_stamped)
        if not ros1:
            _humble_metadata(tmp, path.name)


def _write_messages(writer: Any, store: Any, ros1: bool, recording: Recording,
                    origin: int, twist_stamped: bool = False) -> None:
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    n = recording.positions.shape[1]
    latched = {"latching": 1} if ros1 else {"offered_qos_profiles": [_qos(latched=True)]}
    usual = {} if ros1 else {"offered_qos_profiles": [_qos()]}

    def connect(topic: str, msgtype: str, **kwargs: Any) -> Any:
        return writer.add_connection(topic, msgtype, typestore=store, **(kwargs or usual))

    odom = [connect(f"/robot_{k}/odom", ODOM) for k in range(n)]
    cmd_type = TWIST_STAMPED if twist_stamped else TWIST
    cmd = [connect(f"/robot_{k}/cmd_vel", cmd_type) for k in range(n)]
    clock, tf = connect("/clock", CLOCK), connect("/tf", TF)
    rays = recording.config.observation.lidar_rays
    scans = [connect(f"/robot_{k}/scan", SCAN) for k in range(1, n)] if rays else []
    odom_frames = [f"robot_{k}/odom" for k in range(n)]
    base_frames = [f"robot_{k}/base_footprint" for k in range(n)]
    robots = connect("/markers/robots", MARKERS)
    forces = connect("/markers/forces", MARKERS) if recording.forces else None
    route = connect(PATH_TOPIC, PATH, **latched) if recording.leader_path is not None else None
    sc = recording.config.scenario
    person = connect(PERSON_TOPIC, ODOM) if sc.leader_radius is not None else None
    crowd = recording.pedestrians
    people = connect(PEOPLE_TOPIC, MARKERS) if person is not None or crowd is not None else None
    build = Messages(store, ros1, recording.config.world.robot_radius)
    scene = recording.config.scene
    first = origin + round(float(recording.time[0]) * 1e9)
    writer.write(connect(MAP_TOPIC, GRID, **latched), first,
                 serialize(build.occupancy_grid(first, scene.occupancy()), GRID))
    writer.write(connect(OBSTACLES_TOPIC, MARKERS, **latched), first,
                 serialize(build.obstacle_markers(first, scene), MARKERS))
    # REP 105: map -> robot_k/odom (identity, latched) -> robot_k/base_footprint (the pose)
    writer.write(connect("/tf_static", TF, **latched), first, serialize(build.transforms(
        first, 0, ["map"] * n, odom_frames, np.zeros((n, 2)), None), TF))
    yaws, velocities, commands, turns = _motion(recording)
    lidar = _lidar(recording) if rays else None
    per_second = max(1, round(1.0 / recording.config.world.dt))
    for step, offset in enumerate(recording.time):
        ns = origin + round(float(offset) * 1e9)
        pos, vel, com = recording.positions[step], velocities[step], commands[step]
        writer.write(clock, ns, serialize(build.clock(ns), CLOCK))
        turned = np.stack([np.sin(yaws[step] / 2), np.cos(yaws[step] / 2)], axis=-1)
        writer.write(tf, ns, serialize(build.transforms(ns, step, odom_frames, base_frames,
                                                        pos, turned), TF))
        for k in range(n):
            header = build.header(ns, step, odom_frames[k])
            msg = build.odometry(header, k, pos[k], vel[k], float(yaws[step, k]),
                                 float(turns[step, k]), child=base_frames[k])
            writer.write(odom[k], ns, serialize(msg, ODOM))
            twist = (float(com[k, 0]), float(com[k, 1]), float(com[k, 2]))
            writer.write(cmd[k], ns, serialize(
                build.twist_stamped(build.header(ns, step, base_frames[k]), *twist)
                if twist_stamped else build.twist(*twist), cmd_type))
        if lidar is not None:
            for k, conn in enumerate(scans):
                header = build.header(ns, step, base_frames[k + 1])
                writer.write(conn, ns, serialize(build.laser_scan(
                    header, lidar(step)[k], recording.config.observation.lidar_range), SCAN))
        writer.write(robots, ns, serialize(build.robot_markers(ns, step, pos, yaws[step]),
                                           MARKERS))
        if person is not None:
            msg = build.odometry(build.header(ns, step), 0, pos[0], vel[0], float(yaws[step, 0]))
            msg.child_frame_id = "person"
            writer.write(person, ns, serialize(msg, ODOM))
        if people is not None:
            walkers = np.zeros((0, 2)) if crowd is None else crowd[step]
            markers = build.people_markers(ns, step, pos[0] if person is not None else None,
                                           walkers, sc.person_radius)
            writer.write(people, ns, serialize(markers, MARKERS))
        if forces is not None:
            assert recording.forces is not None
            vectors = {name: vec[step] for name, vec in recording.forces.items()}
            writer.write(forces, ns, serialize(build.force_markers(ns, step, pos[1:], vectors),
                                               MARKERS))
        if route is not None and step % per_second == 0:
            assert recording.leader_path is not None
            writer.write(route, ns, serialize(build.path(ns, step, recording.leader_path),
                                              PATH))


def _lidar(recording: Recording) -> Any:
    """``scans(step)``: the followers' lidar ranges (F, R) at a sample, each in its own frame
    (:func:`~boids_env.observations.lidar_scans`: static geometry and the other robots)."""
    from boids_env.observations import Observer, lidar_scans

    config = recording.config
    sensors = Observer(config).sensors
    rays = config.observation.lidar_rays
    vectors = None if recording.headings is None else np.stack(
        [np.cos(recording.headings), np.sin(recording.headings)], axis=-1)

    def scans(step: int) -> np.ndarray:
        return lidar_scans(recording.positions[step], rays, sensors,
                           None if vectors is None else vectors[step])

    return scans


def _motion(recording: Recording) -> tuple[np.ndarray, ...]:
    """Headings (T, N), odometry velocities (T, N, 2), cmd_vel (T, N, 3: linear.x, linear.y,
    angular.z) and turn rates (T, N) as the bag carries them: the study's robots' world-frame
    velocities and commands, headed along the command (else the motion); a robot with a
    heading's own heading, its twist in its own frame and its (v, ω) (REP 105)."""
    if recording.headings is None:
        still = np.zeros((*recording.commanded.shape[:2], 1))
        commands = np.concatenate([recording.commanded, still], axis=-1)
        return (headings(recording.commanded, recording.velocities), recording.velocities,
                commands, np.zeros(recording.positions.shape[:2]))
    assert recording.native is not None and recording.angular_velocities is not None
    yaws = recording.headings
    unit = np.stack([np.cos(yaws), np.sin(yaws)], axis=-1)  # a bag's orientation, not physics
    steps, n = yaws.shape
    body = to_body(recording.velocities.reshape(-1, 2), unit.reshape(-1, 2)).reshape(steps, n,
                                                                                      2)
    native = recording.native
    commands = np.stack([native[..., 0], np.zeros((steps, n)), native[..., 1]], axis=-1)
    return yaws, body, commands, recording.angular_velocities


def _to_ns(seconds: float) -> int:
    """Unix seconds -> integer nanoseconds, exact to the nanosecond (a double holds 1.7e18 ns
    only to 256 ns)."""
    whole = math.floor(seconds)
    return whole * 10**9 + round((seconds - whole) * 1e9)


def _qos(latched: bool = False) -> Any:
    """The offered QoS of a topic: reliable, keep last 10, volatile; latched (the leader's
    path): transient local, keep last 1, so that a late subscriber (RViz) still gets it."""
    never = QosTime(sec=0, nsec=0)  # unspecified: the default, infinite
    durability = QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE
    return Qos(QosHistory.KEEP_LAST, 1 if latched else 10, QosReliability.RELIABLE, durability,
               never, never, QosLiveliness.AUTOMATIC, never, False)


def _humble_metadata(folder: Path, name: str) -> None:
    """Renames the bag's MCAP file after the bag (``name``.mcap; it was written under a
    temporary name) and rewrites rosbags' metadata (version 8) as version 5, Humble's: the
    fields Humble reads (the QoS profiles a YAML string, as both versions have them), without
    the later ones (``custom_data``, ``ros_distro``, ``type_description_hash``)."""
    from ruamel.yaml import YAML

    meta = folder / "metadata.yaml"
    yaml = YAML(typ="safe")
    data = yaml.load(meta.read_text())
    info = data["rosbag2_bagfile_information"]
    info["version"] = METADATA_VERSION
    for key in ("custom_data", "ros_distro"):
        info.pop(key, None)
    for topic in info["topics_with_message_count"]:
        topic["topic_metadata"].pop("type_description_hash", None)
    (old,) = info["relative_file_paths"]
    new = f"{name}.mcap"
    (folder / old).rename(folder / new)
    info["relative_file_paths"] = [new]
    for entry in info["files"]:
        entry["path"] = new
    yaml.default_flow_style = False
    out = StringIO()
    yaml.dump(data, out)
    meta.write_text(out.getvalue())


MAX_BAG_BYTES = 1024 * 1024 * 1024
"""Largest bag read (1 GiB: a ROS 1 file, or a ROS 2 folder's files together)."""
MAX_BAG_MESSAGES = 5_000_000
"""Most messages a bag may hold (each odometry sample is kept until the end: about 5 GB of
Python objects at this bound would be far beyond any episode; 19 robots at 10 Hz for an hour
send 1.4 M)."""


def check_bag(path: Path) -> None:
    """Refuses, before rosbags opens it, a bag that is not a regular file (or a folder of
    regular files, its own ``metadata.yaml`` read with the bounded YAML reader) within
    :data:`MAX_BAG_BYTES`: a bag is a file from elsewhere."""
    from boids_env.untrusted import check_file, parse_yaml, quote_path, read_text

    if not path.is_dir():
        check_file(path, "bag", MAX_BAG_BYTES)
        return
    total = 0
    for member in sorted(path.iterdir()):
        if member.is_symlink() or member.is_dir():
            raise ValueError(f"bag {quote_path(path)}: {quote_path(member.name)} is a link or a "
                             f"folder; a ROS 2 bag folder holds plain files only")
        total += check_file(member, "bag", MAX_BAG_BYTES)
        if total > MAX_BAG_BYTES:
            raise ValueError(f"bag {quote_path(path)}: more than the {MAX_BAG_BYTES:,} bytes "
                             f"allowed")
    meta = path / "metadata.yaml"
    if meta.exists():
        parse_yaml(read_text(meta, "bag metadata", 1024 * 1024), "bag metadata")


def _bounded(messages: Any) -> Any:
    """The bag's messages, refused past :data:`MAX_BAG_MESSAGES`."""
    for count, message in enumerate(messages, 1):
        if count > MAX_BAG_MESSAGES:
            raise ValueError(f"more than the {MAX_BAG_MESSAGES:,} messages a bag may hold")
        yield message


def _read_messages(path: Path) -> tuple[dict[int, list[tuple[float, ...]]],
                                         dict[int, list[tuple[float, ...]]], np.ndarray | None]:
    """The bag's messages by robot: each robot k's odometry rows ``(stamp, x, y, vx, vy, qz,
    qw, ω)`` and ``cmd_vel`` rows ``(vx, vy, ω)``, in message order, and the first leader
    path (None without one). ``ValueError`` for a file that is not a readable bag."""
    store = get_typestore(Stores.ROS1_NOETIC if path.is_file() else Stores.ROS2_HUMBLE)
    odom: dict[int, list[tuple[float, ...]]] = {}
    cmd: dict[int, list[tuple[float, ...]]] = {}
    leader_path: np.ndarray | None = None
    try:
        with AnyReader([path], default_typestore=store) as reader:
            for conn, stamp, raw in _bounded(reader.messages()):
                if conn.topic == PATH_TOPIC and leader_path is None:  # ours: the first one
                    # rosbags builds message classes at run time: its deserialize returns object
                    path_msg: Any = reader.deserialize(raw, conn.msgtype)
                    poses = path_msg.poses
                    leader_path = np.array([(p.pose.position.x, p.pose.position.y)
                                            for p in poses], dtype=np.float64).reshape(-1, 2)
                match = _TOPIC.match(conn.topic)
                if not match:
                    continue
                k = int(match.group(1))
                msg: Any = reader.deserialize(raw, conn.msgtype)  # an Odometry or a Twist
                if match.group(2) == "odom":
                    p, v = msg.pose.pose.position, msg.twist.twist.linear
                    q, w = msg.pose.pose.orientation, msg.twist.twist.angular.z
                    odom.setdefault(k, []).append((stamp, p.x, p.y, v.x, v.y, q.z, q.w, w))
                else:
                    t = msg.twist if hasattr(msg, "twist") else msg  # TwistStamped, or Twist
                    cmd.setdefault(k, []).append((t.linear.x, t.linear.y, t.angular.z))
    except FileNotFoundError:
        raise
    except Exception as exc:
        raise ValueError(f"cannot read ROS bag {path}: {exc}") from exc
    return odom, cmd, leader_path


def read_bag(path: str | Path, config: EnvConfig | None = None, *,
             odometry_only: bool = False, answers: bool = False) -> Recording:
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
        answers: the bag was recorded from a live graph, where each robot's k-th
            ``cmd_vel`` answers its k-th odometry and so is the command of sample k+1:
            commands move one sample later (sample 0, the reset state, gets zero), and a
            robot may lack its last answer (T−1 or T commands for T samples).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"bag not found: {path}")
    check_bag(path)
    odom, cmd, leader_path = _read_messages(path)
    robots = _check_topics(path, odom, cmd, odometry_only, answers)
    o = np.array([odom[k] for k in robots], dtype=np.float64)  # (N, T, 8)
    c = _commands(o, cmd, robots, odometry_only, answers)
    for name, values in (("odom", o), ("cmd_vel", c)):
        bad = sorted({int(k) for k in np.nonzero(~np.isfinite(values))[0]})
        if bad:
            raise ValueError(f"{path}: non-finite values in the {name} messages of "
                             f"{_robots(bad)}")
    base = _fit_config(path, config if config is not None else EnvConfig(), len(robots),
                       float(np.abs(o[:, :, 1:3]).max()))
    # robot 0's odometry stamps (exact integers, ns): times from the first
    stamps = np.array([row[0] for row in odom[robots[0]]], dtype=np.int64)

    def samples(a: np.ndarray) -> np.ndarray:
        # (T, N, 2) in C order, as a live recording's: numpy sums in memory order, so the
        # metrics come out bit-identical
        return np.ascontiguousarray(a.transpose(1, 0, 2))

    time = (stamps - stamps[0]) / 1e9
    if base.world.has_heading and not odometry_only:
        return _heading_recording(base, time, o, c, leader_path)
    return Recording(base, time, samples(o[:, :, 1:3]), samples(o[:, :, 3:5]),
                     samples(c[:, :, :2]), leader_path=leader_path)


def _heading_recording(config: EnvConfig, time: np.ndarray, o: np.ndarray, c: np.ndarray,
                       leader_path: np.ndarray | None) -> Recording:
    """The recording of robots with a heading (``config``'s drive): odometry oriented along
    the heading, its twist in the robot's frame, ``cmd_vel`` the robot's (v, ω) (REP 105).
    A command's world-frame direction is the heading its robot had when it was given (the
    sample before)."""
    z, w = o[:, :, 5].T, o[:, :, 6].T  # (T, N)
    unit = quaternion_headings(z, w)
    steps, n = z.shape
    velocities = to_world(np.ascontiguousarray(o[:, :, 3:5].transpose(1, 0, 2)).reshape(-1, 2),
                          unit.reshape(-1, 2)).reshape(steps, n, 2)
    native = np.ascontiguousarray(c[:, :, [0, 2]].transpose(1, 0, 2))
    before = np.concatenate([unit[:1], unit[:-1]])
    commanded = before * native[..., :1]
    yaw = 2.0 * np.arctan2(z, w)
    yaw = yaw - 2 * math.pi * np.round(yaw / (2 * math.pi))
    return Recording(config, time, np.ascontiguousarray(o[:, :, 1:3].transpose(1, 0, 2)),
                     velocities, commanded, leader_path=leader_path, headings=yaw,
                     angular_velocities=np.ascontiguousarray(o[:, :, 7].T), native=native)


def _commands(o: np.ndarray, cmd: dict[int, list], robots: list[int], odometry_only: bool,
              answers: bool) -> np.ndarray:
    """The commands (N, T, 3: linear.x, linear.y, angular.z) per sample: the measured
    velocities (``odometry_only``), the k-th command at sample k+1 (``answers``; zero at
    sample 0), or the k-th at sample k."""
    if odometry_only:
        return np.concatenate([o[:, :, 3:5], o[:, :, 7:8]], axis=2)
    if answers:
        c = np.zeros((len(robots), o.shape[1], 3))
        c[:, 1:] = np.array([cmd[k][: o.shape[1] - 1] for k in robots], dtype=np.float64)
        return c
    return np.array([cmd[k] for k in robots], dtype=np.float64)


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
                  odometry_only: bool, answers: bool = False) -> list[int]:
    """The robots 0..N-1 of a bag whose topics align message by message; ``ValueError``
    naming the robots otherwise."""
    robots = sorted(odom)
    if not robots:
        raise ValueError(f"{path} has no /robot_k/odom topics (robot 0 the leader)")
    # the first gaps only, counted without building 0..k for the highest index k: a topic
    # /robot_1099511627776/odom must not ask for a set of 2**40 numbers
    present = set(robots)
    gaps = robots[-1] + 1 - len(robots)
    if gaps:
        first = [k for k in range(min(robots[-1] + 1, len(robots) + 10)) if k not in present]
        shown = _robots(first[:10]) + (f" and {gaps - 10:,} more" if gaps > 10 else "")
        raise ValueError(f"{path}: robots must be numbered robot_0..robot_{robots[-1]} without "
                         f"gaps; no odom for {shown}")
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
    allowed = {counts[robots[0]] - 1, counts[robots[0]]} if answers else {counts[robots[0]]}
    differ = {k: len(cmd[k]) for k in robots if len(cmd[k]) not in allowed}
    if differ:
        need = (f"{counts[robots[0]] - 1} or {counts[robots[0]]}" if answers
                else f"{counts[robots[0]]}")
        raise ValueError(f"{path}: each robot needs as many cmd_vel as odom messages "
                         f"({need}); cmd_vel counts differ for "
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
