"""Robot models: how a robot's body enters the pymunk space, how a command becomes its motion,
and the presets of real robots (the study's Sphero, a TurtleBot3 Burger, the Robotarium's
GRITSbot).

One small class per drive, as VMAS's ``simulator/dynamics/``: :class:`Holonomic` (the study's
omnidirectional disc) and :class:`Unicycle` (a robot with a heading that moves only along it:
differential drive, and a Sphero as its driver rolls it). :class:`~boids_env.world.space.World`
holds one and never asks which.

**Holonomic** (``drive="holonomic"``, the default): a dynamic disc of infinite moment joined
to a kinematic *control body* by a pivot joint (``max_bias = 0``, ``max_force =
drive_force``); the control body's velocity is the command, set once per control period.

**Unicycle** (``drive="unicycle"``): the same disc and pivot, plus a groove joint along the
robot's heading with unlimited force: the wheels never slip sideways (a robot pushed from the
side does not yield; one pressed diagonally into a wall stalls, as a differential drive does).
The heading θ and the turn rate ω are the model's own state (frictionless discs take no torque
from contacts, so rotation does not enter pymunk's solver): each control period ω moves towards
the commanded turn rate by at most ``max_turn_acceleration · dt`` and stays within
``max_turn_rate``; before every physics substep the heading turns by ω·h and the control body
is set to ``v`` along it (and turned with it, so the groove follows), so the sideways
constraint holds within the control period too. The forward speed is tracked with at most
``drive_force``.

**The driver's law** (world-frame velocity command u → (v, ω)), with e the angle from the
heading ĥ to u: ω = clip(k · sin e, ±ω_max) while |e| ≤ 90°, ±ω_max (towards u) beyond, and
- ``turn_and_drive`` (differential drive; the Robotarium's ``si_to_uni_dyn`` without reverse):
  v = max(u · ĥ, 0) = |u| · max(cos e, 0): the robot slows as it turns, turns in place when u
  points behind it, and never reverses;
- ``roll`` (the Sphero's driver: ``cmd_vel`` → heading = atan2, speed = |u|): v = |u|: it
  rolls on at the commanded speed while its heading swings round at the rotation rate.

The gain k is ``heading_gain`` (1/s; default ``max_turn_rate``, full rate at 90°). No atan2,
sin or cos of float arrays is taken (numpy's SIMD versions may differ in the last bit between
CPUs): e enters only through u · ĥ and u × ĥ, and the heading turns by a Taylor polynomial of
the small per-substep angle.

Headings as odometry reports them: a ROS odometry message carries the heading as a quaternion
and the velocity in the robot's own frame (REP 105). The env observes (and its driver law
reads) exactly what such a message gives back (:func:`odometry_headings`,
:func:`odometry_velocities`), so a controller node fed by ROS odometry computes the same bits as
the env in-process.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
import pymunk
import pymunk.batch as batch

from boids_env import kernels
from boids_env.world.robot_protocols import World, WorldConfig

FloatArray = npt.NDArray[np.float64]

VELOCITY_LAWS = ("turn_and_drive", "roll")
"""How a unicycle's driver turns a world-frame velocity command into (v, ω) (module doc)."""
ACTIONS = ("velocity", "unicycle")
"""Action spaces: ``velocity`` (world-frame (vx, vy), every robot; the study's) or ``unicycle``
((v, ω) in the robot's own limits: forward speed m/s, turn rate rad/s, counter-clockwise)."""

LEADER_SPEED_RATIO = 1.1
"""The study's default leader speed over the followers' top speed (0.55 / 0.5 m/s): choosing a
robot sets ``leader_speed`` to this times its ``max_speed`` unless given."""
STUDY_GAP = 0.5 - 2 * 0.036
"""Free gap (m) between neighbouring robots of the study's start grid (0.5 m cells, 36 mm
Spheros): choosing a robot sets ``layout_spacing`` to this plus its diameter unless given."""
GROOVE_LENGTH = 1e4
"""Half length (m) of a unicycle's sideways constraint along its control body's axis: the
robot's centre stays within it however far the control body drifts (only its velocity acts)."""
MAX_TURN_PER_SUBSTEP = 0.2
"""Largest heading change (rad) in one physics substep (max_turn_rate · dt / substeps); the
heading's Taylor polynomial is exact to rounding up to it."""


@dataclass(frozen=True)
class RobotPreset:
    """A real robot's published figures, as env config fields (the docs' robots page cites the
    sources)."""

    robot_radius: float
    """Radius (m) of the disc that collides (a non-round robot: its circumscribed circle)."""
    robot_mass: float
    """Mass (kg)."""
    max_speed: float
    """Top speed (m/s)."""
    drive_force: float
    """Largest drive force (N): mass × the linear acceleration limit."""
    drive: str = "holonomic"
    max_turn_rate: float | None = None
    """Top turn rate (rad/s), unicycles only."""
    max_turn_acceleration: float | None = None
    """Turn-rate acceleration limit (rad/s²); None: the turn rate follows its command at once."""
    heading_gain: float | None = None
    """k of the driver's law (1/s); None: ``max_turn_rate``."""
    velocity_law: str = "turn_and_drive"

    def fields(self) -> dict[str, Any]:
        """The env config fields this preset sets (by flat name)."""
        return {"robot_radius": self.robot_radius, "robot_mass": self.robot_mass,
                "max_speed": self.max_speed, "drive_force": self.drive_force,
                "drive": self.drive, "max_turn_rate": self.max_turn_rate,
                "max_turn_acceleration": self.max_turn_acceleration,
                "heading_gain": self.heading_gain, "velocity_law": self.velocity_law}


ROBOT_PRESETS: dict[str, RobotPreset] = {
    # The study's robot as the study simulated it: holonomic, capped at 0.5 m/s, 1 N drive.
    "sphero": RobotPreset(0.036, 0.18, 0.5, 1.0),
    # A real Sphero SPRK+ as the sphero_sprk_ros driver moves it: cmd_vel -> roll(speed,
    # heading = atan2); the firmware rolls at that speed and turns to the heading at its
    # rotation rate (Sphero API "Set Rotation Rate": C8h = 157 deg/s; maximum 400 deg/s). The
    # study's 0.5 m/s cap is kept (the SPRK+ itself reaches about 2 m/s). The heading is met
    # within a control period when the rate allows (k = 1 / dt at the study's 10 Hz).
    "sphero_sprk": RobotPreset(0.036, 0.18, 0.5, 1.0, "unicycle", math.radians(157.0), None,
                               10.0, "roll"),
    # ROBOTIS TurtleBot3 Burger: 0.22 m/s, 2.84 rad/s, 1 kg (e-Manual, turtlebot3_teleop);
    # radius 0.105 m (turtlebot3_navigation costmap); acceleration 2.5 m/s² and 3.2 rad/s²
    # (turtlebot3_navigation dwa_local_planner_params_burger.yaml).
    "turtlebot3_burger": RobotPreset(0.105, 1.0, 0.22, 2.5, "unicycle", 2.84, 3.2),
    # The Robotarium's GRITSbot as its rps simulator limits it: 0.11 m diameter, 0.2 m/s,
    # 2·0.2/0.11 = 3.64 rad/s. Mass and acceleration are not published (rps sets velocities
    # at once every 0.033 s): 0.25 kg and 4 m/s² (full speed in 0.05 s) are our assumptions.
    "gritsbot": RobotPreset(0.055, 0.25, 0.2, 1.0, "unicycle", 2 * 0.2 / 0.11, None),
}
"""Robot presets by name (``robot=NAME``); ``sphero`` is the study's and the default."""


def scaled_scenario(max_speed: float, robot_radius: float) -> dict[str, float]:
    """The scenario fields that scale with the robot (the study's case for another robot):
    the leader at :data:`LEADER_SPEED_RATIO` × the top speed, and the start grid's cells the
    study's free gap plus a diameter apart. The study's Sphero gets exactly 0.55 m/s and
    0.5 m."""
    return {"leader_speed": round(LEADER_SPEED_RATIO * max_speed, 9),
            "layout_spacing": round(STUDY_GAP + 2 * robot_radius, 9)}


# ------------------------------------------------------------------------ heading helpers
def rotation_terms(phi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(cos φ, sin φ) of small angles |φ| ≤ :data:`MAX_TURN_PER_SUBSTEP` as Taylor
    polynomials (error below 1e-17): elementwise products and sums only, so the same bits on
    every CPU."""
    p2 = phi * phi
    c = 1.0 - p2 / 2.0 * (1.0 - p2 / 12.0 * (1.0 - p2 / 30.0 * (1.0 - p2 / 56.0 * (
        1.0 - p2 / 90.0))))
    s = phi * (1.0 - p2 / 6.0 * (1.0 - p2 / 20.0 * (1.0 - p2 / 42.0 * (1.0 - p2 / 72.0 * (
        1.0 - p2 / 110.0)))))
    return c, s


def unit_vectors(angles: npt.ArrayLike) -> FloatArray:
    """(N, 2) unit vectors of ``angles`` (rad), with the C library's cos and sin per angle
    (once per episode, not in the step)."""
    return np.array([[math.cos(a), math.sin(a)] for a in np.asarray(angles, float).tolist()],
                    dtype=float).reshape(-1, 2)


def quaternions(heading_vectors: FloatArray) -> FloatArray:
    """(N, 2) quaternions (z, w) of rotations about z by each heading (N, 2): the half-angle
    formulas, elementwise (w ≥ 0)."""
    hx, hy = heading_vectors[:, 0], heading_vectors[:, 1]
    w = np.sqrt(np.maximum(0.5 * (1.0 + hx), 0.0))
    z = np.copysign(np.sqrt(np.maximum(0.5 * (1.0 - hx), 0.0)), hy)
    return np.stack([z, w], axis=1)


def quaternion_headings(z: FloatArray, w: FloatArray) -> FloatArray:
    """(N, 2) heading vectors (cos θ, sin θ) of quaternions about z: (w² − z², 2wz)."""
    return np.stack([w * w - z * z, 2.0 * w * z], axis=-1)


def odometry_headings(heading_vectors: FloatArray) -> FloatArray:
    """Headings (N, 2) as ROS odometry gives them back: through the quaternion."""
    q = quaternions(heading_vectors)
    return quaternion_headings(q[:, 0], q[:, 1])


def to_body(velocities: FloatArray, headings: FloatArray) -> FloatArray:
    """World-frame velocities (N, 2) in each robot's own frame (x forward, y left)."""
    vx, vy = velocities[:, 0], velocities[:, 1]
    hx, hy = headings[:, 0], headings[:, 1]
    return np.stack([vx * hx + vy * hy, vy * hx - vx * hy], axis=1)


def to_world(body: FloatArray, headings: FloatArray) -> FloatArray:
    """Body-frame velocities (N, 2) back in the world frame."""
    bx, by = body[:, 0], body[:, 1]
    hx, hy = headings[:, 0], headings[:, 1]
    return np.stack([bx * hx - by * hy, bx * hy + by * hx], axis=1)


def odometry_velocities(velocities: FloatArray, headings: FloatArray) -> FloatArray:
    """World-frame velocities (N, 2) as a controller reads them from odometry whose twist is
    in the robot's frame (REP 105): to the body frame and back, with ``headings`` from
    :func:`odometry_headings`."""
    return to_world(to_body(velocities, headings), headings)


def wrap_angles(angles: FloatArray) -> FloatArray:
    """Angles (rad) wrapped into [−π, π] (elementwise, no trigonometry)."""
    return angles - (2 * math.pi) * np.round(angles / (2 * math.pi))


# --------------------------------------------------------------------------------- models
class RobotModel:
    """A drive: its bodies, its driver's law and its motion over one control period.

    Everything that differs between drives is answered here (the world, the env, the
    observations, recordings and ROS ask the model or its class, never the drive's name):
    whether robots have a heading, the checks of its config fields, how a command becomes
    motion, and the heading state a snapshot or odometry reports. A new drive is a subclass
    registered in :data:`DRIVES` (:func:`register_drive`).

    Args:
        config: the world section of the env config.
    """

    name: ClassVar[str] = ""
    """The drive's name, the value of ``WorldConfig.drive`` that selects it."""
    has_heading: ClassVar[bool] = False
    """Whether robots of this model have a heading (observations, recordings, ROS)."""
    walks_with_people: ClassVar[bool] = True
    """Whether people (a person leader, a crowd) can share the space with these robots: a
    model that steers its control bodies within a control period cannot (a person's body
    does not take those steps)."""

    def __init__(self, config: WorldConfig) -> None:
        self.config = config

    @classmethod
    def check_config(cls, config: WorldConfig) -> None:
        """Refuses (``ValueError``, naming the fields) config values this drive cannot run
        with; called once when the config is built. None for a holonomic robot."""

    @classmethod
    def quarter_turn_time(cls, config: WorldConfig) -> float:
        """Seconds a robot of ``config`` needs to turn a quarter turn from rest; 0 for a
        robot that needs no turn to change its direction of motion."""
        return 0.0

    def command(self, world: World, commanded: FloatArray | None, executed: FloatArray | None,
                native: FloatArray | None) -> tuple[FloatArray, FloatArray | None, FloatArray]:
        """A control period's commands, before the world advances: the world-frame command
        (N, 2) as the world records it, the native commands as sent (None for a drive without
        them) and the native commands to execute (what :meth:`advance` takes).

        Args:
            world: the world about to advance.
            commanded: (N, 2) world-frame velocity commands as sent.
            executed: (N, 2) world-frame velocities executed instead (realism), or None.
            native: (N, 2) commands in the driver's own terms instead of ``commanded``.
        """
        sent = np.array(commanded, dtype=float)
        return sent, None, sent if executed is None else executed

    def initial_native(self, n: int) -> FloatArray | None:
        """The native commands before the first step (None for a drive without them)."""

    def odometry_headings(self) -> FloatArray | None:
        """(N, 2) unit heading vectors as odometry reports them; None without headings."""

    def headings(self) -> FloatArray | None:
        """(N,) headings (rad, in [−π, π]); None without headings."""

    def turn_rates(self) -> FloatArray | None:
        """(N,) turn rates (rad/s); None without headings."""

    def quaternions(self) -> FloatArray | None:
        """(N, 2) orientations as (z, w) of a rotation about z; None without headings."""

    def add_bodies(self, space: pymunk.Space, positions: FloatArray,
                   leader: tuple[float, float, float] | None = None
                   ) -> tuple[list[pymunk.Body], list[pymunk.Body]]:
        """Adds every robot (a disc) and its kinematic control body; returns both lists.
        ``leader``: (mass, radius, drive force) of robot 0 when it is not a robot (a
        person); an infinite drive force makes it a kinematic body that nothing pushes (a
        replayed walk)."""
        cfg = self.config
        robots: list[pymunk.Body] = []
        kinematic = leader is not None and math.isinf(leader[2])
        for k, p in enumerate(positions):
            mass, radius = (leader[0], leader[1]) if k == 0 and leader else (
                cfg.robot_mass, cfg.robot_radius)
            body = (pymunk.Body(body_type=pymunk.Body.KINEMATIC) if k == 0 and kinematic
                    else pymunk.Body(mass, float("inf")))
            body.position = (float(p[0]), float(p[1]))
            shape = pymunk.Circle(body, radius)
            shape.elasticity = 0.0
            shape.friction = 0.0
            space.add(body, shape)
            robots.append(body)
        controls: list[pymunk.Body] = []
        for k, robot in enumerate(robots):
            control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            control.position = robot.position
            if k == 0 and kinematic:  # moved by its velocity alone: no joint
                space.add(control)
                controls.append(control)
                continue
            joint = pymunk.PivotJoint(control, robot, (0, 0), (0, 0))
            joint.max_bias = 0.0  # velocity tracking only: no pull towards the control body
            joint.max_force = leader[2] if k == 0 and leader else cfg.drive_force
            space.add(control, joint)
            self._constrain(space, control, robot)
            controls.append(control)
        return robots, controls

    def _constrain(self, space: pymunk.Space, control: pymunk.Body, robot: pymunk.Body) -> None:
        """Further joints between a robot and its control body (none for a holonomic one)."""

    def reset(self, world: World, headings: FloatArray | None) -> None:
        """Sets the model's state for a new episode (initial headings, rad)."""

    def native(self, velocities: FloatArray, heading_vectors: FloatArray | None) -> FloatArray:
        """The driver's law: world-frame velocity commands (N, 2) -> native commands."""
        return velocities

    def advance(self, world: World, native: FloatArray) -> None:
        """Runs one control period of ``world`` with the native commands (N, 2)."""
        raise NotImplementedError


class Holonomic(RobotModel):
    """The study's omnidirectional disc: the native command is the world-frame velocity."""

    name = "holonomic"

    def advance(self, world: World, native: FloatArray) -> None:
        n = world.n
        w = world._write_velocities
        w[:n] = world.velocities  # unchanged: batch writes every body's velocity
        w[n : 2 * n] = native
        world._people_velocities(w)
        write = world._write_buffer()
        write.set_float_buf(w.reshape(-1))
        batch.set_space_bodies(world.space, batch.BodyFields.VELOCITY, write)
        world._run_substeps()


class Unicycle(RobotModel):
    """A robot that moves only along its heading, which turns at a bounded rate (module doc).

    Native command: (v, ω), forward speed (m/s, negative reverses) and turn rate (rad/s,
    counter-clockwise).
    """

    name = "unicycle"
    has_heading = True
    walks_with_people = False

    @classmethod
    def check_config(cls, config: WorldConfig) -> None:
        """A unicycle needs its top turn rate; a physics substep may turn it at most
        :data:`MAX_TURN_PER_SUBSTEP`; its heading gain may not overshoot within a period."""
        if config.max_turn_rate is None:
            raise ValueError("drive='unicycle' needs max_turn_rate (rad/s), e.g. 2.84 for a "
                             "TurtleBot3 Burger (or choose robot=...)")
        turn = config.max_turn_rate * config.dt / config.substeps
        if turn > MAX_TURN_PER_SUBSTEP:
            raise ValueError(
                f"a unicycle may turn at most {MAX_TURN_PER_SUBSTEP} rad per physics substep; "
                f"max_turn_rate={config.max_turn_rate:g} rad/s × dt={config.dt:g} s / "
                f"substeps={config.substeps} turns {turn:.3g} rad: use substeps >= "
                f"{math.ceil(config.max_turn_rate * config.dt / MAX_TURN_PER_SUBSTEP)}")
        gain = config.max_turn_rate if config.heading_gain is None else config.heading_gain
        if gain * config.dt > 1.0:
            raise ValueError(
                f"heading_gain × dt must be at most 1 (the heading would overshoot its command "
                f"within a control period), got {gain:g} 1/s × {config.dt:g} s")

    @classmethod
    def quarter_turn_time(cls, config: WorldConfig) -> float:
        """π/2 at the top turn rate plus the ramp to it at the turn acceleration."""
        if config.max_turn_rate is None:
            return 0.0
        rate = float(config.max_turn_rate)
        accel = config.max_turn_acceleration
        ramp = rate / float(accel) if accel else 0.0
        return (math.pi / 2) / rate + ramp

    def command(self, world: World, commanded: FloatArray | None, executed: FloatArray | None,
                native: FloatArray | None) -> tuple[FloatArray, FloatArray | None, FloatArray]:
        """The driver's law turns world-frame commands into (v, ω) (unless ``native`` gives
        them); the recorded world-frame command is v along the heading the robot had when
        commanded (what its ``cmd_vel`` says)."""
        heading = world.heading_vectors
        assert heading is not None
        sent = np.array(native, dtype=float) if native is not None else self.native(
            np.asarray(commanded, dtype=float), heading)
        run = sent if executed is None else self.native(np.asarray(executed, dtype=float),
                                                        heading)
        return heading * sent[:, :1], sent, run

    def initial_native(self, n: int) -> FloatArray | None:
        return np.zeros((n, 2))

    def odometry_headings(self) -> FloatArray | None:
        return odometry_headings(self.vectors)

    def headings(self) -> FloatArray | None:
        return wrap_angles(self.theta)

    def turn_rates(self) -> FloatArray | None:
        return self.omega.copy()

    def quaternions(self) -> FloatArray | None:
        return quaternions(self.vectors)

    def __init__(self, config: WorldConfig) -> None:
        super().__init__(config)
        assert config.max_turn_rate is not None
        self.max_turn_rate = float(config.max_turn_rate)
        self.gain = float(config.heading_gain if config.heading_gain is not None
                          else config.max_turn_rate)
        self.roll = config.velocity_law == "roll"
        accel = config.max_turn_acceleration
        self.max_turn_step = None if accel is None else float(accel) * config.dt
        self.theta = np.zeros(0)
        self.vectors = np.zeros((0, 2))
        self.omega = np.zeros(0)
        self._speed = np.zeros(0)
        self._turns: dict[float, tuple[FloatArray, FloatArray, FloatArray]] = {}
        self._buffer = np.zeros((0, 3))
        self._flat = self._buffer.reshape(-1)
        self._hx = self._hy = np.zeros(0)
        self._targets = self._robots_velocity = self._buffer

    def _constrain(self, space: pymunk.Space, control: pymunk.Body, robot: pymunk.Body) -> None:
        # No sideways slip: the robot's velocity across the control body's x axis (turned to
        # the heading before every substep) matches the control body's, which is zero.
        groove = pymunk.GrooveJoint(control, robot, (-GROOVE_LENGTH, 0.0),
                                    (GROOVE_LENGTH, 0.0), (0.0, 0.0))
        groove.max_bias = 0.0  # velocity only; the force is unlimited (wheels do not slip)
        space.add(groove)

    def reset(self, world: World, headings: FloatArray | None) -> None:
        n = world.n
        start = np.zeros(n) if headings is None else np.asarray(headings, dtype=float)
        self.theta = start.copy()
        self.vectors = unit_vectors(start)
        self.omega = np.zeros(n)
        self._speed = np.zeros(n)
        self._compiled = False  # set by advance: this step's substeps compiled or numpy
        self._buffer = np.zeros((2 * n + 1, 3))  # per body: angle, vx, vy (batch order)
        self._buffer[n : 2 * n, 0] = start
        self._flat = self._buffer.reshape(-1)  # a view: what pymunk reads each substep
        angles = np.ascontiguousarray(self._buffer[:, 0])  # robots and static body: 0
        write = world._write_buffer()
        write.set_float_buf(angles)
        batch.set_space_bodies(world.space, batch.BodyFields.ANGLE, write)

    def native(self, velocities: FloatArray, heading_vectors: FloatArray | None) -> FloatArray:
        """(v, ω) from world-frame velocities (N, 2) and headings (N, 2): the driver's law."""
        assert heading_vectors is not None
        ux, uy = velocities[:, 0], velocities[:, 1]
        hx, hy = heading_vectors[:, 0], heading_vectors[:, 1]
        along = ux * hx + uy * hy
        across = hx * uy - hy * ux
        speed = np.sqrt(ux * ux + uy * uy)
        moving = speed > 0.0
        sin_e = np.divide(across, speed, out=np.zeros_like(speed), where=moving)
        top = self.max_turn_rate
        turn = np.where(along >= 0.0, np.clip(self.gain * sin_e, -top, top),
                        np.where(across >= 0.0, top, -top))
        turn = np.where(moving, turn, 0.0)
        forward = speed if self.roll else np.maximum(along, 0.0)
        return np.stack([forward, turn], axis=1)

    def advance(self, world: World, native: FloatArray) -> None:
        self._speed = np.array(native[:, 0], dtype=float)
        wanted = np.asarray(native[:, 1], dtype=float)
        if self.max_turn_step is None:
            self.omega = wanted.copy()
        else:
            step = self.max_turn_step
            self.omega = self.omega + np.clip(wanted - self.omega, -step, step)
        # every distinct substep length at once: (H, N) arrays, the same elementwise bits
        lengths = sorted(set(world._schedule))
        phi = np.array(lengths)[:, None] * self.omega[None, :]
        cos, sin = rotation_terms(phi)
        self._turns = {h: (cos[k], sin[k], phi[k]) for k, h in enumerate(lengths)}
        self._hx, self._hy = self.vectors[:, 0].copy(), self.vectors[:, 1].copy()
        n = world.n
        self._targets = self._buffer[n : 2 * n]  # the control bodies' rows
        self._robots_velocity = self._buffer[:n, 1:]
        world._write_buffer().set_float_buf(self._flat)  # pymunk reads it every substep
        self._compiled = kernels.compiled() is not None  # one path for the step's substeps
        world._run_substeps(self._substep)
        # keep the heading a unit vector (each turn is exact only to rounding)
        norm = np.sqrt(self._hx * self._hx + self._hy * self._hy)
        self.vectors = np.stack([self._hx / norm, self._hy / norm], axis=1)

    def _substep(self, world: World, h: float) -> None:
        """Turns every heading by ω·h and points the control bodies (angle and velocity)
        along it, before pymunk integrates the substep."""
        c, s, turn = self._turns[h]
        read = world._read_buffer()
        read.clear()
        batch.get_space_bodies(world.space, _VELOCITY, read)
        velocities = np.frombuffer(read.float_buf(), dtype=np.float64)
        n = world.n
        compiled = kernels.loaded() if self._compiled else None
        if compiled is not None:  # the numpy below in one loop, the same bits
            compiled.unicycle_substep(self._buffer, n, self._hx, self._hy, c, s, turn,
                                      self.theta, velocities, self._speed)
        else:
            hx, hy = self._hx, self._hy
            turned = hx * c
            turned -= hy * s
            np.multiply(hx, s, out=hx)
            hx += hy * c
            hx, hy = turned, hx  # new (hx, hy)
            self._hx, self._hy = hx, hy
            theta = self.theta
            theta += turn
            # the robots' own velocities, written back as they are
            self._robots_velocity[...] = velocities[: 2 * n].reshape(n, 2)
            targets, speed = self._targets, self._speed  # turned, moving along the heading
            targets[:, 0] = theta
            np.multiply(hx, speed, out=targets[:, 1])
            np.multiply(hy, speed, out=targets[:, 2])
        batch.set_space_bodies(world.space, _ANGLE_VELOCITY, world._write_buffer())


_VELOCITY = batch.BodyFields.VELOCITY
_ANGLE_VELOCITY = batch.BodyFields.ANGLE | batch.BodyFields.VELOCITY


DRIVES: dict[str, type[RobotModel]] = {"holonomic": Holonomic, "unicycle": Unicycle}
"""Drives by name (``WorldConfig.drive``): ``holonomic`` (the study's omnidirectional disc)
and ``unicycle`` (moves along a heading that turns at a bounded rate)."""


def register_drive(model: type[RobotModel]) -> type[RobotModel]:
    """Adds a drive to :data:`DRIVES` under ``model.name`` (usable as a class decorator);
    ``ValueError`` for a name that is empty or taken by another class."""
    if not isinstance(model, type) or not issubclass(model, RobotModel):
        raise TypeError(f"a drive is a RobotModel subclass, got {model!r}")
    if not model.name or DRIVES.get(model.name, model) is not model:
        raise ValueError(f"a drive needs a new name (its class's ``name``), got {model.name!r}; "
                         f"taken: {sorted(DRIVES)}")
    DRIVES[model.name] = model
    return model


def drive_model(name: str) -> type[RobotModel]:
    """The model class of drive ``name``; ``ValueError`` naming the drives."""
    if not isinstance(name, str) or name not in DRIVES:
        raise ValueError(f"drive must be one of {tuple(DRIVES)}, got {name!r}")
    return DRIVES[name]


def make_model(config: WorldConfig) -> RobotModel:
    """The model of ``config.drive``."""
    return drive_model(config.drive)(config)
