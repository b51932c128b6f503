"""ROS messages of a recording, for :func:`boids_env.rosbag.write_bag`: odometry and commands
as the original system recorded them, plus what RViz and Foxglove need to show the flock as
the study's Fig. 5 did: ``/clock``, ``/tf`` (REP 105: ``map`` -> ``robot_k/odom`` ->
``robot_k/base_footprint``), robot markers, the rule forces as marker arrows and the leader's
scripted path; and what the live ROS 1 and ROS 2 nodes publish (:mod:`boids_env.eval.graph.
messages`): one module builds the messages of the bags and of the live topics alike, with
:mod:`boids_env.style`'s look.

The same builders serve ROS 1 (Noetic definitions) and ROS 2 (Humble definitions, which are
Jazzy's on the wire for every type used here) through rosbags' type stores, and the live ROS 1
nodes through a store of rospy's classes (:class:`boids_env.eval.ros.messages.RospyStore`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import style

FloatArray = npt.NDArray[np.float64]

FRAME = "map"
"""The world frame of every message."""
PERSON_HEIGHT = 1.7
"""Height (m) of the cylinders that mark people in the bags."""
STILL = 1e-3
"""Speed (m/s) below which a measured velocity has no direction (the heading is kept)."""
ARROW_SHAFT = 0.012
"""Diameter (m) of a force arrow's shaft in the markers; its head is twice as wide."""


def headings(commanded: FloatArray, velocities: FloatArray, still: float = STILL) -> FloatArray:
    """Each robot's heading (rad, world frame) at each sample, (T, N, 2) -> (T, N): the
    direction of its commanded velocity, else (no command) of its measured velocity, else
    (standing still) the last heading; 0 (facing +x) before it first has one."""
    cmd = np.asarray(commanded, dtype=float)
    vel = np.asarray(velocities, dtype=float)
    commanding = np.hypot(cmd[..., 0], cmd[..., 1]) > 0
    moving = np.hypot(vel[..., 0], vel[..., 1]) > still
    raw = np.where(commanding, np.arctan2(cmd[..., 1], cmd[..., 0]),
                   np.arctan2(vel[..., 1], vel[..., 0]))
    known = commanding | moving
    out = np.zeros(raw.shape)
    last = np.zeros(raw.shape[1])
    for t in range(raw.shape[0]):
        last = np.where(known[t], raw[t], last)
        out[t] = last
    return out


def split_ns(ns: int) -> tuple[int, int]:
    """Nanoseconds -> (seconds, nanoseconds) of a ROS time stamp."""
    return ns // 10**9, ns % 10**9


class Messages:
    """Builds the messages of one bag from a rosbags type store.

    Args:
        store: rosbags type store (``ROS1_NOETIC`` or ``ROS2_HUMBLE``).
        ros1: ROS 1 definitions (headers carry ``seq``; markers lack the ROS 2 fields).
        robot_radius: for the robot markers (m).
    """

    def __init__(self, store: Any, ros1: bool, robot_radius: float) -> None:
        self.t = store.types
        self.ros1 = ros1
        self.radius = robot_radius
        t = self.t
        self._zero36 = np.zeros(36, dtype=np.float64)
        self._vec = t["geometry_msgs/msg/Vector3"]
        self._forever = t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0)
        self._colours = {k: t["std_msgs/msg/ColorRGBA"](*(float(c) for c in v))
                         for k, v in (("robot 0", style.rgb01(style.LEADER)),
                                      ("robot", style.rgb01(style.FOLLOWER)),
                                      ("person", style.rgb01(style.PERSON)),
                                      ("pedestrians", style.rgb01(style.PEDESTRIAN)),
                                      *((name, style.rgb01(c))
                                        for name, c in style.RULE_COLOURS.items()))}

    def time(self, ns: int) -> Any:
        sec, nanosec = split_ns(ns)
        return self.t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)

    def header(self, ns: int, seq: int, frame: str = FRAME) -> Any:
        if self.ros1:
            return self.t["std_msgs/msg/Header"](seq=seq, stamp=self.time(ns), frame_id=frame)
        return self.t["std_msgs/msg/Header"](stamp=self.time(ns), frame_id=frame)

    def quaternion(self, yaw: float) -> Any:
        """A rotation by ``yaw`` about z."""
        return self.t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                      w=math.cos(yaw / 2))

    def rotation(self, z: float, w: float) -> Any:
        """A rotation about z given by its quaternion's (z, w) as they are (a live robot's
        orientation, carried bit for bit)."""
        return self.t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=float(z), w=float(w))

    def pose(self, x: float, y: float, yaw: float, z: float = 0.0) -> Any:
        point = self.t["geometry_msgs/msg/Point"](x=x, y=y, z=z)
        return self.t["geometry_msgs/msg/Pose"](position=point, orientation=self.quaternion(yaw))

    def twist(self, vx: float, vy: float, turn_rate: float = 0.0) -> Any:
        vec = self._vec
        return self.t["geometry_msgs/msg/Twist"](linear=vec(x=vx, y=vy, z=0.0),
                                                 angular=vec(x=0.0, y=0.0, z=turn_rate))

    def odometry(self, header: Any, k: int, position: FloatArray, velocity: FloatArray,
                 yaw: float, turn_rate: float = 0.0, *, child: str | None = None,
                 quaternion: tuple[float, float] | None = None) -> Any:
        """nav_msgs/Odometry of robot ``k``: pose (position, heading) and measured velocity in
        the map frame, as the original's odometry (for a robot with a heading: the twist in
        its own frame and its turn rate, REP 105). ``child`` replaces the child frame
        (``robot_k``); ``quaternion`` (z, w) replaces the orientation of ``yaw``."""
        t = self.t
        pose = self.pose(float(position[0]), float(position[1]), yaw)
        if quaternion is not None:
            pose.orientation = self.rotation(*quaternion)
        twist = self.twist(float(velocity[0]), float(velocity[1]), turn_rate)
        return t["nav_msgs/msg/Odometry"](
            header=header, child_frame_id=f"robot_{k}" if child is None else child,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=self._zero36),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist,
                                                             covariance=self._zero36))

    def clock(self, ns: int) -> Any:
        return self.t["rosgraph_msgs/msg/Clock"](clock=self.time(ns))

    def transforms(self, ns: int, seq: int, parents: list[str], children: list[str],
                   positions: FloatArray, quaternions: FloatArray | None) -> Any:
        """tf2_msgs/TFMessage: ``parents[k]`` -> ``children[k]`` translated by
        ``positions[k]`` and turned by ``quaternions[k]`` ((z, w); None: no rotation)."""
        t = self.t
        transforms = []
        for k, (x, y) in enumerate(np.asarray(positions, dtype=float).tolist()):
            rotation = self.rotation(0.0, 1.0) if quaternions is None else self.rotation(
                *quaternions[k])
            transform = t["geometry_msgs/msg/Transform"](
                translation=self._vec(x=x, y=y, z=0.0), rotation=rotation)
            transforms.append(t["geometry_msgs/msg/TransformStamped"](
                header=self.header(ns, seq, parents[k]), child_frame_id=children[k],
                transform=transform))
        return t["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def twist_stamped(self, header: Any, vx: float, vy: float, turn_rate: float = 0.0) -> Any:
        """geometry_msgs/TwistStamped (a TurtleBot3's ``cmd_vel`` from Jazzy on)."""
        return self.t["geometry_msgs/msg/TwistStamped"](header=header,
                                                        twist=self.twist(vx, vy, turn_rate))

    def laser_scan(self, header: Any, ranges: FloatArray, range_max: float,
                   scan_time: float = 0.0) -> Any:
        """sensor_msgs/LaserScan of ``ranges`` (m), rays evenly spaced counter-clockwise
        from the frame's x axis over a full turn; a ray that hits nothing within
        ``range_max`` reads +inf (REP 117)."""
        rays = len(ranges)
        step = 2 * math.pi / rays if rays else 0.0
        values = np.asarray(ranges, dtype=np.float32)
        values = np.where(values >= np.float32(range_max), np.float32(np.inf), values)
        return self.t["sensor_msgs/msg/LaserScan"](
            header=header, angle_min=0.0, angle_max=float(step * (rays - 1)),
            angle_increment=float(step), time_increment=0.0, scan_time=float(scan_time),
            range_min=0.0, range_max=float(range_max), ranges=values.astype(np.float32),
            intensities=np.zeros(0, dtype=np.float32))

    def string(self, text: str) -> Any:
        return self.t["std_msgs/msg/String"](data=text)

    def marker(self, header: Any, ns: str, marker_id: int, kind: int, action: int, pose: Any,
               scale: tuple[float, float, float], colour: Any, points: list[Any]) -> Any:
        t = self.t
        fields: dict[str, Any] = dict(
            header=header, ns=ns, id=marker_id, type=kind, action=action, pose=pose,
            scale=self._vec(x=scale[0], y=scale[1], z=scale[2]), color=colour,
            lifetime=self._forever, frame_locked=False, points=points, colors=[], text="",
            mesh_resource="", mesh_use_embedded_materials=False)
        if not self.ros1:  # fields ROS 2 added (Humble)
            fields.update(texture_resource="", uv_coordinates=[], mesh_file=t[
                "visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
                texture=t["sensor_msgs/msg/CompressedImage"](
                    header=header, format="", data=np.zeros(0, np.uint8)))
        return t["visualization_msgs/msg/Marker"](**fields)

    def robot_markers(self, ns: int, seq: int, positions: FloatArray, yaws: FloatArray) -> Any:
        """visualization_msgs/MarkerArray: a sphere of the robot's true size per robot, the
        leader red, followers blue (namespace ``robots``, id k)."""
        header = self.header(ns, seq)
        d = 2 * self.radius
        markers = [self.marker(header, "robots", k, 2, 0,  # SPHERE, ADD
                               self.pose(float(x), float(y), float(yaw)), (d, d, d),
                               self._colours["robot 0" if k == 0 else "robot"], [])
                   for k, ((x, y), yaw) in enumerate(zip(positions, yaws, strict=True))]
        return self.t["visualization_msgs/msg/MarkerArray"](markers=markers)

    def people_markers(self, ns: int, seq: int, person: FloatArray | None,
                       pedestrians: FloatArray, radius: float) -> Any:
        """visualization_msgs/MarkerArray: people as upright cylinders of their body's size
        (1.7 m tall): the person leading (namespace ``person``, id 0) and the crowd
        (namespace ``pedestrians``, id k)."""
        header = self.header(ns, seq)
        d, tall = 2 * radius, PERSON_HEIGHT
        walkers = [("person", 0, person)] if person is not None else []
        walkers += [("pedestrians", k, p) for k, p in enumerate(pedestrians)]
        markers = [self.marker(header, name, k, 3, 0,  # CYLINDER, ADD
                               self.pose(float(p[0]), float(p[1]), 0.0, tall / 2), (d, d, tall),
                               self._colours[name], [])
                   for name, k, p in walkers]
        return self.t["visualization_msgs/msg/MarkerArray"](markers=markers)

    def force_markers(self, ns: int, seq: int, followers: FloatArray,
                      forces: dict[str, FloatArray]) -> Any:
        """visualization_msgs/MarkerArray: each rule's force on each follower as an arrow from
        the follower (namespace = rule, id = robot k), scaled as in the videos
        (:func:`boids_env.style.arrow_vectors`); a zero force deletes its arrow."""
        header = self.header(ns, seq)
        point = self.t["geometry_msgs/msg/Point"]
        still = self.pose(0.0, 0.0, 0.0)
        size = (ARROW_SHAFT, 2 * ARROW_SHAFT, 2.5 * ARROW_SHAFT)
        markers = []
        for name, vectors in forces.items():
            colour = self._colours.get(name) or self.t["std_msgs/msg/ColorRGBA"](
                *style.rgb01(style.OTHER_ARROW))
            arrows = style.arrow_vectors(vectors)
            for i, ((x, y), (dx, dy)) in enumerate(zip(followers, arrows, strict=True)):
                if dx == 0 and dy == 0:
                    markers.append(self.marker(header, name, i + 1, 0, 2, still, size, colour,
                                               []))  # ARROW, DELETE
                    continue
                ends = [point(x=float(x), y=float(y), z=0.0),
                        point(x=float(x + dx), y=float(y + dy), z=0.0)]
                markers.append(self.marker(header, name, i + 1, 0, 0, still, size, colour,
                                           ends))
        return self.t["visualization_msgs/msg/MarkerArray"](markers=markers)

    def occupancy_grid(self, ns: int, grid: Any) -> Any:
        """nav_msgs/OccupancyGrid of a scene's cells (an :class:`OccupancyGrid`), as
        ``map_server`` publishes ``/map``: row 0 at the origin, 0 free, 100 occupied, −1
        unknown."""
        t = self.t
        h, w = grid.cells.shape
        x0, y0, yaw = grid.origin
        info = t["nav_msgs/msg/MapMetaData"](
            map_load_time=self.time(ns), resolution=float(grid.resolution), width=w, height=h,
            origin=self.pose(float(x0), float(y0), float(yaw)))
        return t["nav_msgs/msg/OccupancyGrid"](header=self.header(ns, 0), info=info,
                                               data=grid.cells.reshape(-1).astype(np.int8))

    def obstacle_markers(self, ns: int, scene: Any) -> Any:
        """visualization_msgs/MarkerArray of a scene's static geometry: the box's walls, the
        segments and the blocks' edges as one LINE_LIST (namespace ``walls``), each round
        pillar as a CYLINDER (namespace ``pillars``)."""
        header = self.header(ns, 0)
        point = self.t["geometry_msgs/msg/Point"]
        colour = self.t["std_msgs/msg/ColorRGBA"](0.37, 0.37, 0.36, 1.0)
        lines: list[Any] = []

        def add(a: FloatArray, b: FloatArray) -> None:
            lines.extend([point(x=float(a[0]), y=float(a[1]), z=0.0),
                          point(x=float(b[0]), y=float(b[1]), z=0.0)])

        if scene.box is not None:
            x0, y0, x1, y1 = scene.box
            corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
            for k in range(4):
                add(corners[k], corners[(k + 1) % 4])
        markers = []
        for k, (a, b, r) in enumerate(zip(scene.a, scene.b, scene.radius, strict=True)):
            if np.all(a == b):
                markers.append(self.marker(header, "pillars", k, 3, 0,  # CYLINDER, ADD
                                           self.pose(float(a[0]), float(a[1]), 0.0),
                                           (2 * float(r), 2 * float(r), 0.3), colour, []))
            else:
                add(a, b)
        for poly in scene.polygons:
            for k in range(len(poly)):
                add(poly[k], poly[(k + 1) % len(poly)])
        if lines:
            markers.insert(0, self.marker(header, "walls", 0, 5, 0, self.pose(0.0, 0.0, 0.0),
                                          (0.05, 0.0, 0.0), colour, lines))  # LINE_LIST
        return self.t["visualization_msgs/msg/MarkerArray"](markers=markers)

    def path(self, ns: int, seq: int, points: FloatArray) -> Any:
        """nav_msgs/Path of the leader's scripted path (a polyline in the map frame)."""
        header = self.header(ns, seq)
        poses = [self.t["geometry_msgs/msg/PoseStamped"](
            header=header, pose=self.pose(float(x), float(y), 0.0)) for x, y in points]
        return self.t["nav_msgs/msg/Path"](header=header, poses=poses)
