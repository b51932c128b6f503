"""One spec per observation block, in one table (:data:`SPECS`) that everything else loops over.

A block's facts are in its :class:`BlockSpec` and nowhere else: its width and how many slots
a layout gives it, its bounds, how it is filled, where its noise is masked, the config field
that switches it on and the fields that fix its meaning, and its line on the reference page.
:class:`~boids_env.observations.layout.ObservationLayout` (sizes, slices, the Box, the noise
columns, the saved block list), :func:`~boids_env.observations.observer.build_observations`
(the fill loop), the model cards' layout reasons, the trained interface and the reference
page read this table. Adding a block is one more entry at the end of :data:`SPECS` (a new
block never moves an old one: saved models' layouts keep their meaning) and its enabling
field in the config; ``docs/snippets/new_block.py`` is a tested example.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from boids_env.observations.sensing import (
    ROUTE_REACH,
    SLOT_SIZE,
    WALL_SIZE,
    Crowd,
    FloatArray,
    Sensors,
    lidar_block,
    pedestrian_block,
    route_block,
    static_block,
)
from boids_env.world.route import SIZE as ROUTE_SIZE

if TYPE_CHECKING:
    from boids_env.config import EnvConfig


@dataclass(frozen=True)
class Ranges:
    """What bounds the observation's values (the config's ranges, resolved)."""

    reach: float
    """Bound of the leader's relative position (m; the scene's span)."""
    horizon: float
    """Neighbour radius (m)."""
    velocity_bound: float
    """Velocities are clipped to ±this (m/s)."""
    static_range: float
    """Static slots hold surface points within this distance (m)."""
    lidar_range: float
    """Range of the lidar (m)."""
    pedestrian_range: float
    """Pedestrian slots hold the pedestrians within this distance (m)."""


@dataclass(slots=True)
class Inputs:
    """What a block's fill reads: the arrays of one call of
    :func:`~boids_env.observations.observer.build_observations`."""

    positions: FloatArray
    """(N, 2) world-frame positions (m), the leader first."""
    headings: FloatArray | None
    """(N, 2) unit heading vectors in the observation's frame (None: robots without)."""
    index: npt.NDArray[np.intp] | None
    """(N-1, K) each follower's neighbour slots' robot indices (-1: empty; None: no slots)."""
    frame: npt.NDArray[np.float64] | None
    """The observation's :func:`~boids_env.observations.sensing.rotation` (None: world)."""
    sensors: Sensors | None
    """The scene and ranges of the sensors beyond the study's."""
    crowd: Crowd | None
    """The pedestrians (None: none)."""
    velocity_bound: float
    """Velocities are clipped to ±this (m/s)."""
    reach: float
    """Bound of the leader's relative position (m)."""


Fill = Callable[[Inputs, int], "npt.ArrayLike"]
"""A block's fill: its values (F, width·slots) from the inputs and its number of slots."""
Reason = Callable[[int, int, "EnvConfig", "str | None"], str]
"""Why a trained layout's value of a parameter does not fit an env's: ``(trained, env,
config, trained_for)``; ``trained_for`` names the model's robots (its card), or None."""


@dataclass(frozen=True)
class LayoutParameter:
    """A parameter of :class:`~boids_env.observations.layout.ObservationLayout`: what a
    config switches on (a flag) or how many slots it asks for (a count)."""

    name: str
    """The layout's field (``layout.neighbours``) and keyword (``ObservationLayout(...)``)."""
    of_config: Callable[[EnvConfig], int | bool]
    """Its value in an env config (:func:`~boids_env.observations.layout.layout_of`)."""
    flag: bool = False
    """True: on or off (``bool``); False: a count of slots (a non-negative ``int``)."""
    what: str = ""
    """What it counts, for the default :attr:`reason` (``"lidar rays (lidar_rays)"``)."""
    reason: Reason | None = None
    """Why a model trained with another value does not fit (None: ``"trained with {t}
    {what}; this env has {e}"``, or for a flag ``"trained with(out) {what}; this env has it
    on (off)"``)."""

    def differs(self, trained: int, env: int, config: EnvConfig,
                trained_for: str | None = None) -> str:
        """The phrase saying that a model's layout has ``trained`` where ``env`` has ``env``."""
        if self.reason is not None:
            return self.reason(trained, env, config, trained_for)
        if self.flag:
            return (f"trained {'with' if trained else 'without'} {self.what}; this env has it "
                    f"{'on' if env else 'off'}")
        return f"trained with {trained} {self.what}; this env has {env}"


@dataclass(frozen=True)
class BlockSpec:
    """Everything about one observation block.

    A block is ``slots`` slots of ``width`` values. Its noise (``obs_noise``) is Gaussian on
    every value, times the slot's valid flag on the ``masked`` columns and zero on the
    ``flag`` column itself, so a flag stays exactly 0 or 1 and an empty slot stays zero.
    """

    name: str
    """The block's name (``layout.block(name)``, the saved layouts' names)."""
    width: int
    """Values per slot."""
    doc: str
    """One line for the reference page: what a slot holds, with units."""
    bounds: Callable[[Ranges], tuple[Sequence[float], Sequence[float]]]
    """One slot's ``(low, high)``, column by column, under the config's ranges."""
    parameter: LayoutParameter | None = None
    """The layout parameter this block brings (None: always there, or sized by another's)."""
    slots: Callable[[Mapping[str, int | bool]], int] | None = None
    """Its number of slots given a layout's parameters by name (None: its parameter's value,
    1 if a flag is on; 1 without a parameter)."""
    fill: Fill | None = None
    """Computes its values (None: the study's blocks, filled in one kernel call)."""
    flag: int | None = None
    """Column of the slot's valid flag (its noise is zero), if it has one."""
    masked: tuple[int, ...] = ()
    """Columns whose noise is multiplied by the valid flag of the same slot of
    ``masked_by``."""
    masked_by: str | None = None
    """The block whose slot flags mask :attr:`masked` (None: this block's own)."""
    fields: tuple[str, ...] = ()
    """Env config fields that fix what the block means (a model acts only where they have
    its training's values: :data:`boids_env.eval.episode.TRAINED_INTERFACE`)."""
    unit: str = "slot"
    """What one slot is called on the reference page (``"ray"``)."""


# ------------------------------------------------------------------------------------ fills
def _need_scene(inputs: Inputs, what: str) -> Sensors:
    if inputs.sensors is None or inputs.sensors.scene is None:
        raise ValueError(f"{what} (Sensors)")
    return inputs.sensors


def _fill_static(inputs: Inputs, slots: int) -> FloatArray:
    sensors = _need_scene(inputs, "static slots and the lidar need the scene")
    return static_block(inputs.positions[1:], slots, sensors, inputs.frame)


def _fill_lidar(inputs: Inputs, rays: int) -> FloatArray:
    sensors = _need_scene(inputs, "static slots and the lidar need the scene")
    return lidar_block(inputs.positions, rays, sensors, inputs.frame, inputs.crowd)


def _fill_pedestrians(inputs: Inputs, slots: int) -> FloatArray:
    if inputs.sensors is None:
        raise ValueError("pedestrian slots need their range (Sensors)")
    return pedestrian_block(inputs.positions[1:], slots, inputs.sensors,
                            inputs.velocity_bound, inputs.frame, inputs.crowd)


def _headings(inputs: Inputs) -> FloatArray:
    if inputs.headings is None:
        raise ValueError("this observation layout has heading blocks: give the headings")
    return inputs.headings


def _fill_own_heading(inputs: Inputs, slots: int) -> FloatArray:
    return _headings(inputs)[1:]


def _fill_leader_heading(inputs: Inputs, slots: int) -> FloatArray:
    return _headings(inputs)[0]


def _fill_neighbour_headings(inputs: Inputs, slots: int) -> FloatArray:
    headings = _headings(inputs)
    assert inputs.index is not None
    n = len(headings)
    padded = np.zeros((n + 1, 2))  # an empty slot's -1 picks the zero last row
    padded[:n] = headings
    return padded[inputs.index].reshape(n - 1, -1)


def _fill_route(inputs: Inputs, slots: int) -> FloatArray:
    sensors = _need_scene(inputs, "route sensing needs the scene")
    return route_block(inputs.positions, sensors, inputs.frame)


# ------------------------------------------------------------------------------- reasons
def _headings_reason(trained: int, env: int, config: EnvConfig, made: str | None) -> str:
    made = made or ("holonomic robots" if not trained else "robots with headings")
    robot = f"{config.world.robot} ({config.world.drive})"
    return (f"trained for {made} without headings; this env's {robot} has headings" if env
            else f"trained for {made} with headings; this env's {robot} has none")


def _pedestrians_reason(trained: int, env: int, config: EnvConfig, made: str | None) -> str:
    return (("trained without pedestrian slots" if not trained else
             f"trained with {trained} pedestrian slots")
            + f"; this env has {env} (crowd={config.scenario.crowd})")


def _route_reason(trained: int, env: int, config: EnvConfig, made: str | None) -> str:
    return ("trained without route sensing; this env has route_sensing on" if env else
            "trained with route sensing; this env has route_sensing off (set "
            "route_sensing=true)")


def _has_headings(config: EnvConfig) -> bool:
    return config.world.has_heading


def _velocities(r: Ranges) -> tuple[list[float], list[float]]:
    return [-r.velocity_bound] * 2, [r.velocity_bound] * 2


def _unit_vector(r: Ranges) -> tuple[list[float], list[float]]:
    return [-1.0, -1.0], [1.0, 1.0]


# --------------------------------------------------------------------------------- table
SPECS: tuple[BlockSpec, ...] = (
    BlockSpec("own_velocity", 2, "the follower's measured velocity (vx, vy), m/s",
              _velocities, fields=("velocity_bound",)),
    BlockSpec("leader_position", 2,
              "the leader's position relative to the follower (x, y), m",
              lambda r: ([-r.reach] * 2, [r.reach] * 2)),
    BlockSpec("leader_velocity", 2, "the leader's measured velocity (vx, vy), m/s",
              _velocities),
    BlockSpec("neighbours", SLOT_SIZE,
              "K slots, nearest first: relative position (2, m), velocity (2, m/s), valid "
              "flag (1); an empty slot is all zero",
              lambda r: ([-r.horizon, -r.horizon, -r.velocity_bound, -r.velocity_bound, 0.0],
                         [r.horizon, r.horizon, r.velocity_bound, r.velocity_bound, 1.0]),
              LayoutParameter("neighbours", lambda c: c.observation.neighbours,
                              what="neighbour slots"),
              flag=4, masked=(0, 1, 2, 3), fields=("neighbours",)),
    BlockSpec("static", WALL_SIZE,
              "static-geometry slots: offset to the nearest point of walls or obstacles "
              "(2, m), valid flag (1)",
              lambda r: ([-r.static_range, -r.static_range, 0.0],
                         [r.static_range, r.static_range, 1.0]),
              LayoutParameter("static", lambda c: c.static_slots,
                              what="static slots (sense_walls, static_slots)"),
              fill=_fill_static, flag=2, masked=(0, 1),
              fields=("sense_walls", "static_slots", "static_range")),
    BlockSpec("lidar", 1,
              "range-sensor rays evenly spaced in the observation's frame: distance (m) to "
              "the first wall, obstacle or robot, the range where nothing is hit",
              lambda r: ([0.0], [r.lidar_range]),
              LayoutParameter("lidar", lambda c: c.observation.lidar_rays,
                              what="lidar rays (lidar_rays)"),
              fill=_fill_lidar, fields=("lidar_rays", "lidar_range"), unit="ray"),
    BlockSpec("pedestrians", SLOT_SIZE,
              "pedestrian slots, nearest first, as neighbour slots: relative position "
              "(2, m), velocity (2, m/s), valid flag (1)",
              lambda r: ([-r.pedestrian_range] * 2 + [-r.velocity_bound] * 2 + [0.0],
                         [r.pedestrian_range] * 2 + [r.velocity_bound] * 2 + [1.0]),
              LayoutParameter("pedestrians", lambda c: c.pedestrian_slots,
                              reason=_pedestrians_reason),
              fill=_fill_pedestrians, flag=4, masked=(0, 1, 2, 3),
              fields=("pedestrian_slots", "pedestrian_range")),
    BlockSpec("own_heading", 2, "the follower's heading as a unit vector (cos, sin)",
              _unit_vector, LayoutParameter("headings", _has_headings, flag=True,
                                            reason=_headings_reason),
              fill=_fill_own_heading),
    BlockSpec("leader_heading", 2, "the leader's heading as a unit vector (cos, sin)",
              _unit_vector, slots=lambda p: int(p["headings"]), fill=_fill_leader_heading),
    BlockSpec("neighbour_headings", 2,
              "the heading (cos, sin) of the robot in each neighbour slot; zeros in an empty "
              "slot",
              _unit_vector, slots=lambda p: p["neighbours"] * p["headings"],
              fill=_fill_neighbour_headings, masked=(0, 1), masked_by="neighbours"),
    BlockSpec("route", ROUTE_SIZE,
              "route sensing: unit direction (2) along the shortest free path to the leader, "
              "the path's length (1, m), valid flag (1; 0: no free path, the straight line's "
              "values); see the buildings how-to",
              # the length is bounded by ROUTE_REACH spans
              lambda r: ([-1.0, -1.0, 0.0, 0.0], [1.0, 1.0, ROUTE_REACH * r.reach, 1.0]),
              LayoutParameter("route", lambda c: c.observation.route_sensing, flag=True,
                              reason=_route_reason),
              fill=_fill_route, flag=3,
              fields=("route_sensing", "route_cell", "route_leader")),
)
"""Every observation block, in the order they appear in the vector (empty ones left out).
The study's four come first at fixed indices (``ObservationLayout.own_velocity``, ...,
``neighbours_start``); a new block goes at the end."""

BLOCKS = tuple(spec.name for spec in SPECS)
"""The names of the blocks of :data:`SPECS`, in order."""


def specs() -> tuple[BlockSpec, ...]:
    """The block table (read at each call, so that a test can extend :data:`SPECS`)."""
    return SPECS


def parameters() -> tuple[LayoutParameter, ...]:
    """The layout's parameters, in the table's order (``ObservationLayout``'s positional
    order: neighbours, static, lidar, pedestrians, headings, route)."""
    return tuple(spec.parameter for spec in SPECS if spec.parameter is not None)


def interface_fields() -> tuple[str, ...]:
    """The env fields that fix what some block means, each once, in the table's order."""
    return tuple(dict.fromkeys(field for spec in SPECS for field in spec.fields))
