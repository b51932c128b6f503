"""What the followers sense, as numpy arrays: the neighbour search, the frames, and the
static, range-sensor, pedestrian and route blocks' values (no physics, no layout).

The block table (:mod:`boids_env.observations.blocks`) calls these to fill its blocks; the
compiled kernels (:mod:`boids_env._compiled`) compute the same bits in one loop where
they are loaded.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from boids_env import kernels
from boids_env.vectors import times_matrix
from boids_env.world import geometry as geo
from boids_env.world.route import ROUTE_CELL, route_grid, sense_route
from boids_env.world.scene import Scene

FloatArray = npt.NDArray[np.float64]

SLOT_SIZE = 5
"""Values in a neighbour or pedestrian slot: relative position (2), velocity (2), flag (1)."""
WALL_SIZE = 3
"""Values in a static slot: offset to the surface point (2), valid flag (1)."""
ROUTE_REACH = 8.0
"""The ``route`` block's length is clipped to this many times the scene's span (a route
winds, and its wall penalty lengthens it)."""
KD_TREE_MIN_ROBOTS = 96
"""From this group size on, neighbours are found with a KD-tree instead of all pairs
(measured: all-pairs wins below about 100 robots)."""
_NO_FRAME = np.eye(2)
"""The frame the compiled static block is given in the world frame (not applied)."""


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



def route_block(positions: FloatArray, sensors: Sensors,
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


def pedestrian_block(points: FloatArray, slots: int, sensors: Sensors, velocity_bound: float,
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


def static_block(points: FloatArray, slots: int, sensors: Sensors,
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


def lidar_block(positions: FloatArray, rays: int, sensors: Sensors,
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

