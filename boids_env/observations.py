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
original controller. Everything here is a pure function of numpy arrays (no physics).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from scipy.spatial import cKDTree

FloatArray = npt.NDArray[np.floating]

SLOT_SIZE = 5
KD_TREE_MIN_ROBOTS = 96
"""From this group size on, neighbours are found with a KD-tree instead of all pairs
(measured: all-pairs wins below about 100 robots)."""


@dataclass(frozen=True)
class ObservationLayout:
    """Named slices into one follower's observation vector, and views of a batch of them."""

    neighbours: int
    """K, the number of neighbour slots."""

    own_velocity = slice(0, 2)
    leader_position = slice(2, 4)
    leader_velocity = slice(4, 6)
    neighbours_start = 6

    @property
    def size(self) -> int:
        """Length of one observation vector."""
        return self.neighbours_start + SLOT_SIZE * self.neighbours

    def slots(self, obs: FloatArray) -> FloatArray:
        """View of the neighbour slots of a batch ``(..., size)`` as ``(..., K, 5)``."""
        return obs[..., self.neighbours_start:].reshape(*obs.shape[:-1], self.neighbours,
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
        low[self.neighbours_start:] = np.tile(slot_low, self.neighbours)
        high = -low
        high[self.neighbours_start + 4 :: SLOT_SIZE] = 1.0
        return spaces.Box(low, high, dtype=np.float32)


def nearest_neighbours(positions: FloatArray, horizon: float, k: int
                       ) -> tuple[npt.NDArray[np.intp], FloatArray]:
    """The ``k`` nearest other robots within ``horizon`` of every follower (robots 1..N-1).

    Args:
        positions: (N, 2) positions, the leader first.
        horizon: neighbour radius (m); a neighbour at exactly ``horizon`` counts.
        k: number of slots.

    Returns:
        ``(index, distance)`` of shape (N-1, k): robot indices nearest first (ties by index),
        -1 and ``inf`` in empty slots.
    """
    n = len(positions)
    followers = n - 1
    if k == 0 or followers == 0:
        return np.full((followers, k), -1, dtype=np.intp), np.full((followers, k), np.inf)
    if n < KD_TREE_MIN_ROBOTS:
        diff = positions[None, :, :] - positions[1:, None, :]
        dist = np.sqrt(np.einsum("fnd,fnd->fn", diff, diff))
        dist[(dist <= 0.0) | (dist > horizon)] = np.inf  # self (distance 0) and far robots
        order = np.argsort(dist, axis=1, kind="stable")[:, :k]
        nearest = dist[np.arange(followers)[:, None], order]
        width = order.shape[1]
    else:
        # k + 1: the follower finds itself at distance 0 first.
        nearest, order = cKDTree(positions).query(positions[1:], k=k + 1,
                                                  distance_upper_bound=horizon * (1 + 1e-12))
        nearest = np.asarray(nearest).reshape(followers, k + 1)
        order = np.asarray(order).reshape(followers, k + 1)
        bad = (nearest <= 0.0) | (nearest > horizon)
        nearest = np.where(bad, np.inf, nearest)
        resort = np.argsort(nearest, axis=1, kind="stable")[:, :k]
        nearest = np.take_along_axis(nearest, resort, axis=1)
        order = np.take_along_axis(order, resort, axis=1)
        width = k
    index = np.where(np.isfinite(nearest), order, -1).astype(np.intp)
    if width < k:  # fewer robots than slots
        pad = k - width
        index = np.pad(index, ((0, 0), (0, pad)), constant_values=-1)
        nearest = np.pad(nearest, ((0, 0), (0, pad)), constant_values=np.inf)
    return index, nearest


def build_observations(positions: FloatArray, velocities: FloatArray, layout: ObservationLayout,
                       horizon: float, velocity_bound: float, arena_half_size: float
                       ) -> npt.NDArray[np.float32]:
    """Observations of every follower, one row each: ``(N-1, layout.size)`` float32.

    Args:
        positions: (N, 2) positions (m), the leader first.
        velocities: (N, 2) measured velocities (m/s).
        layout: the observation layout (K slots).
        horizon: neighbour radius (m).
        velocity_bound: velocities are clipped to ±this (m/s), keeping obs inside the Box.
        arena_half_size: bounds the leader's relative position.
    """
    n = len(positions)
    followers = n - 1
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
        gathered = table[np.where(index >= 0, index, n)]  # (F, K, 5)
        # relative position; distances are <= horizon, so no clipping is needed
        gathered[..., 0:2] -= positions[1:, None, :] * gathered[..., 4:5]
        obs[:, layout.neighbours_start:] = gathered.reshape(followers, -1)
    return obs
