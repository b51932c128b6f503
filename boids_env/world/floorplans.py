"""Generated floor plans: seeded buildings of rooms, a corridor, doors and furniture, each with
a leader route through them.

``floorplan:SEED`` names one as a scene anywhere a scene is named (``scene="floorplan:7"``,
``boids run --scene floorplan:7``, suites, training recipes); :func:`floorplan` builds it in
Python. The same seed gives the same :class:`~.scene.Scene` on every machine (one
``np.random.Generator(PCG64(seed))``, geometry from its draws only).

A plan (every length in m):

- a straight corridor :data:`CORRIDOR` wide (clear width between wall faces) across the
  building, closed at both ends (dead ends), with 2 or 3 rooms on each side;
- rooms 3.6 m or wider and :data:`ROOM_DEPTH` deep, each with one door :data:`DOOR` wide in
  its corridor wall (10 cm walls, as the built-in scenes');
- furniture: an *office* room has desks along its back wall and, when it is large enough, a
  table island with 1.2 m or more around it; a *store* room has 2 to 4 shelf rows running
  away from the corridor, with aisles of 1.2-1.8 m (open at both ends: a serpentine, or
  closed at the back wall: dead-end aisles the leader backs out of);
- the leader's route: from the start room through its door, along the corridor into two
  other rooms (around the table island, down each aisle), sometimes to a dead end of the
  corridor and back, and home to the start room. The route is the shortest path keeping
  :data:`ROUTE_CLEARANCE` from every wall on a :mod:`~boids_env.world.route` grid,
  simplified to waypoints whose legs keep that clearance.

The flock starts in the start room's most open spot, facing its door, and the scene's
defaults carry the start, the heading and the waypoints. :data:`VERSION` is the generator's;
the scene's resolved name is ``floorplan@VERSION:SEED``, so a recording names the generator
that made its plan, and a plan made by another version is refused instead of rebuilt
differently.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from boids_env.world.layout import follower_cells
from boids_env.world.route import RouteGrid, route_grid
from boids_env.world.scene import STUDY_DEFAULTS, Scene

FloatArray = npt.NDArray[np.float64]
VERSION = 1
"""The generator's version: bumped whenever a seed's plan changes."""
PREFIX = "floorplan"
"""Scene names ``floorplan:SEED`` (resolved to ``floorplan@VERSION:SEED``)."""
MAX_SEED = 2**32 - 1
CORRIDOR = (1.2, 2.5)
"""Clear width of the corridor (m)."""
DOOR = (0.8, 1.5)
"""Clear width of the doors (m)."""
ROOM_DEPTH = (4.0, 6.0)
"""Depth of the rooms (m)."""
ROOM_WIDTH_MIN = 3.6
"""Narrowest room (m)."""
AISLE = (1.2, 1.8)
"""Clear width of a store room's aisles (m)."""
WALL = 0.05
"""Half the thickness of the walls (m)."""
ROUTE_CLEARANCE = 0.3
"""The leader's route keeps this far from every wall (m): it fits the 0.8 m door."""
START_ROBOTS = 19
"""The start room holds the study's largest group's grid (19 robots, 0.5 m apart)."""


@dataclass(frozen=True)
class Room:
    """A room: its floor (inner faces) and its door."""

    x0: float
    x1: float
    y0: float
    y1: float
    north: bool
    """Whether it lies north of the corridor (its door in its south wall)."""
    door: float
    """The door's centre x (m)."""
    door_width: float

    @property
    def door_point(self) -> tuple[float, float]:
        """The middle of the doorway (m)."""
        return (self.door, self.y0 if self.north else self.y1)

    def inward(self, depth: float) -> tuple[float, float]:
        """A point ``depth`` m into the room straight from the door."""
        x, y = self.door_point
        return (x, y + depth if self.north else y - depth)


def parse(spec: str) -> int | None:
    """The seed of a ``floorplan:SEED`` / ``floorplan@VERSION:SEED`` name (None for any other
    scene name); ``ValueError`` for a floor-plan name with a bad seed or another version."""
    if not isinstance(spec, str) or not spec.startswith(PREFIX):
        return None
    head, sep, seed = spec.partition(":")
    if not sep or head not in (PREFIX, f"{PREFIX}@{VERSION}"):
        if sep and head.startswith(f"{PREFIX}@"):
            raise ValueError(f"scene {spec!r} was made by floor-plan generator version "
                             f"{head[len(PREFIX) + 1:]}; this is version {VERSION}, whose plan "
                             f"for that seed may differ (use floorplan:{seed} for today's)")
        return None
    if not seed.isdigit() or int(seed) > MAX_SEED:
        raise ValueError(f"a floor plan is named floorplan:SEED with SEED an integer in [0, "
                         f"{MAX_SEED}], got {spec!r}")
    return int(seed)


def key(seed: int) -> str:
    """The resolved scene name of floor plan ``seed``."""
    return f"{PREFIX}@{VERSION}:{seed}"


def floorplan(seed: int) -> Scene:
    """The floor plan of ``seed`` (an integer in [0, 2³²−1])."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not (
            0 <= seed <= MAX_SEED):
        raise ValueError(f"floor-plan seed must be an integer in [0, {MAX_SEED}], got {seed!r}")
    rng = np.random.default_rng(int(seed))
    for _ in range(50):  # a draw whose rooms cannot hold the start or the tour is drawn again
        scene = _attempt(int(seed), rng)
        if scene is not None:
            return scene
    raise RuntimeError(f"floor plan {seed}: no valid plan in 50 draws")  # pragma: no cover


def _attempt(seed: int, rng: np.random.Generator) -> Scene | None:
    corridor = float(rng.uniform(*CORRIDOR))
    n_rooms = int(rng.integers(2, 4))
    widths = [rng.uniform(ROOM_WIDTH_MIN, 5.5, n_rooms), rng.uniform(ROOM_WIDTH_MIN, 5.5,
                                                                     n_rooms)]
    width = float(max(w.sum() for w in widths))
    depths = (float(rng.uniform(*ROOM_DEPTH)), float(rng.uniform(*ROOM_DEPTH)))
    half = corridor / 2 + 2 * WALL  # the corridor walls' outer faces
    box = (-width / 2, -half - depths[0], width / 2, half + depths[1])
    caps: list[tuple[tuple[float, float], tuple[float, float], str]] = []
    polys: list[tuple[FloatArray, str]] = []
    rooms: list[Room] = []
    kinds: list[str] = []
    for side, north in ((0, False), (1, True)):
        cuts = np.concatenate([[0.0], np.cumsum(widths[side])])
        cuts = -width / 2 + cuts * width / cuts[-1]  # the side's rooms fill the width
        wall_y = (corridor / 2 + WALL) * (1 if north else -1)
        face = wall_y + (WALL if north else -WALL)  # the room side of the corridor wall
        far = box[3] if north else box[1]
        doors = []
        for k in range(n_rooms):
            x0 = cuts[k] + (WALL if k else 0.0)
            x1 = cuts[k + 1] - (WALL if k + 1 < n_rooms else 0.0)
            if k + 1 < n_rooms:  # the partition to the next room
                caps.append(((cuts[k + 1], face), (cuts[k + 1], far), f"partition {side}{k}"))
            d = float(rng.uniform(*DOOR))
            margin = 0.35 + d / 2 + WALL
            door = float(rng.uniform(x0 + margin, x1 - margin))
            doors.append((door, d))
            y0, y1 = (face, far) if north else (far, face)
            rooms.append(Room(x0, x1, y0, y1, north, door, d))
            kinds.append("store" if rng.random() < 0.4 else "office")
        # the corridor wall, broken at each door
        left = -width / 2
        for door, d in doors:
            caps.append(((left, wall_y), (door - d / 2 - WALL, wall_y),
                         f"{'north' if north else 'south'} corridor wall"))
            left = door + d / 2 + WALL
        caps.append(((left, wall_y), (width / 2, wall_y),
                     f"{'north' if north else 'south'} corridor wall"))
    tours: list[list[tuple[float, float]]] = []
    for room, kind in zip(rooms, kinds, strict=True):
        made, tour = (_store(room, rng) if kind == "store" else _office(room, rng))
        polys += made
        tours.append(tour)
    a = np.array([c[0] for c in caps])
    b = np.array([c[1] for c in caps])
    names = tuple(c[2] for c in caps) + tuple(p[1] for p in polys)
    scene = Scene(key(seed), "", box=box, a=a, b=b, radius=np.full(len(caps), WALL),
                  polygons=tuple(p[0] for p in polys), names=names)
    return _with_route(scene, seed, rooms, kinds, tours, corridor, rng)


def _rect(x0: float, y0: float, x1: float, y1: float) -> FloatArray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def _office(room: Room, rng: np.random.Generator
            ) -> tuple[list[tuple[FloatArray, str]], list[tuple[float, float]]]:
    """Desks along the back wall and, in a large room, a table island to go round."""
    polys = []
    back = room.y1 if room.north else room.y0
    sign = 1.0 if room.north else -1.0
    depth = float(rng.uniform(0.6, 0.8))
    x = room.x0 + float(rng.uniform(0.0, 0.6))
    while True:
        w = float(rng.uniform(1.2, 1.6))
        if x + w > room.x1:
            break
        y_a, y_b = back, back - sign * depth
        polys.append((_rect(x, min(y_a, y_b), x + w, max(y_a, y_b)), "a desk"))
        x += w + float(rng.uniform(0.0, 1.0))
    # the free depth between the desks and the door side
    inner = abs(room.y1 - room.y0) - depth
    tw, th = float(rng.uniform(1.2, 2.0)), float(rng.uniform(0.8, 1.2))
    room_w = room.x1 - room.x0
    tour: list[tuple[float, float]] = []
    if room_w >= tw + 2 * 1.3 and inner >= th + 2 * 1.3:
        cx = float(rng.uniform(room.x0 + tw / 2 + 1.3, room.x1 - tw / 2 - 1.3))
        door_side = room.y0 if room.north else room.y1
        cy = door_side + sign * (1.3 + th / 2 + float(rng.uniform(0, inner - th - 2.6)))
        polys.append((_rect(cx - tw / 2, cy - th / 2, cx + tw / 2, cy + th / 2),
                      "the table island"))
        ox, oy = tw / 2 + 0.6, th / 2 + 0.6
        ring = [(cx - ox, cy - sign * oy), (cx - ox, cy + sign * oy), (cx + ox, cy + sign * oy),
                (cx + ox, cy - sign * oy)]
        if rng.random() < 0.5:
            ring = ring[::-1]
        tour = [*ring, ring[0]]  # once round the island
    else:
        tour = [room.inward(inner * 0.55)]
    return polys, tour


def _store(room: Room, rng: np.random.Generator
           ) -> tuple[list[tuple[FloatArray, str]], list[tuple[float, float]]]:
    """Shelf rows running away from the corridor; the tour goes down each aisle."""
    polys = []
    sign = 1.0 if room.north else -1.0
    door_side = room.y0 if room.north else room.y1
    back = room.y1 if room.north else room.y0
    closed = rng.random() < 0.5  # shelves against the back wall: dead-end aisles
    front = 1.3  # a cross aisle along the door side
    back_gap = 0.0 if closed else float(rng.uniform(*AISLE))
    shelf = float(rng.uniform(0.4, 0.6))
    aisle = float(rng.uniform(*AISLE))
    y_front = door_side + sign * front
    y_back = back - sign * back_gap
    if abs(y_back - y_front) < 1.5:
        return [], [room.inward(1.0)]
    # rows placed from the wall farther from the door, so the door keeps its cross aisle
    xs = []
    x = room.x0 + aisle
    while x + shelf <= room.x1 - aisle:
        xs.append(x)
        x += shelf + aisle
    rows = xs[:4]
    aisles: list[float] = []
    for k, x0 in enumerate(rows):
        polys.append((_rect(x0, min(y_front, y_back), x0 + shelf, max(y_front, y_back)),
                      f"shelf row {k + 1}"))
        aisles.append(x0 - aisle / 2)
    if rows:
        aisles.append(rows[-1] + shelf + aisle / 2)
    deep = y_back - sign * 0.6 if closed else back - sign * back_gap / 2
    near = y_front - sign * 0.65
    tour = []
    for k, ax in enumerate(aisles):
        if closed:  # down each dead-end aisle and back out
            tour += [(ax, near), (ax, deep), (ax, near)]
        else:  # a serpentine: U-turns round the shelf ends
            tour += [(ax, near), (ax, deep)] if k % 2 == 0 else [(ax, deep), (ax, near)]
    return polys, tour


def _with_route(scene: Scene, seed: int, rooms: list[Room], kinds: list[str],
                tours: list[list[tuple[float, float]]], corridor: float,
                rng: np.random.Generator) -> Scene | None:
    """The scene with its leader route and start, or None if the draw cannot hold them."""
    grid = route_grid(scene, ROUTE_CLEARANCE)
    if not len(grid.centres):
        return None
    order = [int(k) for k in rng.permutation(len(rooms))]
    spots = [_open_spot(scene, rooms[k]) for k in order]
    homes = [k for k, spot in zip(order, spots, strict=True) if spot is not None]
    if not homes:
        return None
    home = homes[0]  # the first room drawn that holds the start
    spot = spots[order.index(home)]
    assert spot is not None
    start, facing = (spot[0], spot[1]), spot[2]
    visits = [k for k in order if k != home][:2]
    goals: list[tuple[float, float]] = [start, rooms[home].inward(0.6)]
    assert scene.box is not None, "a floor plan is a box of rooms"  # see _attempt
    width = scene.box[2] - scene.box[0]
    dead_end = rng.random() < 0.5
    for k, r in enumerate(visits):
        goals += [rooms[r].inward(-0.6), rooms[r].inward(0.6), *tours[r], rooms[r].inward(0.6),
                  rooms[r].inward(-0.6)]
        if dead_end and k == 0:  # to a closed end of the corridor and back
            end = width / 2 - 0.8
            goals += [(end if rng.random() < 0.5 else -end, 0.0)]
    goals += [rooms[home].inward(-0.6), rooms[home].inward(0.6), start]
    path = _plan(scene, grid, goals)
    if path is None:
        return None
    path[0] = start  # exactly where the grid was fitted, facing the door
    defaults = {**STUDY_DEFAULTS, "path": "waypoints", "waypoints": tuple(path[1:]),
                "start": start, "start_heading": facing}
    described = (f"generated floor plan {seed} (generator v{VERSION}): "
                 f"{width:.1f} m × {scene.bounds[3] - scene.bounds[1]:.1f} m, a "
                 f"{corridor:.2f} m corridor, {len(rooms)} rooms ({kinds.count('office')} "
                 f"offices, {kinds.count('store')} stores), doors "
                 f"{min(r.door_width for r in rooms):.2f}-{max(r.door_width for r in rooms):.2f}"
                 f" m")
    made = Scene(scene.name, described, box=scene.box, a=scene.a, b=scene.b,
                 radius=scene.radius, polygons=scene.polygons, names=scene.names,
                 defaults=defaults)
    made._cache.update({k: v for k, v in scene._cache.items() if k[0] == "route"})
    return made


def _open_spot(scene: Scene, room: Room) -> tuple[float, float, float] | None:
    """The most open point of ``room``, 1.2 m or more in from its door, where the study's
    largest start grid fits behind a leader facing the door (None if there is none)."""
    xs = np.arange(room.x0 + 0.2, room.x1 - 0.2, 0.1)
    ys = np.arange(min(room.y0, room.y1) + 0.2, max(room.y0, room.y1) - 0.2, 0.1)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    clear = scene.clearance(pts)
    dx, dy = room.door_point
    clear = np.where(np.hypot(pts[:, 0] - dx, pts[:, 1] - dy) >= 1.2, clear, -1.0)
    order = np.argsort(-clear, kind="stable")[:300]
    order = order[clear[order] >= 0.6]
    if not len(order):
        return None
    cand = pts[order]
    heading = np.arctan2(dy - cand[:, 1], dx - cand[:, 0])
    cells = _grid_cells(cand, heading)
    fits = (scene.clearance(cells.reshape(-1, 2)).reshape(len(cand), -1) > START_CLEARANCE
            ).all(axis=1)
    if not fits.any():
        return None
    k = int(np.argmax(fits))
    return (round(float(cand[k, 0]), 3), round(float(cand[k, 1]), 3),
            round(math.degrees(float(heading[k])), 6))


START_CLEARANCE = 0.15
"""Each start cell of the study's largest group keeps this far from walls (m)."""


def _grid_cells(starts: FloatArray, heading: FloatArray) -> FloatArray:
    """(S, 18, 2) the 19-robot start grid behind leaders at ``starts`` facing ``heading``
    (rad), as :func:`~boids_env.world.scenario.initial_positions` lays it out."""
    cells = follower_cells(START_ROBOTS)
    turn = heading - math.pi / 2
    c, s = np.cos(turn)[:, None], np.sin(turn)[:, None]
    return np.stack([cells[:, 0] * c - cells[:, 1] * s + starts[:, 0:1],
                     cells[:, 0] * s + cells[:, 1] * c + starts[:, 1:2]], axis=-1)


def _plan(scene: Scene, grid: RouteGrid, goals: list[tuple[float, float]]
          ) -> list[tuple[float, float]] | None:
    """The shortest route through ``goals`` on ``grid``, simplified to waypoints whose legs
    keep :data:`ROUTE_CLEARANCE` from walls (None where a goal is unreachable)."""
    from scipy.sparse.csgraph import dijkstra

    pts = np.asarray(goals, dtype=float)
    nodes = grid.cells_of(pts)
    if np.any(nodes < 0):
        return None
    cells: list[int] = [int(nodes[0])]
    marks = [0]  # where each goal lies on the cell line: kept as waypoints
    for a, b in itertools.pairwise(nodes):
        if a != b:
            cost, pred = dijkstra(grid.graph, indices=int(b), return_predecessors=True)
            if not np.isfinite(cost[a]):
                return None
            cur = int(a)
            while cur != b:
                cur = int(pred[cur])
                cells.append(cur)
        marks.append(len(cells) - 1)
    line = grid.centres[cells]
    keep = [0]
    for lo, hi in itertools.pairwise(marks):
        i = lo
        while i < hi:  # the farthest point in sight (with the clearance) before the next goal
            ahead = np.arange(i + 1, hi + 1)
            blocked, _ = scene.blocked(np.repeat(line[i:i + 1], len(ahead), 0), line[ahead],
                                       ROUTE_CLEARANCE - 0.05)
            first_bad = int(ahead[blocked][0]) if blocked.any() else hi + 1
            i = max(i + 1, first_bad - 1)
            keep.append(i)
    out = [(round(float(x), 3), round(float(y), 3)) for x, y in line[keep]]
    dedup = [out[0]]
    for p in out[1:]:
        if p != dedup[-1]:
            dedup.append(p)
    return dedup if len(dedup) >= 2 else None


def doorways(scene: Scene) -> FloatArray:
    """The middle (D, 2) of each door of a generated plan (the gaps in its corridor walls)."""
    out = []
    for side in ("north corridor wall", "south corridor wall"):
        k = [i for i, name in enumerate(scene.names[:len(scene.radius)]) if name == side]
        for left, right in itertools.pairwise(k):
            out.append((scene.b[left] + scene.a[right]) / 2)
    return np.array(out).reshape(-1, 2)
