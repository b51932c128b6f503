"""Building the observations: the study's blocks in one kernel call (or numpy), then each
other block's fill from the block table, and :class:`Observer`, the one place that builds
observations (the env and the ROS controller node use it)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from boids_env import kernels
from boids_env.observations.blocks import Inputs
from boids_env.observations.layout import ObservationLayout, layout_of
from boids_env.observations.sensing import (
    SLOT_SIZE,
    Crowd,
    FloatArray,
    Sensors,
    nearest_neighbours,
    rotation,
)
from boids_env.vectors import times_matrix
from boids_env.world.route import RouteGrid, leader_in_sight, route_grid

if TYPE_CHECKING:
    from boids_env.config import EnvConfig

HEADING_MIN_SPEED = 0.05
"""The leader frame follows the leader's measured velocity from this speed (m/s) on; below it
(start-up, corners) the last heading is kept."""
INITIAL_HEADING = math.pi / 2
"""Default heading (rad) of the leader frame before the leader first moves: +y, the first leg
of the study's square (the env passes its leader's own first direction)."""


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
    fills = layout.fills
    if fills:  # every other block from its spec (boids_env.observations.blocks)
        inputs = Inputs(world_positions, headings, index, frame, sensors, crowd,
                        velocity_bound, reach)
        for fill, block, slots in fills:
            obs[:, block] = fill(inputs, slots)
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
                               sc.leader_radius,
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
        # float32, but float64 for a moment once numpy adds the noise (clipped back below)
        obs: npt.NDArray[np.floating[Any]] = build_observations(
            positions, velocities, self.layout, cfg.horizon,
            cfg.velocity_bound, self.reach, self.frame, self.sensors, crowd, headings)
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
        return cast("npt.NDArray[np.float32]", obs)  # float32 again: the clip's astype

    def follow(self, velocities: FloatArray) -> None:
        """Turns the leader frame's heading to the leader's velocity (the first row of
        ``velocities``) when the leader moves fast enough to have one."""
        vx, vy = float(velocities[0][0]), float(velocities[0][1])
        if math.hypot(vx, vy) >= HEADING_MIN_SPEED:
            self.heading = math.atan2(vy, vx)

    def _route_grid(self) -> RouteGrid:
        assert self.sensors.scene is not None
        return route_grid(self.sensors.scene, self.sensors.robot_radius, self.sensors.route_cell)

    def _noise(self, obs: npt.NDArray[np.floating[Any]], std: float) -> FloatArray:
        """Sensing noise for ``obs``: Gaussian on every position, velocity and range, none on
        valid flags or in empty slots."""
        assert self._rng is not None
        noise = self._rng.normal(0.0, std, obs.shape)
        scaled, flags, zeroed = self.layout.noise_columns
        noise[:, scaled] *= obs[:, flags]  # float64 noise times a float32 flag of 0 or 1
        noise[:, zeroed] = 0.0  # the valid flags stay exact
        return noise

