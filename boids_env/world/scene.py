"""The static scene: the arena's walls plus any obstacles, and every query on them.

One :class:`Scene` serves the physics (which shapes to add), the observations (nearest
static points, range sensing), the metrics (wall contact, clearance, line of sight), the
config checks (start layout and leader path clear of obstacles), the renderer and the bags.
Pure numpy (see :mod:`~boids_env.world.geometry`): no pymunk here.

A scene holds
- an optional **box**: the enclosing walls as their inner faces ``(xmin, ymin, xmax, ymax)``
  (the study's arena is the box ±5 m); its queries are computed exactly as the study-era code
  did, so the default case stays bit-identical;
- **capsules**: segments swept by a radius (inner walls, round pillars with ``a == b``, the
  contours of a map);
- convex **polygons** (solid blocks), whose edges also count as zero-radius capsules for the
  distance and ray queries;
- optionally the **occupancy grid** of a map (:mod:`~boids_env.world.occupancy`; for ``/map``
  and for telling free from occupied space exactly as the map says).

Queries on the shapes go through a spatial index (:mod:`~boids_env.world.scene_index`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env import kernels
from boids_env.untrusted import excerpt
from boids_env.world import geometry as geo
from boids_env.world.occupancy import OccupancyGrid
from boids_env.world.scene_index import FAR, INDEX_CELL, build_index

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

BOX_WALLS = ("east", "north", "west", "south")
"""The box's walls in the order its queries use (+x, +y, −x, −y)."""
MAX_SPAN = 500.0
"""Largest extent (m, along x or y) of a scene read from a file (a map or a shapes file):
every grid over a scene (its spatial index, its occupancy raster) grows with its area. A
4096² map of 10 cm cells (410 m) fits."""
MAX_RASTER = 4096
"""Most cells along a side of a scene's occupancy raster (``/map``, bags)."""
MAX_SHAPES = 50_000
"""Most capsules and polygon edges in one scene (a map's contours included)."""
SECTOR_COS = math.cos(math.radians(45.0))
"""Static slots after the first hold points whose direction differs by more than 45° from
every earlier slot's (so a corridor shows both walls and a corner both sides)."""
SCENE_FIELDS = ("path", "path_size", "waypoints", "start", "start_heading", "layout_spacing",
                "laps")
"""The scenario fields a scene may set; choosing a scene resets all of them to its values."""
STUDY_DEFAULTS: dict[str, Any] = {"path": "square", "path_size": 4.0, "waypoints": (),
                                  "start": (0.0, 0.0), "start_heading": None,
                                  "layout_spacing": 0.5, "laps": 1}
"""Those fields as the study has them (the ``arena`` scene's)."""


@dataclass(frozen=True, eq=False)
class Scene:
    """Static geometry of a world (metres). Build scenes with
    :func:`boids_env.world.scenes.load_scene` or the constructors there."""

    name: str
    """Built-in name, or the file it was read from."""
    description: str = ""
    box: tuple[float, float, float, float] | None = None
    """Inner faces of the enclosing walls ``(xmin, ymin, xmax, ymax)``; None: no box."""
    a: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    """(S, 2) capsule starts."""
    b: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    """(S, 2) capsule ends (equal to the start for a round pillar)."""
    radius: FloatArray = field(default_factory=lambda: np.zeros(0))
    """(S,) capsule radii (m)."""
    polygons: tuple[FloatArray, ...] = ()
    """Convex solid blocks, each (V, 2) counter-clockwise."""
    names: tuple[str, ...] = ()
    """A name for each capsule, then each polygon (for messages)."""
    grid: OccupancyGrid | None = None
    """A map's cells (None for scenes made of shapes)."""
    defaults: dict[str, Any] = field(default_factory=dict)
    """Scenario fields this scene sets unless the user gives them (its leader path, start)."""
    _cache: dict[Any, Any] = field(default_factory=dict, repr=False, compare=False)
    # Every query shape as a capsule (the capsules, then each polygon's edges with radius 0)
    # and the shape each one belongs to (into names): set by __post_init__, never passed in.
    _qa: FloatArray = field(init=False, repr=False, compare=False)
    _qb: FloatArray = field(init=False, repr=False, compare=False)
    _qr: FloatArray = field(init=False, repr=False, compare=False)
    _owner: npt.NDArray[np.intp] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        a, b = np.asarray(self.a, float).reshape(-1, 2), np.asarray(self.b, float).reshape(-1, 2)
        r = np.asarray(self.radius, float).reshape(-1)
        if not len(a) == len(b) == len(r):
            raise ValueError("scene capsules need as many ends and radii as starts")
        polys = tuple(np.asarray(p, float).reshape(-1, 2) for p in self.polygons)
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "polygons", polys)
        names = tuple(self.names) or tuple(f"obstacle {k}" for k in range(len(r) + len(polys)))
        if len(names) != len(r) + len(polys):
            raise ValueError("a scene needs one name per capsule and polygon")
        object.__setattr__(self, "names", names)
        edges = [(p, np.roll(p, -1, axis=0)) for p in polys]
        # every query shape as a capsule: the capsules, then the polygons' edges (radius 0)
        self._set("_qa", np.concatenate([a, *(e[0] for e in edges)]) if edges else a)
        self._set("_qb", np.concatenate([b, *(e[1] for e in edges)]) if edges else b)
        self._set("_qr", np.concatenate([r, np.zeros(sum(len(p) for p in polys))]))
        owner = [np.arange(len(r))] + [np.full(len(p), len(r) + k) for k, p in enumerate(polys)]
        self._set("_owner", np.concatenate(owner).astype(np.intp))
        self._check_budget()

    def _check_budget(self) -> None:
        """Refuses a scene with shapes (or a map) too large to index: more than
        :data:`MAX_SHAPES` shapes or an extent beyond :data:`MAX_SPAN` (an empty box, the
        study's arena of any size, builds no index)."""
        if len(self._qr) > MAX_SHAPES:
            raise ValueError(f"scene {excerpt(self.name)}: {len(self._qr):,} shapes (capsules "
                             f"and polygon edges), more than the {MAX_SHAPES:,} allowed")
        if (len(self._qr) or self.grid is not None) and self.span > MAX_SPAN:
            x0, y0, x1, y1 = self.bounds
            raise ValueError(f"scene {excerpt(self.name)}: it spans {x1 - x0:g} m × "
                             f"{y1 - y0:g} m; a scene with shapes may span at most "
                             f"{MAX_SPAN:g} m")

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_cache"] = {}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    # ------------------------------------------------------------------------ extent
    @property
    def is_empty_box(self) -> bool:
        """Whether the scene is an empty box (the study's arena, of any size)."""
        return self.box is not None and not len(self.radius) and not self.polygons

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the space robots can be in (the box's inner faces,
        else the extent of every shape)."""
        if self.box is not None:
            return self.box
        if "bounds" not in self._cache:
            if self.grid is not None:  # a map: its cells' extent (its border is a wall)
                h, w = self.grid.cells.shape
                x0, y0, yaw = self.grid.origin
                c, s = math.cos(yaw), math.sin(yaw)
                local = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]]) * self.grid.resolution
                pts = np.column_stack([x0 + c * local[:, 0] - s * local[:, 1],
                                       y0 + s * local[:, 0] + c * local[:, 1]])
            else:
                r = self._qr[:, None]
                pts = np.concatenate([self._qa - r, self._qa + r, self._qb - r, self._qb + r])
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            self._cache["bounds"] = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        return self._cache["bounds"]

    @property
    def span(self) -> float:
        """The largest distance along an axis between two points of the scene (m): bounds
        the leader's position relative to a follower."""
        x0, y0, x1, y1 = self.bounds
        return max(x1 - x0, y1 - y0)

    # -------------------------------------------------------------------- the index
    def _candidates(self, points: FloatArray, reach: float) -> npt.NDArray[np.intp]:
        """(P, C) indices of the query capsules that can lie within ``reach`` of each point
        (padded with the index of a far-away dummy capsule)."""
        key = ("index", float(reach))
        if key not in self._cache:
            self._cache[key] = build_index(self.bounds, self._qa, self._qb, self._qr,
                                           reach)
        origin, shape, table = self._cache[key]
        cell = np.floor((points - origin) / INDEX_CELL).astype(np.intp)
        cx = np.clip(cell[:, 0], 0, shape[0] - 1)
        cy = np.clip(cell[:, 1], 0, shape[1] - 1)
        return table[cx * shape[1] + cy]

    def _kernel_index(self, reach: float) -> tuple[FloatArray, npt.NDArray[np.intp],
                                                   npt.NDArray[np.intp]]:
        """The index for ``reach`` as the compiled queries take it: ``(origin (x, y, cell),
        shape (2,), table)``."""
        key = ("kernel index", float(reach))
        if key not in self._cache:
            self._candidates(np.zeros((0, 2)), reach)  # builds the index
            origin, shape, table = self._cache[("index", float(reach))]
            self._cache[key] = (np.array([origin[0], origin[1], INDEX_CELL]),
                                np.array(shape, dtype=np.intp), np.ascontiguousarray(table))
        return self._cache[key]

    def _kernel_index_or_none(self, reach: float, shapes: bool
                              ) -> tuple[FloatArray, npt.NDArray[np.intp], npt.NDArray[np.intp]]:
        """:meth:`_kernel_index` for ``reach`` when the scene has shapes, else the empty
        index the compiled queries take in its place."""
        if shapes:
            return self._kernel_index(reach)
        if "no index" not in self._cache:
            self._cache["no index"] = (np.zeros(3), np.ones(2, dtype=np.intp),
                                       np.zeros((1, 1), dtype=np.intp))
        return self._cache["no index"]

    def _query_arrays(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The query capsules plus the dummy one at the end."""
        if "padded" not in self._cache:
            far = np.array([[FAR, FAR]])
            self._cache["padded"] = (np.concatenate([self._qa, far]),
                                     np.concatenate([self._qb, far]),
                                     np.concatenate([self._qr, [0.0]]))
        return self._cache["padded"]

    # ---------------------------------------------------------------- box (exact)
    def _box_gaps(self, points: FloatArray) -> FloatArray:
        """Distances (P, 4) from each point to the box's walls (east, north, west, south),
        computed as the study's arena code did (callers check that there is a box)."""
        assert self.box is not None, "_box_gaps needs a box"
        x0, y0, x1, y1 = self.box
        return np.concatenate([np.array([x1, y1]) - points, points - np.array([x0, y0])],
                              axis=1)

    def _box_array(self) -> FloatArray:
        """The box (xmin, ymin, xmax, ymax) as the compiled queries take it (zeros without
        one)."""
        if "box array" not in self._cache:
            self._cache["box array"] = np.array(
                self.box if self.box is not None else (0.0, 0.0, 0.0, 0.0), dtype=float)
        return self._cache["box array"]

    def _box_within(self, points: FloatArray, margins: tuple[float, ...]) -> BoolArray:
        assert self.box is not None, "_box_within needs a box"  # its one caller checks
        x0, y0, x1, y1 = self.box
        hi = np.array([x1, y1], dtype=float)
        lo = -np.array([x0, y0], dtype=float)
        for m in margins:  # subtracted one by one, as the arena code did (h - r - tol)
            hi = hi - m
            lo = lo - m
        return np.any((points >= hi) | (-points >= lo), axis=-1)

    # ---------------------------------------------------------------- distances
    def within(self, points: FloatArray, *margins: float) -> BoolArray:
        """Whether each point (..., 2) is within the sum of ``margins`` (m) of static
        geometry (a robot of radius r touches at ``within(p, r, tolerance)``)."""
        pts = np.asarray(points, dtype=float)
        compiled = kernels.compiled()
        if compiled is not None and pts.ndim == 2 and pts.shape[1] == 2:
            if (self.box is not None and not len(self._qr) and not self.polygons
                    and self.grid is None and all(np.ndim(m) == 0 for m in margins)):
                # a box alone (an arena), scalar margins: one loop
                return compiled.box_within(np.ascontiguousarray(pts), self._box_array(),
                                           np.array(margins, dtype=np.float64))
            if self.box is None and not self.polygons and np.isfinite(pts).all():
                return self._within_compiled(compiled, pts, sum(margins))
        shape = pts.shape[:-1]
        flat = pts.reshape(-1, 2)
        out = np.zeros(len(flat), dtype=bool)
        if self.box is not None:
            out |= self._box_within(flat, margins)
        if len(self._qr):
            out |= self._shape_clearance(flat, sum(margins)) <= sum(margins)
        if self.polygons or self.grid is not None:
            out |= self.inside(flat)
        return out.reshape(shape)

    def _within_compiled(self, compiled: Any, points: FloatArray, reach: float) -> BoolArray:
        """:meth:`within` of a scene of capsules and a map (no box, no polygons) in one
        compiled call: the same clearances and cells."""
        shapes = len(self._qr) > 0
        qa, qb, qr = self._query_arrays()
        origin, shape, table = self._kernel_index_or_none(reach, shapes)
        grid = self.grid
        if grid is not None:
            x0, y0, yaw = grid.origin
            cells, resolution, turn = grid.cells, float(grid.resolution), (
                float(x0), float(y0), math.cos(yaw), math.sin(yaw))
        else:
            cells, resolution, turn = np.zeros((1, 1), dtype=np.int8), 1.0, (0.0, 0.0, 1.0, 0.0)
        return compiled.within(np.ascontiguousarray(points), float(reach), shapes, qa, qb, qr,
                               table, origin, shape, grid is not None, cells, resolution,
                               *turn)

    def _shape_clearance(self, points: FloatArray, reach: float) -> FloatArray:
        """Distance (P,) from each point to the nearest capsule or polygon edge surface
        (values beyond ``reach`` may be any number above it)."""
        qa, qb, qr = self._query_arrays()
        compiled = kernels.compiled()
        if compiled is not None and np.isfinite(points).all():  # the same bits in one loop
            origin, shape, table = self._kernel_index(reach)
            return compiled.shape_clearance(np.ascontiguousarray(points), qa, qb, qr, table,
                                            origin, shape)
        idx = self._candidates(points, reach)
        _, d = geo.closest_on_segments(points[:, None, :], qa[idx], qb[idx])
        return np.min(d - qr[idx], axis=1, initial=np.inf)

    def clearance(self, points: FloatArray) -> FloatArray:
        """Distance (m) from each point (..., 2) to the nearest static geometry (negative
        inside a capsule; 0 inside a polygon or an occupied map cell)."""
        pts = np.asarray(points, dtype=float)
        shape = pts.shape[:-1]
        flat = pts.reshape(-1, 2)
        best = np.full(len(flat), np.inf)
        if self.box is not None:
            best = np.minimum(best, self._box_gaps(flat).min(axis=1))
        compiled = kernels.compiled()
        if len(self._qr) and compiled is not None and np.isfinite(flat).all():
            # the same minimum in one loop (boids_env.kernels)
            best = np.minimum(best, compiled.capsule_clearance(
                np.ascontiguousarray(flat), np.ascontiguousarray(self._qa),
                np.ascontiguousarray(self._qb), np.ascontiguousarray(self._qr)))
        elif len(self._qr):
            qa, qb, qr = self._qa, self._qb, self._qr
            for start in range(0, len(qr), 256):  # exact for any distance: all shapes
                sl = slice(start, start + 256)
                _, d = geo.closest_on_segments(flat[:, None, :], qa[None, sl], qb[None, sl])
                best = np.minimum(best, (d - qr[None, sl]).min(axis=1))
        if self.polygons or self.grid is not None:
            best = np.where(self.inside(flat), np.minimum(best, 0.0), best)
        return best.reshape(shape)

    def inside(self, points: FloatArray) -> BoolArray:
        """Whether each point (P, 2) is inside a solid polygon or an occupied map cell (or
        off the map)."""
        out = np.zeros(len(points), dtype=bool)
        for poly in self.polygons:
            out |= geo.points_in_polygon(points, poly)
        if self.grid is not None:
            out |= self.grid.occupied(points)
        return out

    # --------------------------------------------------------------- sensing
    def nearest_points(self, points: FloatArray, slots: int, reach: float
                       ) -> tuple[FloatArray, BoolArray]:
        """The nearest points of static geometry around each point: slot 0 the nearest,
        each later slot the nearest whose direction differs by more than 45° from every
        earlier slot's; only points within ``reach``.

        Args:
            points: (P, 2) positions (robot centres).
            slots: number of slots M.
            reach: range (m); farther geometry leaves a slot empty.

        Returns:
            ``(offsets (P, M, 2), valid (P, M))``: offsets from each point to the surface
            point (m, world frame), zeros in empty slots.
        """
        pts = np.asarray(points, dtype=float)
        compiled = kernels.compiled()
        shapes = len(self._qr) > 0
        if (compiled is not None and (shapes or self.box is not None) and pts.ndim == 2
                and np.isfinite(pts).all()):  # the same bits in one loop (boids_env.kernels)
            qa, qb, qr = self._query_arrays()
            origin, shape, table = self._kernel_index_or_none(reach, shapes)
            return compiled.nearest_points(np.ascontiguousarray(pts), int(slots),
                                           float(reach), self._box_array(),
                                           self.box is not None, qa, qb,
                                           qr, table, origin, shape, shapes, SECTOR_COS)
        cand_off, cand_d = self._surface_candidates(pts, reach)
        p = len(pts)
        offsets = np.zeros((p, slots, 2))
        valid = np.zeros((p, slots), dtype=bool)
        dist = np.where(cand_d <= reach, cand_d, np.inf)
        rows = np.arange(p)
        for k in range(slots):
            pick = np.argmin(dist, axis=1)
            d = dist[rows, pick]
            ok = np.isfinite(d)
            chosen = cand_off[rows, pick]
            offsets[ok, k] = chosen[ok]
            valid[:, k] = ok
            if k + 1 < slots:
                # candidates within 45° of the chosen direction are used up
                cosine = geo.dot(cand_off, chosen[:, None, :]) / np.maximum(
                    cand_d * d[:, None], 1e-300)
                dist = np.where(ok[:, None] & (cosine > SECTOR_COS), np.inf, dist)
        return offsets, valid

    def _surface_candidates(self, points: FloatArray, reach: float
                            ) -> tuple[FloatArray, FloatArray]:
        """Offsets (P, C, 2) from each point to candidate surface points and their lengths:
        the box's four walls (as the arena's wall slot computed them) and the nearest point
        of each capsule near the point."""
        parts_off, parts_d = [], []
        if self.box is not None:
            gaps = self._box_gaps(points)  # (P, 4)
            direction = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
            parts_off.append(direction[None] * gaps[:, :, None])
            parts_d.append(gaps)
        if len(self._qr):
            qa, qb, qr = self._query_arrays()
            idx = self._candidates(points, reach)
            closest, d = geo.closest_on_segments(points[:, None, :], qa[idx], qb[idx])
            rel = closest - points[:, None, :]
            scale = np.where(d > 0, (d - qr[idx]) / np.where(d > 0, d, 1.0), 0.0)
            parts_off.append(rel * scale[..., None])
            parts_d.append(np.maximum(d - qr[idx], 0.0))
        if not parts_d:
            return np.zeros((len(points), 0, 2)), np.zeros((len(points), 0))
        return np.concatenate(parts_off, axis=1), np.concatenate(parts_d, axis=1)

    def raycast(self, origins: FloatArray, directions: FloatArray, max_range: float
                ) -> FloatArray:
        """Distance (m) along rays to static geometry, capped at ``max_range``.

        Args:
            origins: (P, 2) ray starts.
            directions: (P, R, 2) unit ray directions.
            max_range: the sensor's range (m); no hit reads ``max_range``.
        """
        compiled = kernels.compiled()
        shapes = len(self._qr) > 0
        if (compiled is not None and directions.ndim == 3 and len(directions) == len(origins)
                and np.isfinite(origins).all() and np.isfinite(directions).all()):
            # the same ranges in one loop (boids_env.kernels)
            qa, qb, qr = self._query_arrays()
            origin, shape, table = self._kernel_index_or_none(max_range, shapes)
            best = compiled.raycast(np.ascontiguousarray(origins, dtype=np.float64),
                                    np.ascontiguousarray(directions, dtype=np.float64),
                                    self._box_array(),
                                    self.box is not None, qa, qb, qr, table, origin, shape,
                                    shapes)
            if self.grid is not None:
                best = np.where(self.grid.occupied(origins)[:, None], 0.0, best)
            return np.minimum(best, max_range)
        best = np.full(directions.shape[:2], np.inf)
        o = origins[:, None, :]
        if self.box is not None:
            x0, y0, x1, y1 = self.box
            dx, dy = directions[..., 0], directions[..., 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                tx = np.where(dx > 0, (x1 - o[..., 0]) / dx,
                              np.where(dx < 0, (x0 - o[..., 0]) / dx, np.inf))
                ty = np.where(dy > 0, (y1 - o[..., 1]) / dy,
                              np.where(dy < 0, (y0 - o[..., 1]) / dy, np.inf))
            best = np.maximum(np.minimum(tx, ty), 0.0)
        if len(self._qr):
            qa, qb, qr = self._query_arrays()
            idx = self._candidates(origins, max_range)  # (P, C)
            hit = geo.ray_capsules(o[:, :, None, :], directions[:, :, None, :],
                                   qa[idx][:, None], qb[idx][:, None], qr[idx][:, None])
            best = np.minimum(best, hit.min(axis=2))
        if self.grid is not None:
            best = np.where(self.grid.occupied(origins)[:, None], 0.0, best)
        return np.minimum(best, max_range)

    # -------------------------------------------------------------- checks
    def blocked(self, starts: FloatArray, ends: FloatArray, clearance: float = 0.0, *,
                use_grid: bool = True) -> tuple[BoolArray, npt.NDArray[np.intp]]:
        """Whether each segment ``starts``–``ends`` (L, 2) passes within ``clearance`` of a
        capsule or polygon (the box's walls are not obstacles to a segment inside it), and
        the index of the shape (into :attr:`names`; −1 where clear). With ``use_grid`` a
        map's cells are sampled along the segment too (a segment between two free points
        cannot cross occupied cells without crossing a contour, so without it only the
        contours are tested)."""
        starts, ends = np.atleast_2d(starts).astype(float), np.atleast_2d(ends).astype(float)
        out, which = self._capsules_blocked(starts, ends, clearance)
        for k, poly in enumerate(self.polygons):  # a segment wholly inside a block
            inside = geo.points_in_polygon(starts, poly) | geo.points_in_polygon(ends, poly)
            fresh = inside & ~out
            which[fresh] = len(self.radius) + k
            out |= inside
        if self.grid is not None and use_grid:
            for i in np.flatnonzero(~out):
                n = max(2, math.ceil(geo.norm(ends[i] - starts[i]) / self.grid.resolution * 2))
                t = np.linspace(0.0, 1.0, n)[:, None]
                if self.grid.occupied(starts[i] + t * (ends[i] - starts[i])).any():
                    out[i] = True
        return out, which

    def _capsules_blocked(self, starts: FloatArray, ends: FloatArray, clearance: float
                          ) -> tuple[BoolArray, npt.NDArray[np.intp]]:
        """:meth:`blocked`'s test of the capsules and polygon edges: whether each segment
        passes within ``clearance`` of one, and the first one's shape (−1 where none)."""
        if not len(self._qr):
            return np.zeros(len(starts), dtype=bool), np.full(len(starts), -1, dtype=np.intp)
        compiled = kernels.compiled()
        if (compiled is not None and starts.shape == ends.shape and np.isfinite(starts).all()
                and np.isfinite(ends).all()):  # the same distances and first hits in one loop
            first = compiled.segments_blocked(
                np.ascontiguousarray(starts), np.ascontiguousarray(ends),
                np.ascontiguousarray(self._qa), np.ascontiguousarray(self._qb),
                np.ascontiguousarray(self._qr), float(clearance))
            hit = first >= 0
            return hit, np.where(hit, self._owner[np.maximum(first, 0)], -1)
        out = np.zeros(len(starts), dtype=bool)
        which = np.full(len(starts), -1, dtype=np.intp)
        chunk = max(1, 1_000_000 // len(self._qr))  # bounds the (L, S) temporaries
        for lo in range(0, len(starts), chunk):
            sl = slice(lo, lo + chunk)
            d = geo.segments_distance(starts[sl, None], ends[sl, None], self._qa[None],
                                      self._qb[None]) - self._qr[None]
            hit = d < clearance
            out[sl] = hit.any(axis=1)
            which[sl] = np.where(out[sl], self._owner[np.argmax(hit, axis=1)], -1)
        return out, which

    def occupancy(self, resolution: float = 0.05) -> OccupancyGrid:
        """The scene as a ROS occupancy grid: a map's own cells, else the scene rasterised
        at ``resolution`` (m per cell) over its bounds plus one cell of wall around (a cell is
        occupied when its centre lies within half a cell of static geometry). A scene wider
        than :data:`MAX_RASTER` cells is rasterised with coarser cells."""
        if self.grid is not None:
            return self.grid
        x0, y0, x1, y1 = self.bounds
        # a budget of cells: a huge arena (arena_half_size up to 1000 m) gets coarser cells
        resolution = max(float(resolution), max(x1 - x0, y1 - y0) / MAX_RASTER)
        key = ("occupancy", float(resolution))
        if key not in self._cache:
            ox, oy = x0 - resolution, y0 - resolution
            w = max(1, math.ceil((x1 - x0) / resolution)) + 2
            h = max(1, math.ceil((y1 - y0) / resolution)) + 2
            gx, gy = np.meshgrid(ox + (np.arange(w) + 0.5) * resolution,
                                 oy + (np.arange(h) + 0.5) * resolution)
            centres = np.stack([gx.ravel(), gy.ravel()], axis=1)
            occupied = self.within(centres, resolution / 2 - 1e-9).reshape(h, w)
            outside = ((gx < x0) | (gx > x1) | (gy < y0) | (gy > y1)) & (self.box is not None)
            cells = np.where(occupied | outside, 100, 0).astype(np.int8)
            self._cache[key] = OccupancyGrid(cells, float(resolution), (ox, oy, 0.0))
        return self._cache[key]

    def box_clearance(self, points: FloatArray) -> FloatArray:
        """Distance (P,) from each point to the box's walls (inf without a box)."""
        if self.box is None:
            return np.full(len(points), np.inf)
        return self._box_gaps(np.atleast_2d(np.asarray(points, dtype=float))).min(axis=1)

    def nearest_name(self, point: FloatArray) -> str:
        """The name of the static shape nearest to ``point`` (2,)."""
        p = np.asarray(point, dtype=float).reshape(1, 2)
        best, name = np.inf, "nothing"
        if self.box is not None:
            gaps = self._box_gaps(p)[0]
            best, name = float(gaps.min()), f"the {BOX_WALLS[int(np.argmin(gaps))]} wall"
        if len(self._qr):
            d = geo.closest_on_segments(p, self._qa, self._qb)[1] - self._qr
            k = int(np.argmin(d))
            if d[k] < best:
                best, name = float(d[k]), self.names[self._owner[k]]
        if self.grid is not None and self.grid.occupied(p)[0]:
            name = "an occupied map cell"
        return name

    def box_wall_name(self, points: FloatArray, margin: float) -> str | None:
        """The name of a box wall within ``margin`` of some point (None if none is)."""
        if self.box is None:
            return None
        gaps = self._box_gaps(np.atleast_2d(points))
        close = np.argwhere(gaps < margin)
        if not len(close):
            return None
        return f"the {BOX_WALLS[close[0][1]]} wall"
