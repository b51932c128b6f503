"""The pymunk world: round robots in a static scene (the study's walled square arena by
default; see :mod:`~boids_env.world.scene`). Knows nothing of RL.

Each robot is a dynamic disc (infinite moment) joined to a kinematic *control body* by a pivot
joint with ``max_bias = 0`` and ``max_force = drive_force``: the joint then only removes the
velocity difference between robot and control body, with a bounded force, so setting the
control body's velocity commands the robot's velocity the way a velocity-controlled robot
tracks ``cmd_vel``. How a command sets the control body is the robot model's
(:mod:`~boids_env.world.robots`: the study's holonomic Sphero, or a unicycle with a heading);
the world holds one and never asks which. Contacts are pymunk rigid contacts.

All body reads and writes go through :mod:`pymunk.batch` in one call per control step. Its
buffers list bodies in insertion order (robots, then control bodies) followed by the space's
static body; :class:`World` checks that order once when it is built.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt
import pymunk
import pymunk.batch as batch
from scipy.spatial import cKDTree

from boids_env.config.world import WorldConfig
from boids_env.metrics import CONTACT_TOLERANCE
from boids_env.world.invariants import PhysicsGuard
from boids_env.world.robots import make_model
from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]

PERSON_MASS = 70.0
"""Mass (kg) of a person's body (the leader person and every pedestrian): a 0.18 kg robot
pushing it with its 1 N drive moves it by micrometres."""
PERSON_DRIVE = 20_000.0
"""Largest force (N) with which a person's body holds the velocity the pedestrian model gives
it against robots (its body is given that velocity at each period's start): a robot pushing
with its 1 N drive does not move it."""
WALL_THICKNESS = 1.0
"""Radius (m) of the wall segments; their inner faces are at ±arena_half_size. Thick walls:
a robot would have to travel this far in one physics substep to pass through one (the config
caps a substep's travel at a robot radius)."""


class Stage(Protocol):
    """Who of the crowd is on stage when (a replayed crowd,
    :class:`~boids_env.world.crowd_replay.ReplayedCrowd`)."""

    def places(self, t: float) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """The pedestrians coming on or going off stage in the period from ``t`` (s), and
        where to put them before it."""
        ...

    def present(self, t: float) -> npt.NDArray[np.bool_]:
        """(P,) whether each pedestrian is on stage at ``t`` (s)."""
        ...


@dataclass(frozen=True)
class Snapshot:
    """The world at one instant as plain arrays, robot 0 (the leader) first."""

    time: float
    """Seconds since reset."""
    positions: FloatArray
    """(N, 2) positions (m)."""
    velocities: FloatArray
    """(N, 2) measured velocities (m/s)."""
    commanded: FloatArray
    """(N, 2) velocities commanded for the last step (m/s)."""
    contacts: npt.NDArray[np.int64]
    """(M, 2) index pairs i < j of robots touching each other."""
    wall_contacts: npt.NDArray[np.int64]
    """(W,) indices of robots touching a wall or an obstacle (static geometry)."""
    headings: FloatArray | None = None
    """(N,) headings (rad, in [−π, π], counter-clockwise from +x) of robots that have one
    (``drive="unicycle"``); None for the study's holonomic robots."""
    angular_velocities: FloatArray | None = None
    """(N,) turn rates (rad/s) of robots with a heading; None otherwise."""
    native: FloatArray | None = None
    """(N, 2) the last step's commands as the robots' drivers take them, (v, ω) for robots
    with a heading (what ``cmd_vel`` carries); None otherwise."""
    quaternions: FloatArray | None = None
    """(N, 2) orientations of robots with a heading as (z, w) of a rotation about z, exactly
    what their odometry carries (:func:`~boids_env.world.robots.quaternions`); None
    otherwise."""


_C_STEP = getattr(getattr(pymunk, "_chipmunk", None), "lib", None)
_C_STEP = getattr(_C_STEP, "cpSpaceStep", None)

_BUFFERS = threading.local()


def _buffers() -> tuple[batch.Buffer, batch.Buffer]:
    """This thread's (read, write) pymunk.batch buffers. pymunk never frees a Buffer's C
    arrays, so one World per reset with buffers of its own leaked ~2 kB a reset; every World
    of a thread shares these (a World uses them only inside its own calls)."""
    if not hasattr(_BUFFERS, "pair"):
        _BUFFERS.pair = (batch.Buffer(), batch.Buffer())
    return _BUFFERS.pair


class World:
    """A fresh pymunk space with the static scene and ``len(positions)`` robots at rest.

    Args:
        config: the physical world's section of the env config.
        positions: (N, 2) initial robot positions (m), the leader first.
        scene: the static geometry (None: the scene ``config.scene`` names).
        headings: (N,) initial headings (rad) of robots with a heading (None: +x).
        leader_radius: a person leads (None: a robot): robot 0 is then a disc of this
            radius (m) and :data:`PERSON_MASS` tracking its commanded velocity with up to
            :data:`PERSON_DRIVE`; robots collide with it rigidly and cannot push it.
        leader_kinematic: the person's body is kinematic (a replayed walk among a crowd): it
            moves by its commanded velocity exactly, and pedestrians and robots it meets are
            pushed, never it.
        pedestrians: (P, 2) initial positions of the crowd (m): discs like the person's, of
            ``pedestrian_radius``, tracking :meth:`step`'s ``pedestrian_velocities``.
        pedestrian_radius: the pedestrians' radius (m).
        people_speed: the fastest a person (the leader or a pedestrian) walks (m/s): the
            guard's limit for people, and for robots where people push them.
        stage: a replayed crowd (:class:`~boids_env.world.crowd_replay.ReplayedCrowd`):
            before each period the world puts the pedestrians coming on or going off stage
            where it says, and the guard checks only those on stage.

    People walk among holonomic robots only (the robot models with a heading steer their
    control bodies within a period, which a person's or a pedestrian's body does not take).
    """

    def __init__(self, config: WorldConfig, positions: npt.ArrayLike,
                 scene: Scene | None = None, headings: npt.ArrayLike | None = None, *,
                 leader_radius: float | None = None, pedestrians: npt.ArrayLike | None = None,
                 pedestrian_radius: float = 0.22, leader_kinematic: bool = False,
                 people_speed: float = 0.0, stage: Stage | None = None) -> None:
        self.config = config
        self._stage = stage
        if scene is None:
            from boids_env.world.scenes import load_scene

            scene = load_scene(config.scene, config.arena_half_size)
        self.scene = scene
        start = np.asarray(positions, dtype=float)
        self.n = len(start)
        self.steps = 0
        self.space = pymunk.Space()
        self.space.collision_slop = config.collision_slop
        self.space.iterations = 10
        # Overlaps are removed in full in the substep after they form (chipmunk's bias moves
        # bodies apart without adding velocity), and the last substep of a control period is
        # split in two, so an overlap formed just before a sample is at most half a substep's
        # travel deep: ≤ 5 mm at full speed (1 m/s closing) where the uniform schedule gave
        # up to 7 mm. Costs one chipmunk step more per control period.
        self.space.collision_bias = 0.0
        h = config.dt / config.substeps
        self._schedule = [h] * (config.substeps - 1) + [h / 2, h / 2]
        self._add_scene()
        self.model = make_model(config)
        self.person_leader = person = leader_radius is not None
        crowd = np.zeros((0, 2)) if pedestrians is None else np.asarray(pedestrians, float)
        crowd = crowd.reshape(-1, 2)
        self.p = len(crowd)
        if (person or self.p) and not self.model.walks_with_people:
            raise ValueError(f"a person leader and crowds walk among holonomic robots only "
                             f"(drive={config.drive!r} steers within a control period); use "
                             f"robot='sphero' (or another holonomic robot) with people")
        drive = math.inf if leader_kinematic else PERSON_DRIVE
        leader = (PERSON_MASS, leader_radius, drive) if leader_radius is not None else None
        self._robots, self._controls = self.model.add_bodies(self.space, start, leader)
        self.pedestrian_radius = pedestrian_radius
        walkers = [self._add_disc(q, PERSON_MASS, pedestrian_radius) for q in crowd]
        self._pedestrians = walkers + [self._add_control(b, PERSON_DRIVE) for b in walkers]
        self._fields = batch.BodyFields.POSITION | batch.BodyFields.VELOCITY
        self._check_body_order()
        # One velocity per body in batch order; written in place and handed to pymunk each step.
        self._write_velocities = np.zeros((2 * self.n + 2 * self.p + 1, 2))
        self._pedestrian_walk: FloatArray | float = 0.0
        self.commanded = np.zeros((self.n, 2))
        self.native: FloatArray | None = self.model.initial_native(self.n)
        self.positions = start.copy()
        self.velocities = np.zeros((self.n, 2))
        self.pedestrian_positions = crowd.copy()
        self.pedestrian_velocities = np.zeros((self.p, 2))
        self.model.reset(self, None if headings is None else np.asarray(headings, float))
        self._refresh()
        self.guard: PhysicsGuard | None = None
        """Checks every step for bodies in walls or too fast, in a world with people (what
        can push a robot harder than its drive): :mod:`~boids_env.world.invariants`."""
        if person or self.p:
            self.guard = PhysicsGuard(scene, config.robot_radius, pedestrian_radius,
                                      max(config.max_speed, people_speed), people_speed)

    def _add_disc(self, position: FloatArray, mass: float, radius: float) -> pymunk.Body:
        """A rigid, frictionless disc of ``mass`` with infinite moment (a person does not
        spin) at ``position``."""
        body = pymunk.Body(mass, float("inf"))
        body.position = (float(position[0]), float(position[1]))
        shape = pymunk.Circle(body, radius)
        shape.elasticity = 0.0
        shape.friction = 0.0
        self.space.add(body, shape)
        return body

    def _add_control(self, body: pymunk.Body, drive: float) -> pymunk.Body:
        """The kinematic control body whose velocity ``body`` tracks with at most ``drive``
        (N)."""
        control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        control.position = body.position
        joint = pymunk.PivotJoint(control, body, (0, 0), (0, 0))
        joint.max_bias = 0.0  # velocity tracking only: no pull towards the control body
        joint.max_force = drive
        self.space.add(control, joint)
        return control

    def _add_scene(self) -> None:
        """Static shapes: the box's walls as thick segments whose inner faces are the box
        (as the study's arena always had them), capsules as segments or discs, convex blocks
        as polygons; rigid, frictionless, inelastic like the robots."""
        scene, static = self.scene, self.space.static_body
        shapes: list[pymunk.Shape] = []
        if scene.box is not None:
            x0, y0, x1, y1 = scene.box
            t = WALL_THICKNESS
            # (-h) - t == -(h + t) exactly: the arena's walls are the study-era ones
            corners = [(x0 - t, y0 - t), (x1 + t, y0 - t), (x1 + t, y1 + t), (x0 - t, y1 + t)]
            for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
                shapes.append(pymunk.Segment(static, a, b, t))
        for a, b, r in zip(scene.a.tolist(), scene.b.tolist(), scene.radius.tolist(),
                           strict=True):
            if a == b:
                shapes.append(pymunk.Circle(static, r, tuple(a)))
            else:
                shapes.append(pymunk.Segment(static, tuple(a), tuple(b), r))
        for poly in scene.polygons:
            shapes.append(pymunk.Poly(static, [tuple(p) for p in poly.tolist()]))
        for shape in shapes:
            shape.elasticity = 0.0
            shape.friction = 0.0
        self.space.add(*shapes)

    def _check_body_order(self) -> None:
        buf = _buffers()[0]
        buf.clear()
        batch.get_space_bodies(self.space, batch.BodyFields.BODY_ID, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.uintp)
        bodies = self._robots + self._controls + self._pedestrians
        expected = [b.id for b in bodies] + [self.space.static_body.id]
        if list(ids) != expected:  # pragma: no cover - guards against a pymunk change
            raise RuntimeError("pymunk.batch body order changed; World cannot batch its I/O")

    def _refresh(self) -> None:
        read = _buffers()[0]
        read.clear()
        batch.get_space_bodies(self.space, self._fields, read)
        data = np.frombuffer(read.float_buf(), dtype=np.float64).reshape(-1, 4)
        self.positions = data[: self.n, :2].copy()
        self.velocities = data[: self.n, 2:].copy()
        if self.p:
            crowd = data[2 * self.n : 2 * self.n + self.p]  # then their control bodies
            self.pedestrian_positions = crowd[:, :2].copy()
            self.pedestrian_velocities = crowd[:, 2:].copy()
        self._heading_vectors = self.model.odometry_headings()

    def step(self, commanded: FloatArray | None, executed: FloatArray | None = None,
             pedestrian_velocities: FloatArray | None = None, *,
             native: FloatArray | None = None) -> None:
        """Commands every robot and advances one control period.

        Args:
            commanded: (N, 2) world-frame velocity commands as sent. A robot with a heading
                turns them into (v, ω) with its driver's law.
            executed: (N, 2) world-frame velocities the robots execute instead (realism:
                noise, stall, latency) while :attr:`commanded` keeps the command as sent.
            native: (N, 2) commands in the drivers' own terms, (v, ω), for robots with a
                heading, in place of ``commanded`` (``action="unicycle"``).
            pedestrian_velocities: (P, 2) the crowd's velocities (zero when not given).

        :attr:`commanded` records the world-frame command (the metrics' alignment rule reads
        it): as sent for the holonomic robots; for robots with a heading, what their
        ``cmd_vel`` says: v along the heading they had when commanded.
        """
        self._pedestrian_walk = 0.0 if pedestrian_velocities is None else pedestrian_velocities
        self.commanded, sent, run = self.model.command(self, commanded, executed, native)
        if sent is not None:
            self.native = sent
        if self._stage is not None:
            self._place_pedestrians(*self._stage.places(self.time))
        self.model.advance(self, run)
        self.steps += 1
        self._refresh()
        if self.guard is not None:
            people = self.pedestrian_positions
            moving = self.pedestrian_velocities
            if self._stage is not None:
                shown = self._stage.present(self.time)
                people, moving = people[shown], moving[shown]
            if self.person_leader:  # robot 0 is a person's body
                people = np.concatenate([self.positions[:1], people])
                moving = np.concatenate([self.velocities[:1], moving])
            first = 1 if self.person_leader else 0
            self.guard.check(self.steps, self.positions[first:], self.velocities[first:],
                             people, moving)

    def _place_pedestrians(self, index: npt.NDArray[np.int64], points: FloatArray) -> None:
        """Puts pedestrians ``index`` (and their control bodies) at ``points`` (K, 2) at
        rest: a replayed pedestrian coming on or going off stage (a few a period at most)."""
        for k, (x, y) in zip(index.tolist(), points.tolist(), strict=True):
            for body in (self._pedestrians[k], self._pedestrians[self.p + k]):
                body.position = (x, y)
                body.velocity = (0.0, 0.0)

    def _people_velocities(self, w: FloatArray) -> None:
        """Writes the people's rows of the velocity buffer ``w`` (after the robots'): a person
        leader and the crowd walk as told from the period's first substep (chipmunk moves a
        body by its velocity before its joints act, so a drive lags a substep): body and
        control body both get the velocity, the drive then only holds it against robots."""
        if self.person_leader:
            w[0] = w[self.n] = self.commanded[0]  # and no robot realism for a person
        if self.p:
            n2, p = 2 * self.n, self.p
            w[n2 : n2 + p] = self._pedestrian_walk
            w[n2 + p : n2 + 2 * p] = self._pedestrian_walk

    def _read_buffer(self) -> batch.Buffer:
        return _buffers()[0]

    def _write_buffer(self) -> batch.Buffer:
        return _buffers()[1]

    def _run_substeps(self, before: Callable[[World, float], None] | None = None) -> None:
        """Runs the control period's physics substeps, calling ``before(world, h)`` ahead of
        each (a robot model that steers within the period)."""
        if self.steps == 0 or _C_STEP is None:
            for h in self._schedule:
                if before is not None:
                    before(self, h)
                self.space.step(h)  # the first call also runs pymunk's body checks
        else:
            # Space.step's Python wrapper only handles callbacks and deferred adds/removes,
            # which this world never uses; calling chipmunk directly saves ~2 us a substep.
            handle = self.space._space
            for h in self._schedule:
                if before is not None:
                    before(self, h)
                _C_STEP(handle, h)

    @property
    def heading_vectors(self) -> FloatArray | None:
        """(N, 2) unit heading vectors as odometry reports them (through the quaternion a
        ROS odometry message carries; :func:`~boids_env.world.robots.odometry_headings`);
        None for robots without a heading."""
        return self._heading_vectors

    @property
    def headings(self) -> FloatArray | None:
        """(N,) headings (rad, in [−π, π]); None for robots without a heading."""
        return self.model.headings()

    @property
    def angular_velocities(self) -> FloatArray | None:
        """(N,) turn rates (rad/s); None for robots without a heading."""
        return self.model.turn_rates()

    @property
    def time(self) -> float:
        """Seconds since the world was built (steps × dt, no accumulated rounding)."""
        return self.steps * self.config.dt

    def contacts(self) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """Robot pairs (i < j) touching each other, and robots touching static geometry."""
        r = self.config.robot_radius
        pairs = cKDTree(self.positions).query_pairs(2 * r + CONTACT_TOLERANCE,
                                                    output_type="ndarray")
        walls = np.flatnonzero(self.scene.within(self.positions, r, CONTACT_TOLERANCE))
        return pairs.astype(np.int64).reshape(-1, 2), walls.astype(np.int64)

    def snapshot(self) -> Snapshot:
        """Copies of the current arrays and the contacts."""
        pairs, walls = self.contacts()
        return Snapshot(self.time, self.positions.copy(), self.velocities.copy(),
                        self.commanded.copy(), pairs, walls, self.headings,
                        self.angular_velocities,
                        None if self.native is None else self.native.copy(),
                        self.model.quaternions())
