"""The named observation layout, neighbour search and observation building (DESIGN section 6).

Per follower, float32, world frame, metres and m/s:

=====================  ======  ==============================================================
name                   size    meaning
=====================  ======  ==============================================================
``own_velocity``       2       the follower's measured velocity
``leader_position``    2       leader position relative to the follower
``leader_velocity``    2       the leader's measured velocity
``neighbours``         5·K     K slots, nearest first: relative position (2), velocity (2),
                               valid flag (1); empty slots are all zero
=====================  ======  ==============================================================

Beyond the study, in this order after them: ``static`` (3 per static slot), ``lidar`` (1 per
ray), and for robots with a heading (``drive="unicycle"``) ``own_heading`` (2: cos, sin of the
follower's heading), ``leader_heading`` (2) and ``neighbour_headings`` (2·K: the heading of
the robot in each neighbour slot, zeros in an empty slot). Headings are unit vectors, so they
turn with the frame like every other vector; appended as blocks of their own, they leave
every other block where the study's layout has it.

Neighbours are the other robots j with 0 < |p_j − p_i| ≤ horizon, the leader included, as in the
original controller.

Frames: by default (``frame="world"``, the study's) every vector is in the world frame. With
``frame="leader"`` (opt-in) every vector is expressed in the leader's heading frame (x forward
along the leader's motion, y to its left), and actions are read in the same frame, so a
formation learned relative to the leader holds on any path. :class:`Observer` is the one place
that builds observations (the env and the ROS controller node use it); everything else here is
a pure function of numpy arrays (no physics).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from scipy.spatial import cKDTree

from boids_env import kernels
from boids_env.vectors import times_matrix
from boids_env.world import geometry as geo
from boids_env.world.route import ROUTE_CELL, RouteGrid, leader_in_sight, route_grid, sense_route
from boids_env.world.route import SIZE as ROUTE_SIZE
from boids_env.world.scene import Scene

if TYPE_CHECKING:
    from boids_env.config import EnvConfig

FloatArray = npt.NDArray[np.floating]
HEADING_MIN_SPEED = 0.05
"""The leader frame follows the leader's measured velocity from this speed (m/s) on; below it
(start-up, corners) the last heading is kept."""
INITIAL_HEADING = math.pi / 2
"""Default heading (rad) of the leader frame before the leader first moves: +y, the first leg
of the study's square (the env passes its leader's own first direction)."""

SLOT_SIZE = 5
WALL_SIZE = 3
ROUTE_REACH = 8.0
"""The ``route`` block's length is clipped to this many times the scene's span (a route
winds, and its wall penalty lengthens it)."""
KD_TREE_MIN_ROBOTS = 96
"""From this group size on, neighbours are found with a KD-tree instead of all pairs
(measured: all-pairs wins below about 100 robots)."""
_NO_FRAME = np.eye(2)
"""The frame the compiled static block is given in the world frame (not applied)."""


BLOCKS = ("own_velocity", "leader_position", "leader_velocity", "neighbours", "static", "lidar",
          "pedestrians", "own_heading", "leader_heading", "neighbour_headings", "route")
"""The observation's blocks, in the order they appear (empty blocks are left out)."""


@dataclass(frozen=True)
class ObservationLayout:
    """Named blocks of one follower's observation vector, and views of a batch of them.

    The layout is an explicit list of blocks (:attr:`blocks`), saved with every trained model
    (``boids.json``), never guessed from a vector's length once sensing goes beyond the
    study's (:meth:`for_size` reads only the study-era sizes).
    """

    neighbours: int
    """K, the number of neighbour slots (5 values each)."""
    static: int = 0
    """M, the number of static-geometry slots (3 values each: offset to the nearest point of
    walls or obstacles, valid flag). The study-era ``sense_walls`` is one slot."""
    lidar: int = 0
    """R, the number of range-sensor rays (1 value each: distance in m)."""
    pedestrians: int = 0
    """P, the number of pedestrian slots (5 values each, as a neighbour slot: relative
    position, velocity, valid flag), nearest first (opt-in, with a crowd)."""
    headings: bool = False
    """Whether the robots have headings: the ``own_heading``, ``leader_heading`` and
    ``neighbour_headings`` blocks (unit vectors) follow the others."""
    route: bool = False
    """Whether the ``route`` block (route sensing, :mod:`boids_env.world.route`) comes last:
    the unit direction of the follower's shortest free path to the leader (2), its length
    (1, m) and a valid flag (1; 0 where no free path exists and the first three are the
    straight line's)."""

    own_velocity = slice(0, 2)
    leader_position = slice(2, 4)
    leader_velocity = slice(4, 6)
    neighbours_start = 6

    def __post_init__(self) -> None:
        for name in ("neighbours", "static", "lidar", "pedestrians"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
                raise ValueError(f"ObservationLayout {name} must be a non-negative integer, "
                                 f"got {value!r}")
        for name in ("headings", "route"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"ObservationLayout {name} must be True or False, got "
                                 f"{getattr(self, name)!r}")

    @functools.cached_property  # the fields are frozen; the env reads these every step
    def blocks(self) -> tuple[tuple[str, int], ...]:
        """``(name, size)`` of every non-empty block, in order."""
        sizes = {"own_velocity": 2, "leader_position": 2, "leader_velocity": 2,
                 "neighbours": SLOT_SIZE * self.neighbours, "static": WALL_SIZE * self.static,
                 "lidar": self.lidar, "pedestrians": SLOT_SIZE * self.pedestrians,
                 "own_heading": 2 * self.headings, "leader_heading": 2 * self.headings,
                 "neighbour_headings": 2 * self.neighbours * self.headings,
                 "route": ROUTE_SIZE * self.route}
        return tuple((name, sizes[name]) for name in BLOCKS if sizes[name])

    @classmethod
    def from_blocks(cls, blocks: object) -> ObservationLayout:
        """The layout of a saved block list (``[[name, size], ...]``, as :attr:`blocks`);
        ``ValueError`` for anything that is not one."""
        try:
            named = {str(name): int(size) for name, size in blocks}  # type: ignore[attr-defined]
            pairs = [(str(n), int(s)) for n, s in blocks]  # type: ignore[attr-defined]
        except (TypeError, ValueError):
            raise ValueError(f"an observation layout is a list of [name, size] pairs, got "
                             f"{blocks!r}") from None
        layout = cls(named.get("neighbours", 0) // SLOT_SIZE, named.get("static", 0) // WALL_SIZE,
                     named.get("lidar", 0), pedestrians=named.get("pedestrians", 0) // SLOT_SIZE,
                     headings="own_heading" in named, route="route" in named)
        if list(layout.blocks) != pairs:
            raise ValueError(f"not an observation layout: {pairs!r} (blocks, in order: "
                             f"{list(BLOCKS)}; neighbours and pedestrians 5 per slot, static 3 "
                             f"per slot, neighbour headings 2 per slot, route 4)")
        return layout

    @functools.cached_property
    def size(self) -> int:
        """Length of one observation vector."""
        return sum(size for _, size in self.blocks)

    @functools.cached_property
    def _slices(self) -> dict[str, slice]:
        slices, start = {}, 0
        for block, size in self.blocks:
            slices[block] = slice(start, start + size)
            start += size
        return slices

    def block(self, name: str) -> slice:
        """The slice of block ``name``; ``ValueError`` if this layout has no such block."""
        if name in self._slices:
            return self._slices[name]
        raise ValueError(f"this observation layout has no {name!r} block (blocks: "
                         f"{[b for b, _ in self.blocks]})")

    @property
    def walls(self) -> bool:
        """Whether the observation has static-geometry slots (the study-era wall slot)."""
        return self.static > 0

    @property
    def wall(self) -> slice:
        """The first static slot: offset (2) to the nearest point of static geometry, valid
        flag (1) (the study-era ``sense_walls`` slot)."""
        if not self.static:
            raise ValueError("this layout has no wall slot (sense_walls=False, static_slots=0)")
        start = self.block("static").start
        return slice(start, start + WALL_SIZE)

    @classmethod
    def for_size(cls, size: int) -> ObservationLayout:
        """The layout of a study-era observation vector of ``size``: neighbour slots and at
        most one wall slot (a wall slot of 3 never divides into the 5-wide neighbour slots).
        Layouts with more static slots or a range sensor must be given (:meth:`from_blocks`,
        or the env's ``layout``)."""
        rest = size - cls.neighbours_start
        walls = rest % SLOT_SIZE == WALL_SIZE
        if rest < 0 or rest % SLOT_SIZE not in (0, WALL_SIZE):
            raise ValueError(f"no study-era observation layout has size {size}; give the "
                             f"layout explicitly (e.g. policy.bind(env))")
        return cls((rest - WALL_SIZE * walls) // SLOT_SIZE, int(walls))

    def slots(self, obs: FloatArray) -> FloatArray:
        """View of the neighbour slots of a batch ``(..., size)`` as ``(..., K, 5)``."""
        end = self.neighbours_start + SLOT_SIZE * self.neighbours
        return obs[..., self.neighbours_start:end].reshape(*obs.shape[:-1], self.neighbours,
                                                           SLOT_SIZE)

    def static_slots(self, obs: FloatArray) -> FloatArray:
        """View of the static slots of a batch ``(..., size)`` as ``(..., M, 3)``: offset to
        the surface point (2), valid flag (1)."""
        block = self.block("static") if self.static else slice(0, 0)
        return obs[..., block].reshape(*obs.shape[:-1], self.static, WALL_SIZE)

    def pedestrian_slots(self, obs: FloatArray) -> FloatArray:
        """View of the pedestrian slots of a batch ``(..., size)`` as ``(..., P, 5)``."""
        block = self.block("pedestrians") if self.pedestrians else slice(0, 0)
        return obs[..., block].reshape(*obs.shape[:-1], self.pedestrians, SLOT_SIZE)

    @staticmethod
    def slot_position(slots: FloatArray) -> FloatArray:
        """Relative positions ``(..., K, 2)`` of slots from :meth:`slots`."""
        return slots[..., 0:2]

    @staticmethod
    def slot_velocity(slots: FloatArray) -> FloatArray:
        """Velocities ``(..., K, 2)`` of slots from :meth:`slots`."""
        return slots[..., 2:4]

    @staticmethod
    def slot_valid(slots: FloatArray) -> FloatArray:
        """Valid flags ``(..., K)`` (1.0 for a real neighbour) of slots from :meth:`slots`."""
        return slots[..., 4]

    def space(self, reach: float, horizon: float, velocity_bound: float,
              static_range: float | None = None, lidar_range: float = 0.0,
              pedestrian_range: float = 0.0) -> spaces.Box:
        """The observation Box: finite bounds, float32. ``reach`` bounds the leader's
        relative position (twice the arena's half size: the scene's span)."""
        low = np.empty(self.size, dtype=np.float32)
        low[self.own_velocity] = -velocity_bound
        low[self.leader_position] = -reach
        low[self.leader_velocity] = -velocity_bound
        slot_low = np.array([-horizon, -horizon, -velocity_bound, -velocity_bound, 0.0])
        end = self.neighbours_start + SLOT_SIZE * self.neighbours
        low[self.neighbours_start:end] = np.tile(slot_low, self.neighbours)
        high = -low
        high[self.neighbours_start + 4 : end : SLOT_SIZE] = 1.0
        if self.static:
            r = horizon if static_range is None else static_range
            block = self.block("static")
            low[block] = np.tile([-r, -r, 0.0], self.static)
            high[block] = np.tile([r, r, 1.0], self.static)
        if self.lidar:
            low[self.block("lidar")] = 0.0
            high[self.block("lidar")] = lidar_range
        if self.pedestrians:
            r, vb = pedestrian_range, velocity_bound
            block = self.block("pedestrians")
            low[block] = np.tile([-r, -r, -vb, -vb, 0.0], self.pedestrians)
            high[block] = np.tile([r, r, vb, vb, 1.0], self.pedestrians)
        if self.headings:
            for name in ("own_heading", "leader_heading", "neighbour_headings"):
                if self.neighbours or name != "neighbour_headings":
                    low[self.block(name)] = -1.0
                    high[self.block(name)] = 1.0
        if self.route:  # direction (2), length (1, bounded by ROUTE_REACH spans), flag (1)
            low[self.block("route")] = [-1.0, -1.0, 0.0, 0.0]
            high[self.block("route")] = [1.0, 1.0, ROUTE_REACH * reach, 1.0]
        return spaces.Box(low, high, dtype=np.float32)

    @functools.cached_property
    def noise_columns(self) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp],
                                     npt.NDArray[np.intp]]:
        """Where sensing noise is masked, as column indices ``(scaled, flags, zeroed)``: the
        noise of column ``scaled[i]`` is multiplied by the observation's ``flags[i]`` (a slot's
        position and velocity, or neighbour heading, by its valid flag), the noise of the
        ``zeroed`` columns (the valid flags themselves) is zero. Read off this layout's own
        slot views, so that :meth:`Observer._noise` masks a batch in two indexed operations."""
        cols = np.arange(self.size)[None]
        scaled: list[npt.NDArray[np.intp]] = []
        flags: list[npt.NDArray[np.intp]] = []
        zeroed: list[npt.NDArray[np.intp]] = []

        def scale(block: npt.NDArray[np.intp], flag: npt.NDArray[np.intp]) -> None:
            scaled.append(block.ravel())
            flags.append(np.broadcast_to(flag, block.shape).ravel())

        slots = self.slots(cols)[0]
        scale(slots[:, :4], slots[:, 4:5])
        zeroed.append(slots[:, 4])
        if self.static:
            static = self.static_slots(cols)[0]
            scale(static[:, :2], static[:, 2:3])
            zeroed.append(static[:, 2])
        if self.pedestrians:
            walkers = self.pedestrian_slots(cols)[0]
            scale(walkers[:, :4], walkers[:, 4:5])
            zeroed.append(walkers[:, 4])
        if self.headings and self.neighbours:
            scale(self.neighbour_headings(cols)[0], slots[:, 4:5])
        if self.route:
            zeroed.append(np.array([self.block("route").stop - 1]))
        return tuple(np.concatenate([*parts, np.empty(0, np.intp)]).astype(np.intp)
                     for parts in (scaled, flags, zeroed))  # type: ignore[return-value]

    def neighbour_headings(self, obs: FloatArray) -> FloatArray:
        """View of the neighbour headings of a batch ``(..., size)`` as ``(..., K, 2)``
        (zeros in empty slots); ``ValueError`` for a layout without headings."""
        if not self.headings:
            raise ValueError("this observation layout has no headings (a holonomic robot)")
        block = self.block("neighbour_headings") if self.neighbours else slice(0, 0)
        return obs[..., block].reshape(*obs.shape[:-1], self.neighbours, 2)


def nearest_neighbours(positions: FloatArray, horizon: float, k: int
                       ) -> tuple[npt.NDArray[np.intp], FloatArray]:
    """The ``k`` nearest other robots within ``horizon`` of every follower (robots 1..N-1).

    Args:
        positions: (N, 2) positions, the leader first.
        horizon: neighbour radius (m); a neighbour at exactly ``horizon`` counts.
        k: number of slots.

    Returns:
        ``(index, distance)`` of shape (N-1, k): robot indices nearest first (exact ties by
        index below ``KD_TREE_MIN_ROBOTS`` robots, in the KD-tree's order above), -1 and
        ``inf`` in empty slots. From ``KD_TREE_MIN_ROBOTS`` robots on, the compiled kernels
        search a grid of cells instead (``_compiled.nearest_grid``: the KD-tree's distances
        and order, bit for bit; a step with an exact tie falls back to the KD-tree). Robots
        at distance 0 (a follower itself, or one exactly on it) are never neighbours.
    """
    n = len(positions)
    followers = n - 1
    if k == 0 or followers == 0:
        return np.full((followers, k), -1, dtype=np.intp), np.full((followers, k), np.inf)
    compiled = kernels.compiled()
    if n < KD_TREE_MIN_ROBOTS and compiled is not None:
        return compiled.nearest(np.ascontiguousarray(positions, dtype=np.float64),
                                float(horizon), int(k))
    if compiled is not None:  # many robots: a grid of cells, declining exact ties
        status, index, distance = compiled.nearest_grid(
            np.ascontiguousarray(positions, dtype=np.float64), float(horizon), int(k))
        if status == 0:
            return index, distance
    if n < KD_TREE_MIN_ROBOTS:
        # x and y apart: (F, N) differences broadcast row by row (a trailing axis of 2 makes
        # numpy's inner loops two elements long, 4x slower at 19 robots); the squares are
        # those of p_j - p_i exactly (negation is exact), summed in the same order.
        dx = np.subtract.outer(positions[1:, 0], positions[:, 0])
        dy = np.subtract.outer(positions[1:, 1], positions[:, 1])
        dist = dx * dx
        dist += dy * dy
        np.sqrt(dist, out=dist)
        # self (distance 0) and far robots
        np.copyto(dist, np.inf, where=(dist <= 0.0) | (dist > horizon))
        width = min(k, n)
        order = dist.argsort(axis=1, kind="stable")[:, :width]
        nearest = dist.ravel()[order + _row_starts(followers, n)]
    else:
        # k + 1: the follower finds itself at distance 0 first. The query's rows are sorted,
        # so the zero distances (itself, and any robot exactly on it, which the all-pairs
        # branch excludes too) lead each row: skip them instead of sorting again.
        nearest, order = cKDTree(positions).query(positions[1:], k=k + 1,
                                                  distance_upper_bound=horizon * (1 + 1e-12))
        nearest = np.asarray(nearest).reshape(followers, k + 1)
        order = np.asarray(order).reshape(followers, k + 1)
        leading = (nearest <= 0.0).sum(axis=1)
        cols = np.minimum(leading[:, None] + np.arange(k), k)
        nearest = np.take_along_axis(nearest, cols, axis=1)
        order = np.take_along_axis(order, cols, axis=1)
        beyond = (leading[:, None] + np.arange(k) > k) | (nearest > horizon)
        nearest = np.where(beyond, np.inf, nearest)
        width = k
    found = np.where(np.isfinite(nearest), order, -1)
    if width == k:
        return found, nearest
    # Filled in place rather than padded (np.pad cost ~20 us a call, a third of a step).
    index = np.full((followers, k), -1, dtype=np.intp)
    distance = np.full((followers, k), np.inf)
    index[:, :width] = found
    distance[:, :width] = nearest
    return index, distance


@functools.lru_cache(maxsize=64)
def _row_starts(rows: int, width: int) -> npt.NDArray[np.intp]:
    """(rows, 1) flat offsets of each row of a (rows, width) array (a cached gather index)."""
    starts = (np.arange(rows, dtype=np.intp) * width)[:, None]
    starts.flags.writeable = False
    return starts


def rotation(heading: float) -> npt.NDArray[np.float64]:
    """The matrix (2, 2) taking world vectors (rows, ``v @ R``) into the frame whose x axis
    points along ``heading`` (rad): ``v_frame = v_world @ rotation(heading)``; its transpose
    goes back."""
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class Sensors:
    """What the sensors beyond the study's see: static geometry and the range sensor."""

    scene: Scene | None = None
    """The static scene (None: no static slots or lidar can be filled)."""
    static_range: float = 1.0
    """Static slots hold surface points within this distance (m)."""
    lidar_range: float = 3.0
    """Range (m) of the lidar; a ray that hits nothing reads this."""
    robot_radius: float = 0.036
    """Robots are discs of this radius for the lidar (m)."""
    leader_radius: float | None = None
    """A person leads: the leader is a disc of this radius for the lidar (m)."""
    pedestrian_radius: float = 0.22
    """Pedestrians are discs of this radius for the lidar (m)."""
    pedestrian_range: float = 3.0
    """Pedestrian slots hold the pedestrians within this distance (m)."""
    route_cell: float = ROUTE_CELL
    """Cell size (m) of the route sensing's grid."""


@dataclass(frozen=True)
class Crowd:
    """The pedestrians at one instant, for the observations."""

    positions: FloatArray
    """(P, 2) positions (m)."""
    velocities: FloatArray
    """(P, 2) velocities (m/s)."""


LIDAR_ROBOTS = 32
"""The lidar sees the nearest this-many other robots within its range (rays hit their discs)."""


def lidar_directions(rays: int) -> FloatArray:
    """Unit vectors (R, 2) of ``rays`` rays evenly spaced from the frame's x axis,
    counter-clockwise."""
    angles = [2 * math.pi * k / rays for k in range(rays)]
    return np.array([[math.cos(a), math.sin(a)] for a in angles]).reshape(-1, 2)


def build_observations(positions: FloatArray, velocities: FloatArray, layout: ObservationLayout,
                       horizon: float, velocity_bound: float, reach: float,
                       frame: npt.NDArray[np.float64] | None = None,
                       sensors: Sensors | None = None,
                       crowd: Crowd | None = None, headings: FloatArray | None = None
                       ) -> npt.NDArray[np.float32]:
    """Observations of every follower, one row each: ``(N-1, layout.size)`` float32.

    Args:
        positions: (N, 2) positions (m), the leader first.
        velocities: (N, 2) measured velocities (m/s).
        layout: the observation layout (K slots).
        horizon: neighbour radius (m).
        velocity_bound: velocities are clipped to ±this (m/s), keeping obs inside the Box.
        reach: bounds the leader's relative position (m; the scene's span).
        frame: a :func:`rotation` matrix; every vector is expressed in that frame (None: the
            world frame).
        sensors: the scene and ranges for the static slots and the lidar.
        crowd: the pedestrians, for the pedestrian slots and the lidar (None: none).
        headings: (N, 2) unit heading vectors, for a layout with headings.
    """
    n = len(positions)
    followers = n - 1
    world_positions = positions
    if layout.headings and headings is None:
        raise ValueError("this observation layout has heading blocks: give the headings")
    if frame is not None:
        # Distances do not change under a rotation, so the neighbour search and its order are
        # the same; rotating the inputs rotates every vector of the observation.
        positions = times_matrix(positions, frame)
        velocities = times_matrix(velocities, frame)
        if headings is not None:
            headings = times_matrix(headings, frame)
    compiled = kernels.compiled()
    if compiled is not None:  # the same bits in one loop (boids_env.kernels)
        obs = np.empty((followers, layout.size), dtype=np.float32)
        index = (nearest_neighbours(positions, horizon, layout.neighbours)[0]
                 if layout.neighbours else None)
        compiled.fill_observations(
            np.ascontiguousarray(positions, dtype=np.float64),
            np.ascontiguousarray(velocities, dtype=np.float64),
            np.empty((followers, 0), dtype=np.intp) if index is None else index,
            float(velocity_bound), float(reach), obs, layout.neighbours_start)
    else:
        obs, index = _study_blocks(positions, velocities, layout, horizon, velocity_bound,
                                   reach)
    if layout.headings:
        assert headings is not None
        _heading_blocks(obs, layout, headings, index)
    _sensed_blocks(obs, layout, world_positions, velocity_bound, frame, sensors, crowd)
    return obs


def _study_blocks(positions: FloatArray, velocities: FloatArray, layout: ObservationLayout,
                  horizon: float, velocity_bound: float, reach: float
                  ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.intp] | None]:
    """The numpy reference of the study's blocks (own velocity, leader position and velocity,
    neighbour slots) of every follower's observation, and the neighbour index (None without
    slots); the remaining blocks are left for the caller to fill."""
    n = len(positions)
    followers = n - 1
    # One feature table, a row per robot plus an all-zero row that empty slots point at:
    # position, velocity (clipped), valid flag. Slots are one gather from it.
    table = np.zeros((n + 1, SLOT_SIZE))
    table[:n, 0:2] = positions
    # clip as max then min (np.clip's wrapper costs more than both at these sizes)
    np.minimum(np.maximum(velocities, -velocity_bound, out=table[:n, 2:4]), velocity_bound,
               out=table[:n, 2:4])
    table[:n, 4] = 1.0
    obs = np.empty((followers, layout.size), dtype=np.float32)
    obs[:, layout.own_velocity] = table[1:n, 2:4]
    leader = positions[0] - positions[1:]
    obs[:, layout.leader_position] = np.minimum(np.maximum(leader, -reach, out=leader), reach,
                                                out=leader)
    obs[:, layout.leader_velocity] = table[0, 2:4]
    index = None
    if layout.neighbours:
        index, _ = nearest_neighbours(positions, horizon, layout.neighbours)
        gathered = table[index]  # (F, K, 5); an empty slot's -1 picks the all-zero last row
        # relative position (x and y apart: a trailing axis of 2 makes numpy's inner loops
        # short); an empty slot keeps +0.0; distances are <= horizon, so no clipping
        flag = gathered[..., 4]
        gathered[..., 0] -= positions[1:, 0:1] * flag
        gathered[..., 1] -= positions[1:, 1:2] * flag
        end = layout.neighbours_start + SLOT_SIZE * layout.neighbours
        obs[:, layout.neighbours_start:end] = gathered.reshape(followers, -1)
    return obs, index


def _heading_blocks(obs: npt.NDArray[np.float32], layout: ObservationLayout,
                    headings: FloatArray, index: npt.NDArray[np.intp] | None) -> None:
    """Fills the heading blocks of ``obs``: own, the leader's, each neighbour slot's."""
    n = len(headings)
    obs[:, layout.block("own_heading")] = headings[1:]
    obs[:, layout.block("leader_heading")] = headings[0]
    if index is not None:
        padded = np.zeros((n + 1, 2))  # an empty slot's -1 picks the zero last row
        padded[:n] = headings
        obs[:, layout.block("neighbour_headings")] = padded[index].reshape(n - 1, -1)


def _sensed_blocks(obs: npt.NDArray[np.float32], layout: ObservationLayout,
                   positions: FloatArray, velocity_bound: float,
                   frame: npt.NDArray[np.float64] | None, sensors: Sensors | None,
                   crowd: Crowd | None) -> None:
    """Fills the static slots, the lidar and the pedestrian slots of ``obs`` (world-frame
    ``positions`` (N, 2), the leader first)."""
    if layout.static or layout.lidar:
        if sensors is None or sensors.scene is None:
            raise ValueError("static slots and the lidar need the scene (Sensors)")
        if layout.static:
            obs[:, layout.block("static")] = _static_block(positions[1:], layout.static,
                                                           sensors, frame)
        if layout.lidar:
            obs[:, layout.block("lidar")] = _lidar_block(positions, layout.lidar, sensors,
                                                         frame, crowd)
    if layout.pedestrians:
        if sensors is None:
            raise ValueError("pedestrian slots need their range (Sensors)")
        obs[:, layout.block("pedestrians")] = _pedestrian_block(
            positions[1:], layout.pedestrians, sensors, velocity_bound, frame, crowd)
    if layout.route:
        if sensors is None or sensors.scene is None:
            raise ValueError("route sensing needs the scene (Sensors)")
        obs[:, layout.block("route")] = _route_block(positions, sensors, frame)


def _route_block(positions: FloatArray, sensors: Sensors,
                 frame: npt.NDArray[np.float64] | None) -> FloatArray:
    """(F, 4): each follower's route to the leader: direction in the frame, length (m, clipped
    to the block's bound), valid flag."""
    assert sensors.scene is not None
    grid = route_grid(sensors.scene, sensors.robot_radius, sensors.route_cell)
    direction, length, valid = sense_route(grid, positions)
    bound = ROUTE_REACH * sensors.scene.span
    return np.column_stack([_in_frame(direction, frame), np.minimum(length, bound), valid])


def _in_frame(v: FloatArray, frame: npt.NDArray[np.float64] | None) -> FloatArray:
    """``v @ frame`` for vectors (..., 2), elementwise (no BLAS call: its kernels differ by
    CPU in the last bit)."""
    if frame is None:
        return v
    x, y = v[..., 0], v[..., 1]
    return np.stack([x * frame[0, 0] + y * frame[1, 0], x * frame[0, 1] + y * frame[1, 1]],
                    axis=-1)


def _pedestrian_block(points: FloatArray, slots: int, sensors: Sensors, velocity_bound: float,
                      frame: npt.NDArray[np.float64] | None, crowd: Crowd | None
                      ) -> FloatArray:
    """(F, 5·P): each follower's nearest pedestrians within ``pedestrian_range``, nearest
    first: relative position, velocity (clipped), valid flag; empty slots all zero."""
    block = np.zeros((len(points), slots, SLOT_SIZE))
    if crowd is not None and len(crowd.positions):
        rel = crowd.positions[None, :, :] - points[:, None, :]  # (F, P, 2)
        dist = np.sqrt(rel[..., 0] * rel[..., 0] + rel[..., 1] * rel[..., 1])
        dist = np.where(dist <= sensors.pedestrian_range, dist, np.inf)
        order = dist.argsort(axis=1, kind="stable")[:, :slots]
        rows = np.arange(len(points))[:, None]
        near = dist[rows, order]
        valid = np.isfinite(near)
        k = order.shape[1]
        picked = rel[rows, order]
        vel = np.clip(crowd.velocities[order], -velocity_bound, velocity_bound)
        block[:, :k, 0:2] = _in_frame(picked, frame) * valid[..., None]
        block[:, :k, 2:4] = _in_frame(vel, frame) * valid[..., None]
        block[:, :k, 4] = valid
    return block.reshape(len(points), -1)


def _static_block(points: FloatArray, slots: int, sensors: Sensors,
                  frame: npt.NDArray[np.float64] | None) -> FloatArray:
    """(F, 3·M): the static slots of every follower (offsets in the frame, valid flags)."""
    assert sensors.scene is not None
    offsets, valid = sensors.scene.nearest_points(points, slots, sensors.static_range)
    compiled = kernels.compiled()
    if compiled is not None:  # the same products in one loop
        turned = frame is not None
        return compiled.static_block(offsets, valid, frame if turned else _NO_FRAME, turned)
    if frame is not None:
        offsets = times_matrix(offsets, frame)
    block = np.concatenate([offsets * valid[..., None], valid[..., None]], axis=2)
    return block.reshape(len(points), -1)


def _lidar_block(positions: FloatArray, rays: int, sensors: Sensors,
                 frame: npt.NDArray[np.float64] | None, crowd: Crowd | None = None
                 ) -> FloatArray:
    """(F, R): each follower's ranges (m) to static geometry, other robots, a person leader
    and pedestrians, rays evenly spaced in the observation's frame."""
    directions = lidar_directions(rays)
    if frame is not None:
        directions = times_matrix(directions, frame.T)  # the frame's axes in the world
    dirs = np.broadcast_to(directions, (len(positions) - 1, rays, 2))
    return _ranges_along(positions, dirs, sensors, crowd)


def lidar_scans(positions: FloatArray, rays: int, sensors: Sensors,
                headings: FloatArray | None = None) -> FloatArray:
    """(F, R): each follower's lidar ranges (m) along rays evenly spaced counter-clockwise
    from its *own* x axis (its heading, ``headings`` (N, 2) the robots' heading vectors
    (cos θ, sin θ); the world's x axis for robots without one), what its
    ``sensor_msgs/LaserScan`` carries; what the rays hit is the observation's lidar's."""
    assert sensors.scene is not None
    directions = lidar_directions(rays)
    dirs = np.broadcast_to(directions, (len(positions) - 1, rays, 2))
    if headings is not None:
        c, s = headings[1:, 0:1], headings[1:, 1:2]
        dirs = np.stack([c * dirs[..., 0] - s * dirs[..., 1],
                         s * dirs[..., 0] + c * dirs[..., 1]], axis=-1)
    return _ranges_along(positions, dirs, sensors, None)


def _ranges_along(positions: FloatArray, dirs: FloatArray, sensors: Sensors,
                  crowd: Crowd | None) -> FloatArray:
    """(F, R) ranges from each follower along its rays ``dirs`` (F, R, 2)."""
    assert sensors.scene is not None
    origins = positions[1:]
    ranges = sensors.scene.raycast(origins, dirs, sensors.lidar_range)
    k = min(LIDAR_ROBOTS, len(positions) - 1)
    if k:
        index, _ = nearest_neighbours(positions, sensors.lidar_range + sensors.robot_radius, k)
        centres = np.where((index >= 0)[..., None], positions[np.maximum(index, 0)], FAR_AWAY)
        radii = np.full(1, sensors.robot_radius)
        if sensors.leader_radius is not None:  # the person: a wider disc than a robot's
            radii = np.where(index == 0, sensors.leader_radius, sensors.robot_radius)[:, None]
        compiled = kernels.compiled()
        if compiled is not None and np.isfinite(dirs).all():  # the same ranges in one loop
            hit = compiled.ray_circles_nearest(
                np.ascontiguousarray(origins), np.ascontiguousarray(dirs),
                np.ascontiguousarray(centres),
                np.ascontiguousarray(np.broadcast_to(radii.reshape(-1, index.shape[1])
                                                     if radii.ndim > 1 else radii,
                                                     index.shape), dtype=np.float64))
            ranges = np.minimum(ranges, hit)
        else:
            hit = geo.ray_circles(origins[:, None, None, :], dirs[:, :, None, :],
                                  centres[:, None, :, :], radii)
            ranges = np.minimum(ranges, hit.min(axis=2))
    if crowd is not None and len(crowd.positions):
        hit = geo.ray_circles(origins[:, None, None, :], dirs[:, :, None, :],
                              crowd.positions[None, None, :, :],
                              np.full(1, sensors.pedestrian_radius))
        ranges = np.minimum(ranges, hit.min(axis=2))
    return np.minimum(ranges, sensors.lidar_range)


FAR_AWAY = 1e9
"""Where an empty neighbour entry of the lidar puts its disc (never hit)."""


class Observer:
    """Builds every follower's observation from the world's arrays: the env's and the ROS
    controller node's one source of observations.

    It holds the two pieces of state observations need: the leader frame's heading
    (``frame="leader"``) and the random stream of the opt-in sensing noise (``obs_noise``).

    Args:
        config: the env config (its ``observation`` section and the arena size).
    """

    def __init__(self, config: EnvConfig) -> None:
        obs = config.observation
        self.config = config
        self.layout = layout_of(config)
        scene = config.scene
        static_range = obs.horizon if obs.static_range is None else obs.static_range
        self.reach = scene.span
        sc = config.scenario
        self.sensors = Sensors(scene, static_range, obs.lidar_range, config.world.robot_radius,
                               None if sc.leader == "robot" else sc.person_radius,
                               sc.person_radius, obs.pedestrian_range, obs.route_cell)
        self.space = self.make_space()
        self.heading = INITIAL_HEADING
        self._rng: np.random.Generator | None = None
        self._leader_velocity: npt.NDArray[np.float64] | None = None
        self.leader_hidden: npt.NDArray[np.bool_] | None = None
        """With ``route_leader``: which followers did not see the leader in the last call
        (F,), whose leader blocks were read along the route; None otherwise (and before the
        first call of an episode)."""

    def make_space(self) -> spaces.Box:
        """A new observation Box (one object per agent: seeding one must not reseed
        another's)."""
        obs = self.config.observation
        return self.layout.space(self.reach, obs.horizon, obs.velocity_bound,
                                 self.sensors.static_range, obs.lidar_range,
                                 obs.pedestrian_range)

    def reset(self, rng: np.random.Generator | None = None,
              heading: float = INITIAL_HEADING) -> None:
        """Starts an episode: ``rng`` draws the sensing noise; ``heading`` (rad) is the leader
        frame's until the leader moves (where the leader faces: its path's first move)."""
        self.heading = float(heading)
        self._rng = rng
        self._leader_velocity = None
        self.leader_hidden = None

    @property
    def frame(self) -> npt.NDArray[np.float64] | None:
        """The current :func:`rotation` (None in the world frame)."""
        return rotation(self.heading) if self.config.observation.frame == "leader" else None

    def to_world(self, actions: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Actions (F, 2) in the observation frame of the last call, in the world frame; with
        ``relative_actions`` each is first added to the leader velocity its follower observed
        in that call."""
        if self.config.observation.relative_actions:
            if self._leader_velocity is None or len(self._leader_velocity) != len(actions):
                raise RuntimeError("relative_actions: observe the followers before turning "
                                   "their actions into commands")
            actions = actions + self._leader_velocity
        frame = self.frame
        return actions if frame is None else times_matrix(actions, frame.T)

    def __call__(self, positions: FloatArray, velocities: FloatArray,
                 crowd: Crowd | None = None, headings: FloatArray | None = None
                 ) -> npt.NDArray[np.float32]:
        """Observations (N-1, size) of the robots' positions and velocities (N, 2), leader
        first, the pedestrians', and the robots' unit heading vectors (N, 2) for robots with a
        heading. In the leader frame the frame's heading first follows the leader's
        velocity."""
        cfg = self.config.observation
        if cfg.frame == "leader":
            self.follow(velocities)
        obs = build_observations(positions, velocities, self.layout, cfg.horizon,
                                 cfg.velocity_bound, self.reach, self.frame, self.sensors,
                                 crowd, headings)
        if cfg.route_leader:  # the leader out of sight: as reached along its route
            self.leader_hidden = hidden = ~leader_in_sight(self._route_grid(), positions)
            rows = np.flatnonzero(hidden)
            if len(rows):
                route = obs[rows, self.layout.block("route")].astype(np.float64)
                obs[rows, self.layout.leader_position] = np.minimum(
                    np.maximum(route[:, 0:2] * route[:, 2:3], -self.reach), self.reach)
                # its motion as seen along that way: the leader's speed along the route
                seen = obs[rows, self.layout.leader_velocity].astype(np.float64)
                speed = np.sqrt(seen[:, 0] * seen[:, 0] + seen[:, 1] * seen[:, 1])
                obs[rows, self.layout.leader_velocity] = speed[:, None] * route[:, 0:2]
        compiled = kernels.compiled()
        clipped = False
        if cfg.obs_noise > 0:
            if self._rng is None:
                raise RuntimeError("Observer.reset(rng) must give a generator for obs_noise")
            if compiled is not None:  # the masking, the sum and the clip in one loop
                scaled, flags, zeroed = self.layout.noise_columns
                obs = compiled.noisy_observations(
                    obs, self._rng.normal(0.0, cfg.obs_noise, obs.shape), scaled, flags,
                    zeroed, self.space.low, self.space.high)
                clipped = True
            else:
                obs = obs + self._noise(obs, cfg.obs_noise)
        if not clipped and (cfg.obs_noise > 0 or cfg.frame != "world"):
            if obs.dtype == np.float32:  # this call's own array (no noise added): in place
                np.clip(obs, self.space.low, self.space.high, out=obs)
            else:
                obs = np.clip(obs, self.space.low, self.space.high).astype(np.float32)
        if cfg.relative_actions:
            self._leader_velocity = obs[:, self.layout.leader_velocity].astype(np.float64)
        return obs

    def follow(self, velocities: FloatArray) -> None:
        """Turns the leader frame's heading to the leader's velocity (the first row of
        ``velocities``) when the leader moves fast enough to have one."""
        vx, vy = float(velocities[0][0]), float(velocities[0][1])
        if math.hypot(vx, vy) >= HEADING_MIN_SPEED:
            self.heading = math.atan2(vy, vx)

    def _route_grid(self) -> RouteGrid:
        assert self.sensors.scene is not None
        return route_grid(self.sensors.scene, self.sensors.robot_radius, self.sensors.route_cell)

    def _noise(self, obs: npt.NDArray[np.float32], std: float) -> FloatArray:
        """Sensing noise for ``obs``: Gaussian on every position, velocity and range, none on
        valid flags or in empty slots."""
        assert self._rng is not None
        noise = self._rng.normal(0.0, std, obs.shape)
        scaled, flags, zeroed = self.layout.noise_columns
        noise[:, scaled] *= obs[:, flags]  # float64 noise times a float32 flag of 0 or 1
        noise[:, zeroed] = 0.0  # the valid flags stay exact
        return noise


def layout_of(config: EnvConfig) -> ObservationLayout:
    """The observation layout an env config gives (its resolved sensing fields)."""
    obs = config.observation
    return ObservationLayout(obs.neighbours, config.static_slots, obs.lidar_rays,
                             pedestrians=config.pedestrian_slots,
                             headings=config.world.drive == "unicycle",
                             route=obs.route_sensing)
