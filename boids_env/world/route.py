"""Route sensing: the way to the leader through free space, not the straight line.

A follower behind a wall from its leader has to go through the door; every rule that seeks the
leader's straight-line position strands it. This sensor gives each follower the direction of
the shortest *free* path to the leader and the path's length, a pure function of the scene's
geometry, the robots' positions and the leader's.

How (measured choice, see ``docs/how-to/buildings.md``): the scene is rasterised once into a
grid of ``cell`` m cells (0.1 m by default); a cell is free when its centre is farther than
the robot's radius from every wall, so a door narrower than a robot's diameter has no free
cell and is no way through. The free cells form an 8-connected graph (a diagonal step only
where both cells beside it are free: no cutting corners), each step weighted by its length
times a penalty that grows within :data:`SOFT_CLEARANCE` of a wall (routes keep to the middle
of doors and corridors). That grid and graph are cached on the :class:`~.scene.Scene` (like
its ``occupancy``), keyed by robot radius and cell size: built once per scene, never per
robot or step. Each step one Dijkstra from the leader's cell (``scipy.sparse.csgraph``) gives
every cell's route cost and its next cell towards the leader; the last few fields are kept
by leader cell (a scripted leader drives the same cells in every episode). Each follower
then reads its cell, walks up to :data:`LOOKAHEAD` m along the next-cell chain as far as it
sees the chain's cells through free cells, and aims at that point (so it never aims across
a door's jamb), all followers in one array pass.

A follower whose cell is not free (touching a wall) reads the nearest free cell's; where no
free path exists (a door too narrow, a closed room), the sensor says so with its valid flag 0
and falls back to the straight line (direction and distance to the leader).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
import numpy.typing as npt

from boids_env import kernels
from boids_env.world.scene import Scene

if TYPE_CHECKING:  # scipy.sparse is imported when a grid is first built (1 s on a busy machine)
    from scipy.sparse import csr_matrix

FloatArray = npt.NDArray[np.float64]
ROUTE_CELL = 0.1
"""Default cell size (m) of the route grid."""
LOOKAHEAD = 1.0
"""How far along its route (m) a follower aims: far enough to smooth the grid's 45° steps,
short enough to stay within sight round a door's jamb."""
SOFT_CLEARANCE = 0.35
"""Within this distance (m) of a wall a route step costs more, up to :data:`WALL_PENALTY`
times its length at the wall (the route keeps to a door's middle)."""
WALL_PENALTY = 2.0
"""Extra cost factor of a step at zero clearance (1 + this)."""
FIELDS_KEPT = 512
"""Route fields kept per grid, by the leader's cell (a field of the 12 m × 10 m ``lab`` takes
85 kB: a scripted leader's whole path is kept, and the next seed's episode reuses it)."""
SIZE = 4
"""Values per follower in the ``route`` observation block: direction (2), length (1), valid
flag (1)."""


@dataclass(frozen=True, eq=False)
class RouteGrid:
    """The free space of a scene for a robot of one radius, as a graph of grid cells."""

    origin: tuple[float, float]
    """World position (m) of the lower-left corner of cell (0, 0)."""
    cell: float
    """Cell size (m)."""
    free: npt.NDArray[np.bool_]
    """(H, W) whether each cell's centre is farther than the robot radius from walls."""
    node: npt.NDArray[np.intp]
    """(H·W,) the graph node of each cell: its own if free, else the nearest free cell's
    (−1 only when no cell is free)."""
    centres: FloatArray
    """(nodes, 2) the centre of each free cell (m)."""
    graph: csr_matrix
    """Weighted 8-connected adjacency of the free cells."""

    def cells_of(self, points: FloatArray) -> npt.NDArray[np.intp]:
        """The graph node (P,) each point (P, 2) reads (−1 without free space)."""
        h, w = self.free.shape
        col = np.clip(np.floor((points[:, 0] - self.origin[0]) / self.cell), 0, w - 1)
        row = np.clip(np.floor((points[:, 1] - self.origin[1]) / self.cell), 0, h - 1)
        return self.node[row.astype(np.intp) * w + col.astype(np.intp)]


def route_grid(scene: Scene, radius: float, cell: float = ROUTE_CELL) -> RouteGrid:
    """The scene's route grid for robots of ``radius`` (m), cached on the scene."""
    key = ("route", float(radius), float(cell))
    if key not in scene._cache:
        scene._cache[key] = _build(scene, float(radius), float(cell))
    return scene._cache[key]


MAX_CELLS = 4_000_000
"""Largest route grid (cells); a larger one is refused before it is allocated."""


def _build(scene: Scene, radius: float, cell: float) -> RouteGrid:
    from scipy import ndimage
    from scipy.sparse import csr_matrix

    x0, y0, x1, y1 = scene.bounds
    w = max(1, math.ceil((x1 - x0) / cell))
    h = max(1, math.ceil((y1 - y0) / cell))
    if w * h > MAX_CELLS:
        raise ValueError(f"route_cell {cell} m gives a {w} × {h} route grid over scene "
                         f"{scene.name!r}, more than {MAX_CELLS} cells: use a larger route_cell")
    gx, gy = np.meshgrid(x0 + (np.arange(w) + 0.5) * cell, y0 + (np.arange(h) + 0.5) * cell)
    centres = np.stack([gx.ravel(), gy.ravel()], axis=1)
    clearance = scene.clearance(centres)
    free = (clearance > radius).reshape(h, w)
    ids = np.full((h, w), -1, dtype=np.intp)
    ids[free] = np.arange(int(free.sum()))
    soft = np.clip(1.0 - (clearance.reshape(h, w) - radius) / SOFT_CLEARANCE, 0.0, 1.0)
    cost = 1.0 + WALL_PENALTY * soft  # per unit length, at each cell
    rows, cols, weights = [], [], []
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = _shifted(free, 0, 0, dy, dx)
        b = _shifted(free, dy, dx, dy, dx)
        both = a & b
        if dx and dy:  # a diagonal only where both cells beside it are free
            both &= _shifted(free, dy, 0, dy, dx) & _shifted(free, 0, dx, dy, dx)
        ia, ib = _shifted(ids, 0, 0, dy, dx)[both], _shifted(ids, dy, dx, dy, dx)[both]
        ca, cb = _shifted(cost, 0, 0, dy, dx)[both], _shifted(cost, dy, dx, dy, dx)[both]
        wgt = cell * math.hypot(dx, dy) * 0.5 * (ca + cb)
        rows += [ia, ib]
        cols += [ib, ia]
        weights += [wgt, wgt]
    n = int(free.sum())
    graph = csr_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(n, n))
    if n:
        # every cell reads its nearest free cell (a follower touching a wall, or off the map)
        _, (ri, ci) = ndimage.distance_transform_edt(~free, return_indices=True)
        node = ids[ri, ci].ravel()
    else:
        node = np.full(h * w, -1, dtype=np.intp)
    return RouteGrid((x0, y0), cell, free, node, centres[free.ravel()], graph)


def _shifted(a: npt.NDArray, oy: int, ox: int, dy: int, dx: int) -> npt.NDArray:
    """The part of ``a`` that pairs cell (r, c) with (r + dy, c + dx): offset (oy, ox) into
    the overlap of ``a`` and ``a`` shifted by (dy, dx) (dy >= 0)."""
    h, w = a.shape
    c0 = max(0, -dx)
    cw = w - abs(dx)
    return a[oy:oy + h - dy, c0 + ox:c0 + ox + cw]


@dataclass(frozen=True)
class RouteField:
    """Every free cell's route to one leader cell."""

    leader: int
    """The leader's node."""
    cost: npt.NDArray[np.float32]
    """(nodes,) route cost to the leader (m, wall penalty included; inf: no route)."""
    next: npt.NDArray[np.int32]
    """(nodes,) the next node along each node's route (itself at the leader)."""


def route_field(grid: RouteGrid, leader: FloatArray) -> RouteField | None:
    """The route field towards the leader at ``leader`` (2,) (None without free space);
    the last :data:`FIELDS_KEPT` fields are reused by leader cell."""
    node = int(grid.cells_of(np.asarray(leader, float).reshape(1, 2))[0])
    if node < 0:
        return None
    kept: OrderedDict[int, RouteField] = grid.__dict__.setdefault("_fields", OrderedDict())
    if node in kept:
        kept.move_to_end(node)
        return kept[node]
    from scipy.sparse.csgraph import dijkstra

    cost, pred = dijkstra(grid.graph, indices=node, return_predecessors=True)
    nxt = np.where(pred >= 0, pred, np.arange(len(pred)))
    field = RouteField(node, cost.astype(np.float32), nxt.astype(np.int32))
    kept[node] = field
    if len(kept) > FIELDS_KEPT:
        kept.popitem(last=False)
    return field


def _in_sight_ahead(grid: RouteGrid, field: RouteField, node: npt.NDArray[np.intp],
                    points: FloatArray) -> npt.NDArray[np.intp]:
    """The farthest node up to :data:`LOOKAHEAD` m along each follower's route that it sees
    through free cells (every earlier one seen too), so its aim never cuts a door's jamb;
    the next node where it sees none."""
    steps = max(1, round(LOOKAHEAD / grid.cell))
    t = np.linspace(0.0, 1.0, 2 * steps + 1)
    compiled = kernels.compiled()
    if compiled is not None and (node >= 0).all() and np.isfinite(points).all():
        # the same nodes in one loop (boids_env.kernels)
        return compiled.in_sight_ahead(np.ascontiguousarray(points, dtype=np.float64), node,
                                       field.next, grid.centres, grid.free,
                                       float(grid.origin[0]), float(grid.origin[1]),
                                       float(grid.cell), t, steps)
    t = t[None, :, None]
    cur = field.next[node]
    best = cur.astype(np.intp)
    alive = np.ones(len(node), dtype=bool)
    h, w = grid.free.shape
    flat = grid.free.ravel()
    for _ in range(steps):
        ends = grid.centres[cur]
        samples = points[:, None, :] + t * (ends - points)[:, None, :]  # (F, S, 2)
        col = np.floor((samples[..., 0] - grid.origin[0]) / grid.cell).astype(np.intp)
        row = np.floor((samples[..., 1] - grid.origin[1]) / grid.cell).astype(np.intp)
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        free = np.where(inside, flat[np.clip(row, 0, h - 1) * w + np.clip(col, 0, w - 1)],
                        False)
        alive &= free[:, 1:].all(axis=1)  # the follower's own spot may touch a wall
        best = np.where(alive, cur, best)
        cur = field.next[cur]
    return best


def leader_in_sight(grid: RouteGrid, positions: FloatArray) -> npt.NDArray[np.bool_]:
    """Whether each follower sees the leader through free cells (F,): every point of the
    straight segment between them, sampled every half cell (their own spots left out), lies
    in a free cell, so a robot of the grid's radius could drive it. ``positions`` (N, 2),
    the leader first."""
    positions = np.asarray(positions, dtype=float)
    leader, points = positions[0], positions[1:]
    offset = leader - points
    dist = np.sqrt(offset[:, 0] * offset[:, 0] + offset[:, 1] * offset[:, 1])
    samples = max(2, math.ceil(float(dist.max(initial=0.0)) / (grid.cell / 2)))
    t = (np.arange(1, samples) / samples)[None, :, None]
    along = points[:, None, :] + t * offset[:, None, :]  # (F, S, 2)
    h, w = grid.free.shape
    col = np.floor((along[..., 0] - grid.origin[0]) / grid.cell).astype(np.intp)
    row = np.floor((along[..., 1] - grid.origin[1]) / grid.cell).astype(np.intp)
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    free = np.where(inside, grid.free.ravel()[np.clip(row, 0, h - 1) * w
                                              + np.clip(col, 0, w - 1)], False)
    return cast("npt.NDArray[np.bool_]", free.all(axis=1))  # (F, S) -> (F,), not a scalar


def sense_route(grid: RouteGrid, positions: FloatArray) -> tuple[FloatArray, FloatArray,
                                                                  npt.NDArray[np.bool_]]:
    """Each follower's way to the leader.

    Args:
        grid: the scene's :func:`route_grid`.
        positions: (N, 2) positions (m), the leader first.

    Returns:
        ``(direction (F, 2), length (F,), valid (F,))`` for the N−1 followers: the unit vector
        towards the farthest point in sight up to :data:`LOOKAHEAD` m along the route
        (towards the leader itself within that distance) and the route's cost (m); where
        no route exists, ``valid`` is False and direction and length are the straight
        line's. A follower on the leader
        gets a zero direction.
    """
    positions = np.asarray(positions, dtype=float)
    leader, points = positions[0], positions[1:]
    straight = leader - points
    dist = np.sqrt(straight[:, 0] * straight[:, 0] + straight[:, 1] * straight[:, 1])
    field = route_field(grid, leader)
    if field is None:
        valid = np.zeros(len(points), dtype=bool)
        aim, length = straight, dist
    else:
        node = grid.cells_of(points)
        cost = field.cost[node].astype(float)
        valid = np.isfinite(cost)
        ahead = _in_sight_ahead(grid, field, node, points)
        target = np.where((ahead == field.leader)[:, None], leader, grid.centres[ahead])
        aim = np.where(valid[:, None], target - points, straight)
        length = np.where(valid, cost, dist)
    norm = np.sqrt(aim[:, 0] * aim[:, 0] + aim[:, 1] * aim[:, 1])
    direction = aim / np.where(norm > 0, norm, 1.0)[:, None]
    return direction, length, valid
