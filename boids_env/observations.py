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

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from scipy.spatial import cKDTree

from boids_env.vectors import times_matrix

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
KD_TREE_MIN_ROBOTS = 96
"""From this group size on, neighbours are found with a KD-tree instead of all pairs
(measured: all-pairs wins below about 100 robots)."""


@dataclass(frozen=True)
class ObservationLayout:
    """Named slices into one follower's observation vector, and views of a batch of them."""

    neighbours: int
    """K, the number of neighbour slots."""
    walls: bool = False
    """Whether the wall slot follows the neighbour slots (``sense_walls``)."""

    own_velocity = slice(0, 2)
    leader_position = slice(2, 4)
    leader_velocity = slice(4, 6)
    neighbours_start = 6

    @property
    def size(self) -> int:
        """Length of one observation vector."""
        return self.neighbours_start + SLOT_SIZE * self.neighbours + WALL_SIZE * self.walls

    @property
    def wall(self) -> slice:
        """The wall slot: offset (2) to the nearest point of the walls, valid flag (1)."""
        if not self.walls:
            raise ValueError("this layout has no wall slot (sense_walls=False)")
        return slice(self.size - WALL_SIZE, self.size)

    @classmethod
    def for_size(cls, size: int) -> ObservationLayout:
        """The layout of an observation vector of ``size`` (a wall slot of 3 never divides
        into the 5-wide neighbour slots, so the size tells both)."""
        rest = size - cls.neighbours_start
        walls = rest % SLOT_SIZE == WALL_SIZE
        if rest < 0 or rest % SLOT_SIZE not in (0, WALL_SIZE):
            raise ValueError(f"no observation layout has size {size}")
        return cls((rest - WALL_SIZE * walls) // SLOT_SIZE, walls)

    def slots(self, obs: FloatArray) -> FloatArray:
        """View of the neighbour slots of a batch ``(..., size)`` as ``(..., K, 5)``."""
        end = self.neighbours_start + SLOT_SIZE * self.neighbours
        return obs[..., self.neighbours_start:end].reshape(*obs.shape[:-1], self.neighbours,
                                                           SLOT_SIZE)

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

    def space(self, arena_half_size: float, horizon: float, velocity_bound: float) -> spaces.Box:
        """The observation Box: finite bounds, float32."""
        low = np.empty(self.size, dtype=np.float32)
        low[self.own_velocity] = -velocity_bound
        low[self.leader_position] = -2 * arena_half_size
        low[self.leader_velocity] = -velocity_bound
        slot_low = np.array([-horizon, -horizon, -velocity_bound, -velocity_bound, 0.0])
        end = self.neighbours_start + SLOT_SIZE * self.neighbours
        low[self.neighbours_start:end] = np.tile(slot_low, self.neighbours)
        high = -low
        high[self.neighbours_start + 4 : end : SLOT_SIZE] = 1.0
        if self.walls:
            low[self.wall] = [-horizon, -horizon, 0.0]
            high[self.wall] = [horizon, horizon, 1.0]
        return spaces.Box(low, high, dtype=np.float32)


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
        ``inf`` in empty slots. Robots at distance 0 (a follower itself, or one exactly on it)
        are never neighbours.
    """
    n = len(positions)
    followers = n - 1
    if k == 0 or followers == 0:
        return np.full((followers, k), -1, dtype=np.intp), np.full((followers, k), np.inf)
    if n < KD_TREE_MIN_ROBOTS:
        diff = positions[None, :, :] - positions[1:, None, :]
        dist = np.sqrt(np.einsum("fnd,fnd->fn", diff, diff))
        dist[(dist <= 0.0) | (dist > horizon)] = np.inf  # self (distance 0) and far robots
        width = min(k, n)
        order = np.argsort(dist, axis=1, kind="stable")[:, :width]
        nearest = np.take_along_axis(dist, order, axis=1)
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
    # Filled in place rather than padded (np.pad cost ~20 us a call, a third of a step).
    index = np.full((followers, k), -1, dtype=np.intp)
    distance = np.full((followers, k), np.inf)
    index[:, :width] = np.where(np.isfinite(nearest), order, -1)
    distance[:, :width] = nearest
    return index, distance


def rotation(heading: float) -> npt.NDArray[np.float64]:
    """The matrix (2, 2) taking world vectors (rows, ``v @ R``) into the frame whose x axis
    points along ``heading`` (rad): ``v_frame = v_world @ rotation(heading)``; its transpose
    goes back."""
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[c, -s], [s, c]])


def build_observations(positions: FloatArray, velocities: FloatArray, layout: ObservationLayout,
                       horizon: float, velocity_bound: float, arena_half_size: float,
                       frame: npt.NDArray[np.float64] | None = None
                       ) -> npt.NDArray[np.float32]:
    """Observations of every follower, one row each: ``(N-1, layout.size)`` float32.

    Args:
        positions: (N, 2) positions (m), the leader first.
        velocities: (N, 2) measured velocities (m/s).
        layout: the observation layout (K slots).
        horizon: neighbour radius (m).
        velocity_bound: velocities are clipped to ±this (m/s), keeping obs inside the Box.
        arena_half_size: bounds the leader's relative position.
        frame: a :func:`rotation` matrix; every vector is expressed in that frame (None: the
            world frame).
    """
    n = len(positions)
    followers = n - 1
    world_positions = positions
    if frame is not None:
        # Distances do not change under a rotation, so the neighbour search and its order are
        # the same; rotating the inputs rotates every vector of the observation.
        positions = times_matrix(positions, frame)
        velocities = times_matrix(velocities, frame)
    # One feature table, a row per robot plus an all-zero row that empty slots point at:
    # position, velocity (clipped), valid flag. Slots are one gather from it.
    table = np.zeros((n + 1, SLOT_SIZE))
    table[:n, 0:2] = positions
    np.clip(velocities, -velocity_bound, velocity_bound, out=table[:n, 2:4])
    table[:n, 4] = 1.0
    obs = np.empty((followers, layout.size), dtype=np.float32)
    obs[:, layout.own_velocity] = table[1:n, 2:4]
    reach = 2 * arena_half_size
    obs[:, layout.leader_position] = np.clip(positions[0] - positions[1:], -reach, reach)
    obs[:, layout.leader_velocity] = table[0, 2:4]
    if layout.neighbours:
        index, _ = nearest_neighbours(positions, horizon, layout.neighbours)
        gathered = table[index]  # (F, K, 5); an empty slot's -1 picks the all-zero last row
        # relative position; distances are <= horizon, so no clipping is needed
        gathered[..., 0:2] -= positions[1:, None, :] * gathered[..., 4:5]
        end = layout.neighbours_start + SLOT_SIZE * layout.neighbours
        obs[:, layout.neighbours_start:end] = gathered.reshape(followers, -1)
    if layout.walls:
        offset = nearest_wall(world_positions[1:], arena_half_size)
        near = np.linalg.norm(offset, axis=1) <= horizon
        if frame is not None:
            offset = times_matrix(offset, frame)
        obs[:, layout.wall] = np.column_stack([offset * near[:, None], near])
    return obs


def nearest_wall(positions: FloatArray, arena_half_size: float) -> FloatArray:
    """Offset (m) from each position (F, 2) to the nearest point of the square arena's walls
    (their inner faces at ±arena_half_size): along one axis, towards the closest wall."""
    gaps = np.concatenate([arena_half_size - positions, arena_half_size + positions], axis=1)
    side = np.argmin(gaps, axis=1)  # 0: +x wall, 1: +y, 2: -x, 3: -y
    distance = gaps[np.arange(len(positions)), side]
    direction = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])[side]
    return direction * distance[:, None]


class Observer:
    """Builds every follower's observation from the world's arrays: the env's and the ROS
    controller node's one source of observations.

    It holds the two pieces of state observations need: the leader frame's heading
    (``frame="leader"``) and the random stream of the opt-in sensing noise (``obs_noise``).

    Args:
        config: the env config (its ``observation`` section and the arena size).
    """

    def __init__(self, config: EnvConfig) -> None:
        obs, world = config.observation, config.world
        self.config = config
        self.layout = ObservationLayout(obs.neighbours, obs.sense_walls)
        self.space = self.layout.space(world.arena_half_size, obs.horizon, obs.velocity_bound)
        self.heading = INITIAL_HEADING
        self._rng: np.random.Generator | None = None
        self._leader_velocity: npt.NDArray[np.float64] | None = None

    def reset(self, rng: np.random.Generator | None = None,
              heading: float = INITIAL_HEADING) -> None:
        """Starts an episode: ``rng`` draws the sensing noise; ``heading`` (rad) is the leader
        frame's until the leader moves (where the leader faces: its path's first move)."""
        self.heading = float(heading)
        self._rng = rng
        self._leader_velocity = None

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

    def __call__(self, positions: FloatArray, velocities: FloatArray
                 ) -> npt.NDArray[np.float32]:
        """Observations (N-1, size) of the robots' positions and velocities (N, 2), leader
        first. In the leader frame the heading first follows the leader's velocity."""
        cfg, world = self.config.observation, self.config.world
        if cfg.frame == "leader":
            vx, vy = float(velocities[0][0]), float(velocities[0][1])
            if math.hypot(vx, vy) >= HEADING_MIN_SPEED:
                self.heading = math.atan2(vy, vx)
        obs = build_observations(positions, velocities, self.layout, cfg.horizon,
                                 cfg.velocity_bound, world.arena_half_size, self.frame)
        if cfg.obs_noise > 0:
            if self._rng is None:
                raise RuntimeError("Observer.reset(rng) must give a generator for obs_noise")
            noise = self._rng.normal(0.0, cfg.obs_noise, obs.shape)
            slots = self.layout.slots(noise)
            valid = self.layout.slot_valid(self.layout.slots(obs))
            slots[..., :4] *= valid[..., None]
            slots[..., 4] = 0.0
            if self.layout.walls:
                wall = noise[:, self.layout.wall]
                wall[:, :2] *= obs[:, self.layout.wall][:, 2:3]
                wall[:, 2] = 0.0
                noise[:, self.layout.wall] = wall
            obs = obs + noise
        if cfg.obs_noise > 0 or cfg.frame != "world":
            obs = np.clip(obs, self.space.low, self.space.high).astype(np.float32)
        if cfg.relative_actions:
            self._leader_velocity = obs[:, self.layout.leader_velocity].astype(np.float64)
        return obs
