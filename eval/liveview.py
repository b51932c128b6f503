"""The live view over Foxglove's WebSocket protocol (``boids run --live foxglove``,
``boids ros2 sim --live foxglove``): the running episode served by the Foxglove SDK
(``pip install -e '.[live]'``) for Foxglove (app or web) to open at
``ws://127.0.0.1:8765``, no ROS needed.

Channels (Foxglove's own schemas, protobuf):

- ``/scene`` (foxglove.SceneUpdate): the robots as spheres of their true size (the leader
  red, followers blue), each follower's trail of the last :data:`TRAIL_SECONDS`, the scene's
  walls and blocks (lines) and pillars (cylinders), pedestrians (cylinders) and, with a lidar,
  every follower's rays (lines to where they hit);
- ``/tf`` (foxglove.FrameTransforms): ``map`` → ``robot_k``;
- ``/robots`` (foxglove.PosesInFrame): every robot's pose in ``map``, the leader first;
- ``/metrics`` (JSON): the study's running V_sep, V_coh, V_align and the steps so far, for a
  Plot panel (``/metrics.V_sep``).

Log times are the episode's simulated time from :data:`LOG_START` on, each episode after the
previous one (never going back across resets), paced at ``speed`` × real time.
"""

from __future__ import annotations

import math
import os
import socket
import threading
import time
from collections import deque
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import style
from boids_env.config import EnvConfig
from boids_env.extras import import_extra

FloatArray = npt.NDArray[np.float64]

DEFAULT_PORT = 8765
"""Foxglove's usual port."""
TRAIL_SECONDS = 5.0
SCENE_EVERY = 10
"""Ticks between repeats of the static scene (a client that connects late gets it within a
second)."""
LOG_START = 1_000_000_000
"""Log time (ns) of the first tick: 1 s, as the ROS graph's clock starts."""
MAX_SPEED = 1000.0


def _foxglove() -> Any:
    return import_extra("foxglove", "the live view needs the Foxglove SDK: pip install "
                        "-e '.[live]'")


def _taken(port: int, host: str, why: str) -> ValueError:
    return ValueError(f"the live view's port {port} on {host} is taken ({why}): another live "
                      f"view or a Foxglove bridge runs there? Choose another with --live-port "
                      f"PORT (port= in Python), or --live-port 0 for any free one")


def check_port(port: int, host: str = "127.0.0.1") -> None:
    """Refuses a port the live view could not listen on (``ValueError`` naming it and how to
    choose another), so that ``--live foxglove`` is refused before the run starts rather
    than ending it with the server's error. Port 0 (any free one) always passes."""
    if port == 0:
        return
    try:
        # as the server binds (SO_REUSEADDR: a port left in TIME_WAIT is free to it)
        with socket.create_server((host, port)):
            pass
    except OSError as exc:
        why = os.strerror(exc.errno) if exc.errno else str(exc)
        raise _taken(port, host, why) from None


SUBSCRIBE_GRACE = 0.5
"""Seconds the first tick waits after a client's first subscription (``wait``), for its
other subscriptions of the same request."""

class FoxgloveView:
    """A Foxglove WebSocket server showing one run (see the module's docstring).

    Args:
        config: the run's env config (robot size, scene, dt).
        host, port: where the server listens (``port=0``: any free port, see :attr:`port`).
        speed: times real time (0: as fast as the run goes).
        wait: seconds to wait for a client to subscribe before the first tick (0: none).
        name: the server's name, as Foxglove shows it.
    """

    def __init__(self, config: EnvConfig, *, host: str = "127.0.0.1",
                 port: int = DEFAULT_PORT, speed: float = 1.0, wait: float = 0.0,
                 name: str = "boids") -> None:
        if not (isinstance(port, int) and not isinstance(port, bool) and 0 <= port <= 65535):
            raise ValueError(f"port must be an integer in [0, 65535], got {port!r}")
        if not (isinstance(speed, int | float) and 0 <= speed <= MAX_SPEED):
            raise ValueError(f"speed must be in [0, {MAX_SPEED:g}] times real time (0: as fast "
                             f"as possible), got {speed!r}")
        if not (isinstance(wait, int | float) and 0 <= wait <= 3600):
            raise ValueError(f"wait must be in [0, 3600] s, got {wait!r}")
        foxglove = _foxglove()
        from foxglove.channels import (
            FrameTransformsChannel,
            PosesInFrameChannel,
            SceneUpdateChannel,
        )

        self.config, self.speed = config, float(speed)
        self.dt = config.world.dt
        self._subscribed = threading.Event()
        view = self

        class Listener(foxglove.ServerListener):  # type: ignore[misc, name-defined]
            def on_subscribe(self, client: Any, channel: Any) -> None:
                view._subscribed.set()

        self._listener = Listener()
        self.context = foxglove.Context()
        try:
            self.server = foxglove.start_server(name=name, host=host, port=port,
                                                server_listener=self._listener,
                                                context=self.context)
        except RuntimeError as exc:  # the SDK's FoxgloveError: taken since check_port
            if "bind" not in str(exc).lower():
                raise
            raise _taken(port, host, str(exc)) from None
        self.port = int(self.server.port)
        self.scene = SceneUpdateChannel("/scene", context=self.context)
        self.tf = FrameTransformsChannel("/tf", context=self.context)
        self.poses = PosesInFrameChannel("/robots", context=self.context)
        self.metrics = foxglove.Channel("/metrics", message_encoding="json",
                                        context=self.context)
        self._trails: deque[FloatArray] = deque(maxlen=max(2, round(TRAIL_SECONDS / self.dt)))
        self._ticks = 0
        self._offset = LOG_START
        """Log time of the current episode's tick 0 (ns)."""
        self._last = LOG_START - 1
        self._paced: tuple[float, int] | None = None
        self._static = self._scene_entities()
        if wait > 0 and self._subscribed.wait(wait):
            # a client subscribes to its panels' channels together, reported one by one:
            # the first tick waits for the rest of them too
            time.sleep(SUBSCRIBE_GRACE)

    # ------------------------------------------------------------------------- episodes
    def new_episode(self) -> None:
        """The next tick starts a new episode: its time continues after the last one's."""
        self._offset = self._last + round(self.dt * 1e9)
        self._trails.clear()

    def log_time(self, step: int) -> int:
        """The log time (ns) of step ``step`` of the current episode."""
        return self._offset + step * round(self.dt * 1e9)

    # -------------------------------------------------------------------------- showing
    def show(self, step: int, positions: FloatArray, headings: FloatArray | None = None,
             metrics: dict[str, Any] | None = None, scans: FloatArray | None = None,
             pedestrians: FloatArray | None = None) -> int:
        """Logs one tick (``headings``: (N, 2) heading vectors, None: facing +x); returns its
        log time (ns). Paced at ``speed`` × real time."""
        ns = max(self.log_time(step), self._last + 1)
        self._pace(ns)
        self._last = ns
        positions = np.asarray(positions, dtype=float)
        yaws = np.zeros(len(positions)) if headings is None else np.arctan2(
            headings[:, 1], headings[:, 0])
        self._trails.append(positions.copy())
        self.tf.log(self._transforms(ns, positions, yaws), log_time=ns)
        self.poses.log(self._poses(ns, positions, yaws), log_time=ns)
        self.scene.log(self._update(ns, positions, scans, pedestrians, yaws), log_time=ns)
        if metrics is not None:
            self.metrics.log({"timestamp": {"sec": ns // 10**9, "nsec": ns % 10**9},
                              **{k: metrics[k] for k in ("V_sep", "V_coh", "V_align", "steps")
                                 if k in metrics}}, log_time=ns)
        self._ticks += 1
        return ns

    def _pace(self, ns: int) -> None:
        if self.speed <= 0:
            return
        now = time.monotonic()
        if self._paced is None:
            self._paced = (now, ns)
            return
        due = self._paced[0] + (ns - self._paced[1]) / 1e9 / self.speed
        if due > now:
            time.sleep(due - now)
        elif now - due > 1.0:  # far behind (a slow step): re-anchor instead of rushing
            self._paced = (now, ns)

    # ------------------------------------------------------------------------- messages
    @staticmethod
    def _stamp(ns: int) -> Any:
        from foxglove.messages import Timestamp

        return Timestamp(sec=ns // 10**9, nsec=ns % 10**9)

    @staticmethod
    def _quaternion(yaw: float) -> Any:
        from foxglove.messages import Quaternion

        return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def _pose(self, x: float, y: float, yaw: float = 0.0, z: float = 0.0) -> Any:
        from foxglove.messages import Pose, Vector3

        return Pose(position=Vector3(x=float(x), y=float(y), z=float(z)),
                    orientation=self._quaternion(float(yaw)))

    def _transforms(self, ns: int, positions: FloatArray, yaws: FloatArray) -> Any:
        from foxglove.messages import FrameTransform, FrameTransforms, Vector3

        stamp = self._stamp(ns)
        return FrameTransforms(transforms=[
            FrameTransform(timestamp=stamp, parent_frame_id="map", child_frame_id=f"robot_{k}",
                           translation=Vector3(x=float(x), y=float(y), z=0.0),
                           rotation=self._quaternion(float(yaw)))
            for k, ((x, y), yaw) in enumerate(zip(positions.tolist(), yaws, strict=True))])

    def _poses(self, ns: int, positions: FloatArray, yaws: FloatArray) -> Any:
        from foxglove.messages import PosesInFrame

        return PosesInFrame(timestamp=self._stamp(ns), frame_id="map",
                            poses=[self._pose(x, y, yaw) for (x, y), yaw
                                   in zip(positions.tolist(), yaws, strict=True)])

    @staticmethod
    def _colour(rgb: tuple[float, float, float], alpha: float = 1.0) -> Any:
        from foxglove.messages import Color

        return Color(r=rgb[0], g=rgb[1], b=rgb[2], a=alpha)

    def _lines(self, points: list[tuple[float, float]], rgb: tuple[float, float, float],
               thickness: float, kind: str = "LineList", alpha: float = 1.0) -> Any:
        from foxglove.messages import LinePrimitive, LinePrimitiveLineType, Point3

        return LinePrimitive(type=getattr(LinePrimitiveLineType, kind),
                             pose=self._pose(0.0, 0.0), thickness=thickness,
                             scale_invariant=False,
                             points=[Point3(x=float(x), y=float(y), z=0.0) for x, y in points],
                             color=self._colour(rgb, alpha))

    def _scene_entities(self) -> list[Any]:
        """The static scene: walls and block edges as lines, pillars as cylinders."""
        from foxglove.messages import CylinderPrimitive, Vector3

        scene = self.config.scene
        grey = (0.37, 0.37, 0.36)
        segments: list[tuple[float, float]] = []
        if scene.box is not None:
            x0, y0, x1, y1 = scene.box
            corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
            for k in range(4):
                segments += [corners[k], corners[(k + 1) % 4]]
        pillars = []
        for a, b, r in zip(scene.a, scene.b, scene.radius, strict=True):
            if np.all(a == b):
                pillars.append(CylinderPrimitive(
                    pose=self._pose(a[0], a[1], z=0.15),
                    size=Vector3(x=2 * float(r), y=2 * float(r), z=0.3),
                    bottom_scale=1.0, top_scale=1.0, color=self._colour(grey)))
            else:
                segments += [(float(a[0]), float(a[1])), (float(b[0]), float(b[1]))]
        for poly in scene.polygons:
            for k in range(len(poly)):
                segments += [tuple(poly[k]), tuple(poly[(k + 1) % len(poly)])]
        lines = [self._lines(segments, grey, 0.05)] if segments else []
        return [("walls", lines, pillars)]

    def _update(self, ns: int, positions: FloatArray, scans: FloatArray | None,
                pedestrians: FloatArray | None, yaws: FloatArray) -> Any:
        from foxglove.messages import (
            CylinderPrimitive,
            SceneEntity,
            SceneUpdate,
            SpherePrimitive,
            Vector3,
        )

        stamp = self._stamp(ns)
        d = 2 * self.config.world.robot_radius
        leader, follower = style.rgb01(style.LEADER), style.rgb01(style.FOLLOWER)
        spheres = [SpherePrimitive(pose=self._pose(x, y), size=Vector3(x=d, y=d, z=d),
                                   color=self._colour(leader if k == 0 else follower))
                   for k, (x, y) in enumerate(positions.tolist())]
        entities = [SceneEntity(timestamp=stamp, frame_id="map", id="robots",
                                spheres=spheres)]
        trail = np.array(self._trails)  # (T, N, 2)
        if len(trail) > 1:
            lines = [self._lines([tuple(p) for p in trail[:, k].tolist()],
                                 leader if k == 0 else follower, 0.01, "LineStrip", 0.5)
                     for k in range(trail.shape[1])]
            entities.append(SceneEntity(timestamp=stamp, frame_id="map", id="trails",
                                        lines=lines))
        if pedestrians is not None and len(pedestrians):
            r = self.config.scenario.person_radius
            people = [CylinderPrimitive(pose=self._pose(x, y, z=0.85),
                                        size=Vector3(x=2 * r, y=2 * r, z=1.7),
                                        bottom_scale=1.0, top_scale=1.0,
                                        color=self._colour(style.rgb01(style.PEDESTRIAN)))
                      for x, y in np.asarray(pedestrians, dtype=float).tolist()]
            entities.append(SceneEntity(timestamp=stamp, frame_id="map", id="pedestrians",
                                        cylinders=people))
        if scans is not None:
            entities.append(SceneEntity(timestamp=stamp, frame_id="map", id="lidar",
                                        lines=[self._lidar_lines(positions, scans, yaws)]))
        if self._ticks % SCENE_EVERY == 0:
            for name, lines, cylinders in self._static:
                entities.append(SceneEntity(timestamp=stamp, frame_id="map", id=name,
                                            lines=lines, cylinders=cylinders))
        return SceneUpdate(entities=entities)

    def _lidar_lines(self, positions: FloatArray, scans: FloatArray, yaws: FloatArray) -> Any:
        rays = scans.shape[1]
        angles = 2 * np.pi * np.arange(rays) / rays
        points: list[tuple[float, float]] = []
        for k, ranges in enumerate(np.asarray(scans, dtype=float)):
            x, y = positions[k + 1]
            a = angles + yaws[k + 1]
            for r, c, s in zip(ranges.tolist(), np.cos(a).tolist(), np.sin(a).tolist(),
                               strict=True):
                points += [(x, y), (x + r * c, y + r * s)]
        return self._lines(points, (0.9, 0.5, 0.0), 0.005, alpha=0.6)

    def close(self) -> None:
        self.server.stop()


def env_frame(env: Any) -> dict[str, Any]:
    """What :meth:`FoxgloveView.show` takes, from a running env: positions, heading vectors,
    the running metrics, the followers' lidar scans (with ``lidar_rays``), pedestrians."""
    from boids_env.observations import Observer, lidar_scans

    snap = env.snapshot()
    headings = None
    if snap.quaternions is not None:
        from boids_env.world.robots import quaternion_headings

        headings = quaternion_headings(snap.quaternions[:, 0], snap.quaternions[:, 1])
    scans = None
    rays = env.config.observation.lidar_rays
    if rays > 0:
        sensors = getattr(env, "_live_sensors", None)
        if sensors is None:
            sensors = env._live_sensors = Observer(env.config).sensors
        scans = lidar_scans(snap.positions, rays, sensors, headings)
    world = env._require_world()
    pedestrians = world.pedestrian_positions if getattr(world, "p", 0) else None
    return dict(positions=snap.positions, headings=headings, metrics=env.episode_metrics(),
                scans=scans, pedestrians=pedestrians)
