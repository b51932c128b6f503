"""People in the world: the walkable area of a scene and the pedestrian model that walks the
person (the leader, ``leader="person"``) and the crowd (``crowd=N``) through it.

The pedestrian dynamics are JuPedSim's (the ``people`` extra): its anticipation velocity
model (collision-free, velocity-based, with a reaction time that smooths turns and an
anticipation of the others' motion) steps at :data:`PEDESTRIAN_DT` inside each control period.
The person walks to its path's corners in turn at a preferred speed that varies slowly
(a seeded Ornstein–Uhlenbeck factor around 1) and stops for a seeded while at each corner;
pedestrians walk to random goals in the walkable area, a new one on arrival. The pedestrians
see the robots as people see a robot on the floor: each period every robot is a standing agent
of the simulation on its disc (:meth:`People.advance`'s ``robots``), put in anew every period,
so they walk around robots instead of through them; the person leading does not (it leads;
the robots keep out of its way). The world moves the people's bodies at the velocity that
takes them to the simulation's positions, never faster than they walk, and robots collide
with them rigidly. A replayed walk (``leader="trajectory"``) among a crowd is a standing
agent the same way, so the pedestrians walk around it.

Deterministic: JuPedSim's model is seeded from the episode's stream and every draw here
comes from one ``np.random.Generator``; the same seed gives the same walk bit for bit (JuPedSim
iterates its agents in the order they were added). A pickled :class:`People` rebuilds its
simulation and replays its periods.
"""

from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]

PEDESTRIAN_DT = 0.01
"""JuPedSim's iteration step (s), the library's recommended one; a control period of 0.1 s is
ten iterations."""
GAIT_TIME = 2.0
"""Correlation time (s) of the person's speed factor (how long a faster or slower spell
lasts)."""
GAIT_RANGE = (0.5, 1.5)
"""The speed factor is kept within these bounds (× the preferred speed)."""
GOAL_REACHED = 0.3
"""A person or pedestrian within this distance (m) of its goal has reached it."""
ROBOT_ROOM = 0.05
"""People keep their bodies this much (m) farther from each other and from walls than their
own model asks (JuPedSim walks discs of radius + ROBOT_ROOM): two people never close a gap a
robot (0.072 m across) could not leave, so a robot is never crushed between them."""
WALL_BUFFER = 0.1
"""Distance (m) people keep from walls and obstacles beyond their radius (JuPedSim's
``wall_buffer_distance``): a robot (0.072 m across) still fits between a person and a wall."""
CROWD_SPEED_SPREAD = (0.8, 1.2)
"""Each pedestrian's preferred speed is ``crowd_speed`` × a uniform draw in these bounds."""
CROWD_CLEARANCE = 1.0
"""Pedestrians start at least this far (m) from every robot and from each other's bodies."""
STUCK_TIME = 3.0
"""A pedestrian that moved less than :data:`STUCK_DISTANCE` in this long (s) gives way: it
picks a new goal near where it stands (velocity models jam in counterflow at a door)."""
STUCK_DISTANCE = 0.2
"""See :data:`STUCK_TIME` (m)."""
GIVE_WAY_RADIUS = 3.0
"""A pedestrian giving way picks its new goal within this distance (m)."""
WALKER_ROOM = 1e-3
"""Gap (m) a replayed person's disc in JuPedSim leaves to the nearest pedestrian's (JuPedSim
refuses an agent overlapping another)."""
MIN_WALKER_RADIUS = 0.05
"""Smallest disc (m) of a replayed person put into JuPedSim; a pedestrian nearer than this
leaves none that period."""
MIN_ROBOT_RADIUS = 0.01
"""Smallest disc (m) of a robot put into JuPedSim; a pedestrian nearer than this leaves none
that period."""
PLACEMENT_TRIES = 2_000
"""Random start or goal draws tried before giving up."""


class _Args(TypedDict):
    """:class:`People`'s arguments as kept (and pickled) to rebuild its simulation."""

    scene: Scene
    dt: float
    person: tuple[float, float] | None
    goals: FloatArray
    speed: float
    gait_variation: float
    goal_pause: float
    startup_time: float
    crowd: int
    crowd_speed: float
    radius: float
    keep_clear: FloatArray
    walk: tuple[FloatArray, FloatArray] | None


def _require_jupedsim() -> Any:
    from boids_env.extras import require

    require("people", purpose="leader='person' (walking its path) and crowd > 0")
    import jupedsim

    return jupedsim


def check_crowd_fits(scene: Scene, crowd: int, radius: float) -> None:
    """Refuses (``ValueError`` naming ``crowd``) a crowd that no placement can fit: its
    pedestrians start at random points of the walkable area (less the walls' buffer) at least
    a clearance apart, and discs dropped at random never cover more than about 54.7 % of a
    floor (random sequential adsorption's jamming limit), so a crowd whose discs would
    cover more is refused when the config is built, not at reset."""
    inner = walkable_area(scene).buffer(-(radius + ROBOT_ROOM + WALL_BUFFER + 0.05))
    clearance = max(CROWD_CLEARANCE, 2 * (radius + ROBOT_ROOM))
    disc = math.pi * (clearance / 2) ** 2
    if crowd * disc > JAMMING * inner.area:
        most = int(JAMMING * inner.area // disc)
        raise ValueError(f"crowd must be at most {most} in scene {scene.name!r} (got {crowd}): "
                         f"{crowd} pedestrians {clearance:.2f} m apart (person_radius "
                         f"{radius:g} m) cannot be placed at random on its {inner.area:.1f} m² "
                         f"of floor where pedestrians start")


JAMMING = 0.547
"""The densest cover random placement of equal discs reaches (random sequential
adsorption's jamming limit in the plane)."""


def walkable_area(scene: Scene) -> Any:
    """The scene's free floor as a shapely polygon (with holes): the box (or the scene's
    bounds) less every capsule (buffered by its radius, polygons circumscribing the round
    ends) and convex block; for a map, its free cells. The part containing most area is kept
    when obstacles cut the floor in pieces. Built once per scene object (a frozen value;
    shapely's geometries are immutable): the config's crowd check and every reset share it."""
    area = _AREAS.get(scene)
    if area is None:
        area = _AREAS[scene] = _walkable_area(scene)
    return area


_AREAS: weakref.WeakKeyDictionary[Scene, Any] = weakref.WeakKeyDictionary()
""":func:`walkable_area` by scene (gone with the scene)."""


def _walkable_area(scene: Scene) -> Any:
    import shapely
    from shapely.geometry import LineString, Point, Polygon, box

    sides = 16  # a buffered circle is a polygon inscribed in it: grow it to circumscribe
    grow = 1.0 / math.cos(math.pi / (4 * sides))
    if scene.grid is not None:
        floor = _free_cells(scene)
    else:
        floor = box(*scene.bounds)
    solids = []
    for a, b, r in zip(scene.a.tolist(), scene.b.tolist(), scene.radius.tolist(), strict=True):
        shape = Point(a) if a == b else LineString([a, b])
        solids.append(shape.buffer(max(r, 1e-6) * grow, quad_segs=sides))
    solids += [Polygon(p) for p in scene.polygons]
    if solids:
        floor = floor.difference(shapely.union_all(solids))
    if floor.geom_type != "Polygon":
        floor = max(getattr(floor, "geoms", [floor]), key=lambda g: g.area)
    return floor


def _free_cells(scene: Scene) -> Any:
    """A map's free cells as one geometry: each row's runs of free cells as rectangles,
    united."""
    import shapely
    from shapely import affinity
    from shapely.geometry import box

    grid = scene.grid
    assert grid is not None
    free = grid.cells == 0
    rects = []
    for row in range(free.shape[0]):
        line = np.concatenate([[False], free[row], [False]]).astype(np.int8)
        edges = np.flatnonzero(np.diff(line))
        for start, end in zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True):
            rects.append(box(start, row, end, row + 1))
    cells = shapely.union_all(rects)
    x0, y0, yaw = grid.origin
    cells = affinity.scale(cells, grid.resolution, grid.resolution, origin=(0, 0))
    cells = affinity.rotate(cells, yaw, origin=(0, 0), use_radians=True)
    return affinity.translate(cells, x0, y0)


class People:
    """The person and the crowd walking in one JuPedSim simulation.

    Args:
        scene: the static scene they walk in.
        dt: the control period (s); :meth:`advance` moves everyone by one.
        rng: the episode's generator: seeds JuPedSim, draws the gait, pauses, crowd starts and
            goals.
        person: the person's start (m), or None (no person walks here).
        goals: (G, 2) the person's goals in order (m).
        speed: the person's preferred walking speed (m/s).
        gait_variation: standard deviation of the person's speed factor (relative).
        goal_pause: mean time (s) the person stops at each goal but the last.
        startup_time: the person stands still until then (s).
        crowd: number of pedestrians.
        crowd_speed: the pedestrians' preferred speed (m/s), each drawn within ±20 %.
        radius: body radius (m) of the person and the pedestrians.
        keep_clear: (M, 2) points pedestrians do not start near (the robots' start).
        walk: a replayed person's walk (times (M,) s, points (M, 2) m), or None: the crowd
            gives way to it (see :meth:`_place_walker`).
    """

    def __init__(self, scene: Scene, dt: float, rng: np.random.Generator, *,
                 person: tuple[float, float] | None, goals: FloatArray, speed: float,
                 gait_variation: float, goal_pause: float, startup_time: float, crowd: int,
                 crowd_speed: float, radius: float, keep_clear: FloatArray,
                 walk: tuple[FloatArray, FloatArray] | None = None) -> None:
        self._args: _Args = dict(scene=scene, dt=dt, person=person, goals=np.asarray(goals, float),
                          speed=speed, gait_variation=gait_variation, goal_pause=goal_pause,
                          startup_time=startup_time, crowd=crowd, crowd_speed=crowd_speed,
                          radius=radius, keep_clear=np.asarray(keep_clear, float), walk=walk)
        self._rng_state = rng.bit_generator.state
        self._build(rng)

    def _build(self, rng: np.random.Generator) -> None:
        jps = _require_jupedsim()
        a = self._args
        self.dt = float(a["dt"])
        self.radius = float(a["radius"])
        self.area = walkable_area(a["scene"])
        self._rng = rng
        self._iterations = max(1, round(self.dt / PEDESTRIAN_DT))
        self._sim = jps.Simulation(
            model=jps.AnticipationVelocityModel(rng_seed=int(rng.integers(2**63))),
            geometry=self.area, dt=self.dt / self._iterations)
        stage = self._sim.add_direct_steering_stage()
        journey = self._sim.add_journey(jps.JourneyDescription([stage]))

        def add(position: FloatArray, desired: float, radius: float | None = None) -> int:
            params = jps.AnticipationVelocityModelAgentParameters(
                position=(float(position[0]), float(position[1])), journey_id=journey,
                stage_id=stage, desired_speed=desired,
                radius=self.radius + ROBOT_ROOM if radius is None else radius,
                wall_buffer_distance=WALL_BUFFER)
            return int(self._sim.add_agent(params))

        self.has_person = a["person"] is not None
        self.goals = a["goals"].reshape(-1, 2)
        self.goal_index = 0
        self.finished = not self.has_person or not len(self.goals)
        self._ids: list[int] = []
        if self.has_person:
            self._ids.append(add(np.asarray(a["person"], float), 0.0))
            if not self.finished:
                self._agent(0).target = tuple(self.goals[0].tolist())
        self._gait = 1.0
        self._pause_until = 0.0
        self.speeds = np.zeros(0)
        if a["crowd"]:
            starts = self._crowd_starts(a["crowd"], a["keep_clear"])
            self.speeds = a["crowd_speed"] * rng.uniform(*CROWD_SPEED_SPREAD, a["crowd"])
            for p, v in zip(starts, self.speeds.tolist(), strict=True):
                self._ids.append(add(p, v))
                self._agent(len(self._ids) - 1).target = tuple(self._free_point().tolist())
        self._walker: int | None = None  # JuPedSim's id of the replayed person's disc
        self._robot_discs: list[int] = []  # JuPedSim's ids of this period's robot discs
        self._robot_log: list[FloatArray | None] = []  # the robots each period saw (replay)
        self._robot_radius = 0.0
        self._add = add
        self.steps = 0
        self.positions = self._read()
        self.start_pedestrians = self.pedestrians.copy()
        self._stuck_steps = max(1, round(STUCK_TIME / self.dt))
        self._past: list[FloatArray] = []

    def _agent(self, k: int) -> Any:
        return self._sim.agent(self._ids[k])

    def _read(self) -> FloatArray:
        return np.array([self._agent(k).position for k in range(len(self._ids))],
                        dtype=float).reshape(-1, 2)

    def _free_point(self, away: FloatArray | None = None, clear: float = 0.0) -> FloatArray:
        """A random point of the walkable area at least radius + wall buffer from its walls
        and ``clear`` from every point of ``away``."""
        from shapely import contains_xy

        inner = self._inner()
        x0, y0, x1, y1 = inner.bounds
        for _ in range(PLACEMENT_TRIES):
            p = self._rng.uniform((x0, y0), (x1, y1))
            if not contains_xy(inner, p[0], p[1]):
                continue
            if away is not None and len(away):
                gap = np.hypot(away[:, 0] - p[0], away[:, 1] - p[1])
                # clear > 0: at least that far from every point; < 0: within -clear of them
                if (gap.min() < clear) if clear >= 0 else (gap.max() > -clear):
                    continue
            return p
        raise ValueError(f"crowd: no free place for a pedestrian in scene "
                         f"{self._args['scene'].name!r} in {PLACEMENT_TRIES} draws; use a "
                         f"smaller crowd")

    def _inner(self) -> Any:
        if not hasattr(self, "_inner_area"):
            self._inner_area = self.area.buffer(-(self.radius + ROBOT_ROOM + WALL_BUFFER + 0.05))
        return self._inner_area

    def _crowd_starts(self, count: int, keep_clear: FloatArray) -> list[FloatArray]:
        taken = [keep_clear.reshape(-1, 2)]
        if self.has_person:
            taken.append(np.asarray(self._args["person"], float).reshape(1, 2))
        starts = []
        # centres at least two pedestrian bodies apart too (as JuPedSim demands of its agents)
        clearance = max(CROWD_CLEARANCE, 2 * (self.radius + ROBOT_ROOM) + 1e-6)
        for _ in range(count):
            p = self._free_point(np.concatenate(taken), clearance)
            starts.append(p)
            taken.append(p.reshape(1, 2))
        return starts

    # ------------------------------------------------------------------------ stepping
    def advance(self, t: float, robots: FloatArray | None = None,
                robot_radius: float = 0.0) -> FloatArray:
        """Moves everyone by one control period starting at time ``t`` (s); returns the new
        positions (K, 2), the person first when there is one. ``robots`` (R, 2): where the
        robots are (m), discs of ``robot_radius`` the crowd walks around this period (None:
        the crowd sees none)."""
        a = self._args
        self._robot_log.append(None if robots is None else np.array(robots, dtype=float))
        self._robot_radius = robot_radius
        if self._walker is not None:
            self._sim.mark_agent_for_removal(self._walker)
        for disc in self._robot_discs:
            self._sim.mark_agent_for_removal(disc)
        self._robot_discs = []
        if self.has_person:
            self._steer_person(t, a)
        for k in range(self._iterations):
            self._sim.iterate()
            if k == 0:  # the last period's discs are gone now
                if a["walk"] is not None:
                    self._place_walker(t)
                if robots is not None and a["crowd"]:
                    self._place_robots(np.asarray(robots, dtype=float), robot_radius)
        self.steps += 1
        agents = [self._sim.agent(i) for i in self._ids]  # looked up once for both uses
        self.positions = np.array([agent.position for agent in agents],
                                  dtype=float).reshape(-1, 2)
        self._retarget_crowd(agents)
        return self.positions

    def _steer_person(self, t: float, a: _Args) -> None:
        """Sets the person's desired speed for this period (zero before start-up, while
        pausing and once done) and moves its goal on when reached."""
        person = self._agent(0)
        if not self.finished:
            here = self.positions[0]
            goal = self.goals[self.goal_index]
            if math.hypot(here[0] - goal[0], here[1] - goal[1]) < GOAL_REACHED:
                self.goal_index += 1
                if self.goal_index == len(self.goals):
                    self.finished = True
                else:
                    person.target = tuple(self.goals[self.goal_index].tolist())
                    self._pause_until = t + float(self._rng.uniform(0.0, 2 * a["goal_pause"]))
        # the speed factor: an Ornstein-Uhlenbeck process, stationary std = gait_variation
        theta = self.dt / GAIT_TIME
        noise = float(self._rng.standard_normal())
        self._gait += theta * (1.0 - self._gait) + a["gait_variation"] * math.sqrt(
            2 * theta) * noise
        self._gait = min(max(self._gait, GAIT_RANGE[0]), GAIT_RANGE[1])
        walking = (t >= a["startup_time"] - 1e-9 and t >= self._pause_until - 1e-9
                   and not self.finished)
        person.model.desired_speed = a["speed"] * self._gait if walking else 0.0

    def _place_walker(self, t: float) -> None:
        """Puts the replayed person into JuPedSim for the period from ``t`` (s): a standing
        agent on the disc the person's body sweeps in it (centred between its positions at
        ``t`` and ``t + dt``, the person's radius + :data:`ROBOT_ROOM` + half the step), so
        the pedestrians steer around it as around anyone; its disc of the last period is
        marked for removal (JuPedSim removes it in its next iteration). JuPedSim refuses an
        agent overlapping another: the disc shrinks to the room the pedestrians leave (none, or
        a refusal: no disc this period; the person's kinematic body still pushes them
        aside)."""
        walk = self._args["walk"]
        assert walk is not None, "_place_walker needs a walk"  # its one caller checks
        times, points = walk
        here = np.array([np.interp(t, times, points[:, 0]), np.interp(t, times, points[:, 1])])
        t1 = t + self.dt
        there = np.array([np.interp(t1, times, points[:, 0]),
                          np.interp(t1, times, points[:, 1])])
        centre = (here + there) / 2
        body = self.radius + ROBOT_ROOM
        radius = body + math.hypot(*(there - here)) / 2
        if self._ids:
            now = self._read()  # where JuPedSim has them now
            gaps = np.hypot(now[:, 0] - centre[0], now[:, 1] - centre[1])
            radius = min(radius, float(gaps.min()) - body - WALKER_ROOM)
        self._walker = None
        if radius >= MIN_WALKER_RADIUS:
            try:
                self._walker = self._add(centre, 0.0, radius)
            except RuntimeError:  # JuPedSim found two of its agents too close: none now
                self._walker = None

    def _place_robots(self, robots: FloatArray, radius: float) -> None:
        """Puts every robot into JuPedSim for this period: a standing agent on its disc
        (``radius`` + :data:`ROBOT_ROOM`), so the pedestrians steer around it. JuPedSim
        refuses an agent overlapping another: a disc shrinks to the room the people leave
        (none below :data:`MIN_ROBOT_RADIUS`, or a refusal: no disc this period; the robot's
        body still collides with theirs)."""
        now = self._read()
        body = self.radius + ROBOT_ROOM
        for x, y in robots.tolist():
            room = radius + ROBOT_ROOM
            if len(now):
                gaps = np.hypot(now[:, 0] - x, now[:, 1] - y)
                room = min(room, float(gaps.min()) - body - WALKER_ROOM)
            if room < MIN_ROBOT_RADIUS:
                continue
            try:
                self._robot_discs.append(self._add(np.array([x, y]), 0.0, room))
            except RuntimeError:  # outside the walkable area, or against another disc
                continue

    def _retarget_crowd(self, agents: list[Any]) -> None:
        """Pedestrians that reached their goal get a new random one; those stuck for
        :data:`STUCK_TIME` give way (a new goal near them). ``agents``: JuPedSim's agents in
        ``_ids`` order."""
        first = 1 if self.has_person else 0
        self._past.append(self.positions)
        before = self._past.pop(0) if len(self._past) > self._stuck_steps else None
        positions = self.positions.tolist()
        for k in range(first, len(self._ids)):
            agent = agents[k]
            tx, ty = agent.target
            x, y = positions[k]
            if math.hypot(x - tx, y - ty) < GOAL_REACHED:
                agent.target = tuple(self._free_point().tolist())
            elif before is not None and math.hypot(x - before[k][0],
                                                   y - before[k][1]) < STUCK_DISTANCE:
                here = self.positions[k:k + 1]
                agent.target = tuple(self._free_point(here, -GIVE_WAY_RADIUS).tolist())
                self._past[0] = self._past[0].copy()
                self._past[0][k] = (tx, ty)  # judged again a full STUCK_TIME later

    def walk(self, t: float, world: Any) -> FloatArray:
        """Advances the people by the control period from ``t`` (s), the robots of ``world``
        (a :class:`~boids_env.world.space.World`) as obstacles the crowd walks around, and
        returns the crowd's body velocities (P, 2) that take each body to its pedestrian's
        new position, each within that pedestrian's walking speed (a body held back by a
        robot catches up no faster than it walks, and never flings what it meets)."""
        robots = world.positions[1:] if world.person_leader else world.positions
        self.advance(t, robots, world.config.robot_radius)
        return within_speeds((self.pedestrians - world.pedestrian_positions) / self.dt,
                             self.speeds)

    @property
    def pedestrians(self) -> FloatArray:
        """The crowd's positions (P, 2) (m)."""
        return self.positions[1:] if self.has_person else self.positions

    # --------------------------------------------------------------------------- pickle
    def __getstate__(self) -> dict[str, Any]:
        return {"args": self._args, "rng_state": self._rng_state, "steps": self.steps,
                "robots": list(self._robot_log), "robot_radius": self._robot_radius}

    def __setstate__(self, state: dict[str, Any]) -> None:
        # JuPedSim cannot be copied: rebuild from the same draws and replay every period
        self._args = state["args"]
        self._rng_state = state["rng_state"]
        rng = np.random.default_rng()
        rng.bit_generator.state = self._rng_state
        self._build(rng)
        radius = state.get("robot_radius", 0.0)
        for k, robots in enumerate(state.get("robots", [None] * state["steps"])):
            self.advance(k * self.dt, robots, radius)  # the env's time: steps · dt


def within_speeds(velocities: FloatArray, limits: FloatArray | float) -> FloatArray:
    """``velocities`` (K, 2) with each row longer than its limit (m/s; ``limits`` (K,) or one
    for all) scaled down to it, elementwise (the same bits on every CPU)."""
    speed = np.sqrt(velocities[:, 0] * velocities[:, 0] + velocities[:, 1] * velocities[:, 1])
    over = speed > limits
    if not over.any():
        return velocities
    scale = np.where(over, np.asarray(limits, dtype=float) / np.where(over, speed, 1.0), 1.0)
    return velocities * scale[:, None]
