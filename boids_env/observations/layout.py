"""The named layout of one follower's observation vector, read off the block table.

:class:`ObservationLayout` holds the layout's parameters (how many slots of each kind, which
blocks are on) and derives everything else from :data:`boids_env.observations.blocks.SPECS`:
the blocks' sizes and slices, the observation Box, where the sensing noise is masked, and
the block list saved with every trained model.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from boids_env.observations import blocks as table
from boids_env.observations.blocks import BlockSpec, Fill, LayoutParameter, Ranges
from boids_env.observations.sensing import SLOT_SIZE, WALL_SIZE, FloatArray

if TYPE_CHECKING:
    from boids_env.config import EnvConfig


class ObservationLayout:
    """Named blocks of one follower's observation vector, and views of a batch of them.

    Built from its parameters, positionally in the table's order or by name:
    ``ObservationLayout(18)``, ``ObservationLayout(6, 2, 8, pedestrians=3, headings=True,
    route=True)``; a block added to the table brings its parameter as a keyword. The layout
    is an explicit list of blocks (:attr:`blocks`), saved with every trained model
    (``boids.json``), never guessed from a vector's length once sensing goes beyond the
    study's (:meth:`for_size` reads only the study-era sizes). Layouts are immutable and
    equal when their parameters are.
    """

    neighbours: int
    """K, the number of neighbour slots (5 values each)."""
    static: int
    """M, the number of static-geometry slots (3 values each: offset to the nearest point of
    walls or obstacles, valid flag). The study-era ``sense_walls`` is one slot."""
    lidar: int
    """R, the number of range-sensor rays (1 value each: distance in m)."""
    pedestrians: int
    """P, the number of pedestrian slots (5 values each, as a neighbour slot: relative
    position, velocity, valid flag), nearest first (opt-in, with a crowd)."""
    headings: bool
    """Whether the robots have headings: the ``own_heading``, ``leader_heading`` and
    ``neighbour_headings`` blocks (unit vectors) follow the others."""
    route: bool
    """Whether the ``route`` block (route sensing, :mod:`boids_env.world.route`) is on: the
    unit direction of the follower's shortest free path to the leader (2), its length (1, m)
    and a valid flag (1; 0 where no free path exists and the first three are the straight
    line's)."""

    _values: tuple[tuple[str, int | bool], ...]
    """``(name, value)`` of every parameter, in the table's order (what equality compares)."""

    own_velocity = slice(0, 2)
    leader_position = slice(2, 4)
    leader_velocity = slice(4, 6)
    neighbours_start = 6
    """The study's blocks sit at these fixed indices in every layout (the table's first four
    blocks; the compiled kernels write them there)."""

    def __init__(self, *args: int | bool, **values: int | bool) -> None:
        params = table.parameters()
        if len(args) > len(params):
            raise TypeError(f"ObservationLayout takes at most {len(params)} positional "
                            f"parameters ({', '.join(p.name for p in params)}), got {len(args)}")
        given = dict(zip((p.name for p in params), args, strict=False))
        for name in values:
            if name in given:
                raise TypeError(f"ObservationLayout got {name!r} twice")
        given.update(values)
        unknown = set(given) - {p.name for p in params}
        if unknown:
            raise TypeError(f"ObservationLayout has no parameter {sorted(unknown)[0]!r} "
                            f"(parameters: {', '.join(p.name for p in params)})")
        items = tuple((p.name, _checked(p, given.get(p.name, False if p.flag else 0)))
                      for p in params)
        for name, value in items:
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_values", items)

    def __setattr__(self, name: str, value: Any) -> None:
        raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")

    def __delattr__(self, name: str) -> None:
        raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ObservationLayout) or type(other) is not type(self):
            return NotImplemented
        return self._values == other._values

    def __hash__(self) -> int:
        return hash(self._values)

    def __repr__(self) -> str:
        return f"ObservationLayout({', '.join(f'{n}={v!r}' for n, v in self._values)})"

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuilt, (dict(self._values),))

    @functools.cached_property
    def parameters(self) -> dict[str, int | bool]:
        """The layout's parameters by name, in the table's order (a new dict per layout:
        do not change it)."""
        return dict(self._values)

    def value(self, name: str) -> int | bool:
        """The parameter ``name`` (``layout.value("lidar") == layout.lidar``)."""
        return self.parameters[name]

    def _slots(self, spec: BlockSpec) -> int:
        if spec.slots is not None:
            return int(spec.slots(self.parameters))
        return int(self.value(spec.parameter.name)) if spec.parameter is not None else 1

    @functools.cached_property  # the parameters are frozen; the env reads these every step
    def present(self) -> tuple[tuple[BlockSpec, slice, int], ...]:
        """``(spec, slice, slots)`` of every non-empty block, in order."""
        out, start = [], 0
        for spec in table.specs():
            slots = self._slots(spec)
            if slots:
                size = spec.width * slots
                out.append((spec, slice(start, start + size), slots))
                start += size
        return tuple(out)

    @functools.cached_property
    def blocks(self) -> tuple[tuple[str, int], ...]:
        """``(name, size)`` of every non-empty block, in order."""
        return tuple((spec.name, block.stop - block.start) for spec, block, _ in self.present)

    @functools.cached_property
    def fills(self) -> tuple[tuple[Fill, slice, int], ...]:
        """``(fill, slice, slots)`` of the blocks filled beyond the study's, in order."""
        return tuple((spec.fill, block, slots) for spec, block, slots in self.present
                     if spec.fill is not None)

    @property
    def study_only(self) -> bool:
        """Whether every block is one of the study's (filled in one kernel call, no fill of
        its own): what the fused step (:mod:`boids_env.fused`) computes."""
        return not self.fills

    @classmethod
    def from_blocks(cls, blocks: object) -> ObservationLayout:
        """The layout of a saved block list (``[[name, size], ...]``, as :attr:`blocks`);
        ``ValueError`` for anything that is not one."""
        try:  # blocks is anything read from a file: what is not pairs raises here
            named = {str(name): int(size) for name, size in blocks}  # type: ignore[attr-defined]
            pairs = [(str(n), int(s)) for n, s in blocks]  # type: ignore[attr-defined]
        except (TypeError, ValueError):
            raise ValueError(f"an observation layout is a list of [name, size] pairs, got "
                             f"{blocks!r}") from None
        values: dict[str, int | bool] = {}
        for spec in table.specs():
            if spec.parameter is not None:
                values[spec.parameter.name] = (spec.name in named if spec.parameter.flag
                                               else named.get(spec.name, 0) // spec.width)
        layout = cls(**values)
        if list(layout.blocks) != pairs:
            widths = ", ".join(f"{s.name} {s.width}" for s in table.specs())
            raise ValueError(f"not an observation layout: {pairs!r} (blocks, in order, with "
                             f"their values per slot: {widths})")
        return layout

    @functools.cached_property
    def size(self) -> int:
        """Length of one observation vector."""
        return sum(size for _, size in self.blocks)

    @functools.cached_property
    def _slices(self) -> dict[str, slice]:
        return {spec.name: block for spec, block, _ in self.present}

    def block(self, name: str) -> slice:
        """The slice of block ``name``; ``ValueError`` if this layout has no such block."""
        if name in self._slices:
            return self._slices[name]
        raise ValueError(f"this observation layout has no {name!r} block (blocks: "
                         f"{[b for b, _ in self.blocks]})")

    @functools.cached_property
    def _shapes(self) -> dict[str, tuple[slice, int, int]]:
        """``(slice, slots, width)`` of every block of the table (an empty slice where this
        layout leaves it out)."""
        shapes = {spec.name: (slice(0, 0), 0, spec.width) for spec in table.specs()}
        shapes.update({spec.name: (block, slots, spec.width)
                       for spec, block, slots in self.present})
        return shapes

    def slot_view(self, obs: FloatArray, name: str) -> FloatArray:
        """View of block ``name``'s slots of a batch ``(..., size)`` as ``(..., slots,
        width)`` (no slots where this layout leaves the block out); ``ValueError`` for a
        name the block table does not have."""
        if name not in self._shapes:
            raise ValueError(f"no observation block is called {name!r} (blocks: "
                             f"{[s.name for s in table.specs()]})")
        block, slots, width = self._shapes[name]
        return obs[..., block].reshape(*obs.shape[:-1], slots, width)

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
        return self.slot_view(obs, "static")

    def pedestrian_slots(self, obs: FloatArray) -> FloatArray:
        """View of the pedestrian slots of a batch ``(..., size)`` as ``(..., P, 5)``."""
        return self.slot_view(obs, "pedestrians")

    def neighbour_headings(self, obs: FloatArray) -> FloatArray:
        """View of the neighbour headings of a batch ``(..., size)`` as ``(..., K, 2)``
        (zeros in empty slots); ``ValueError`` for a layout without headings."""
        if not self.headings:
            raise ValueError("this observation layout has no headings (a holonomic robot)")
        return self.slot_view(obs, "neighbour_headings")

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
        """The observation Box: finite bounds, float32, each block's from its spec.
        ``reach`` bounds the leader's relative position (twice the arena's half size: the
        scene's span); ``static_range`` defaults to ``horizon``."""
        ranges = Ranges(reach, horizon, velocity_bound,
                        horizon if static_range is None else static_range, lidar_range,
                        pedestrian_range)
        low = np.empty(self.size, dtype=np.float32)
        high = np.empty(self.size, dtype=np.float32)
        for spec, block, slots in self.present:
            slot_low, slot_high = spec.bounds(ranges)
            low[block] = np.tile(slot_low, slots)
            high[block] = np.tile(slot_high, slots)
        return spaces.Box(low, high, dtype=np.float32)

    @functools.cached_property
    def noise_columns(self) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp],
                                     npt.NDArray[np.intp]]:
        """Where sensing noise is masked, as column indices ``(scaled, flags, zeroed)``: the
        noise of column ``scaled[i]`` is multiplied by the observation's ``flags[i]`` (a
        spec's ``masked`` columns by its slot's valid flag), the noise of the ``zeroed``
        columns (the valid flags themselves) is zero. Read off the block specs, so that
        :meth:`Observer._noise <boids_env.observations.observer.Observer._noise>` masks a
        batch in two indexed operations."""
        parts: dict[str, list[npt.NDArray[np.intp]]] = {"scaled": [], "flags": [],
                                                         "zeroed": []}
        columns = {spec.name: (spec, np.arange(block.start, block.stop).reshape(slots, -1))
                   for spec, block, slots in self.present}
        for spec, cols in columns.values():
            if spec.masked:
                owner, owner_cols = columns[spec.masked_by or spec.name]
                assert owner.flag is not None, f"{owner.name} has no flag to mask with"
                block = cols[:, list(spec.masked)]
                parts["scaled"].append(block.ravel())
                parts["flags"].append(np.broadcast_to(owner_cols[:, owner.flag:owner.flag + 1],
                                                      block.shape).ravel())
            if spec.flag is not None:
                parts["zeroed"].append(cols[:, spec.flag])
        scaled, flags, zeroed = (np.concatenate([*parts[k], np.empty(0, np.intp)]).astype(np.intp)
                                 for k in ("scaled", "flags", "zeroed"))
        return scaled, flags, zeroed


def _checked(parameter: LayoutParameter, value: Any) -> int | bool:
    """``value`` if it is one of ``parameter``'s, else ``ValueError`` naming the parameter."""
    if parameter.flag and not isinstance(value, bool):
        raise ValueError(f"ObservationLayout {parameter.name} must be True or False, got "
                         f"{value!r}")
    if not parameter.flag and (isinstance(value, bool) or not isinstance(value, int | np.integer)
                               or value < 0):
        raise ValueError(f"ObservationLayout {parameter.name} must be a non-negative integer, "
                         f"got {value!r}")
    return value


def _rebuilt(values: dict[str, int | bool]) -> ObservationLayout:
    """A pickled layout, rebuilt from its parameters."""
    return ObservationLayout(**values)


def layout_of(config: EnvConfig) -> ObservationLayout:
    """The observation layout an env config gives (each parameter's value in the config)."""
    return ObservationLayout(**{p.name: p.of_config(config) for p in table.parameters()})
