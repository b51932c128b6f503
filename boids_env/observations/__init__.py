"""The named observation layout, neighbour search and observation building.

Per follower, one float32 vector of named blocks, world frame, metres and m/s. Each block is
one :class:`~boids_env.observations.blocks.BlockSpec` of the table
:data:`~boids_env.observations.blocks.SPECS` (its size, bounds, fill, noise mask and
meaning); the layout, the observation Box, the noise masks, the saved layouts, the fill loop
and the reference page all read that table. The study's blocks come first at fixed
indices: own velocity (2), the leader's relative position (2) and velocity (2), and K
neighbour slots of 5 (relative position, velocity, valid flag; an empty slot all zero).

Every other block is appended after them, in the table's order: the static slots, the lidar,
the pedestrian slots, for robots with a heading (``drive="unicycle"``) ``own_heading``,
``leader_heading`` and ``neighbour_headings`` (unit vectors, so they turn with the frame like
every other vector), and the route. An opt-in block therefore never moves a block the
study's layout has.

Neighbours are the other robots j with 0 < |p_j − p_i| ≤ horizon, the leader included, as in the
original controller.

Frames: by default (``frame="world"``, the study's) every vector is in the world frame. With
``frame="leader"`` (opt-in) every vector is expressed in the leader's heading frame (x forward
along the leader's motion, y to its left), and actions are read in the same frame, so a
formation learned relative to the leader holds on any path. :class:`Observer` is the one place
that builds observations (the env and the ROS controller node use it); everything else here is
a pure function of numpy arrays (no physics).

The modules: :mod:`~boids_env.observations.blocks` (the block table),
:mod:`~boids_env.observations.layout` (:class:`ObservationLayout`, :func:`layout_of`),
:mod:`~boids_env.observations.sensing` (the neighbour search and the sensed blocks' values),
:mod:`~boids_env.observations.observer` (:func:`build_observations`, :class:`Observer`).
"""

from __future__ import annotations

from boids_env.observations.blocks import (
    BLOCKS,
    BlockSpec,
    Inputs,
    LayoutParameter,
    Ranges,
    interface_fields,
    parameters,
    specs,
)
from boids_env.observations.layout import ObservationLayout, layout_of
from boids_env.observations.observer import (
    HEADING_MIN_SPEED,
    INITIAL_HEADING,
    Observer,
    build_observations,
)
from boids_env.observations.sensing import (
    FAR_AWAY,
    KD_TREE_MIN_ROBOTS,
    LIDAR_ROBOTS,
    ROUTE_REACH,
    SLOT_SIZE,
    WALL_SIZE,
    Crowd,
    FloatArray,
    Sensors,
    lidar_directions,
    lidar_scans,
    nearest_neighbours,
    rotation,
)

__all__ = [
    "BLOCKS", "FAR_AWAY", "HEADING_MIN_SPEED", "INITIAL_HEADING", "KD_TREE_MIN_ROBOTS",
    "LIDAR_ROBOTS", "ROUTE_REACH", "SLOT_SIZE", "WALL_SIZE", "BlockSpec", "Crowd",
    "FloatArray", "Inputs", "LayoutParameter", "ObservationLayout", "Observer", "Ranges",
    "Sensors", "build_observations", "interface_fields", "layout_of", "lidar_directions",
    "lidar_scans", "nearest_neighbours", "parameters", "rotation", "specs",
]
