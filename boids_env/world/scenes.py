"""The built-in scenes, and :func:`load_scene` for a name, a map or a shapes file.

Every built-in scene has a default leader path through it and a start for the flock; the
scenario fields it sets are in its :attr:`~boids_env.world.scene.Scene.defaults` (a field the
user gives wins). ``arena`` is the study's empty 10 m box and sets nothing new.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from boids_env.world import floorplans
from boids_env.world import geometry as geo
from boids_env.world.scene import STUDY_DEFAULTS, Scene

DATA = Path(__file__).parent / "data"
"""Scene data files shipped with the package (the ``lab`` map)."""
WALL = 0.05
"""Half the thickness (m) of the built-in scenes' inner walls (10 cm walls)."""


def _defaults(**fields: Any) -> dict[str, Any]:
    return {**STUDY_DEFAULTS, **fields}


def arena(half_size: float = 5.0) -> Scene:
    """The study's arena: an empty square box of side 2·``half_size`` (10 m)."""
    h = float(half_size)
    return Scene("arena", f"the study's empty {2 * h:g} m × {2 * h:g} m arena", box=(-h, -h, h, h),
                 defaults=_defaults())


def small_room() -> Scene:
    """A 5 m × 5 m room; the study's square scaled to ±2 m passes 0.5 m from its walls."""
    return Scene("small_room", "a 5 m × 5 m room; the study's square scaled to ±2 m passes "
                 "0.5 m from the walls", box=(-2.5, -2.5, 2.5, 2.5),
                 defaults=_defaults(path_size=2.0))


def doorway() -> Scene:
    """Two 6 m × 6 m rooms joined by a 1 m door in the wall between them; the leader crosses
    into the east room, circles in it and comes back through the door."""
    jamb = 0.5 + WALL  # the capsule's round end reaches 0.5 m from the door's centre line
    a = np.array([[0.0, jamb], [0.0, -jamb]])
    b = np.array([[0.0, 3.0 + 1.0], [0.0, -3.0 - 1.0]])
    points = ((3.0, 0.0), (4.0, 1.5), (4.0, -1.5), (3.0, 0.0), (-3.0, 0.0), (-4.5, -1.5),
              (-4.5, 1.5), (-3.0, 0.0))
    return Scene("doorway", "two 6 m × 6 m rooms joined by a 1 m door; the leader goes "
                 "through it, around the east room and back", box=(-6.0, -3.0, 6.0, 3.0), a=a,
                 b=b, radius=np.full(2, WALL), names=("the wall north of the door",
                                                      "the wall south of the door"),
                 defaults=_defaults(path="waypoints", waypoints=points, start=(-4.0, 0.0),
                                    start_heading=0.0))


def corridor() -> Scene:
    """A closed loop of corridor 2.2 m wide around a 3.8 m block; the leader drives one lap
    along its centre line."""
    block = np.array([[-1.9, -1.9], [1.9, -1.9], [1.9, 1.9], [-1.9, 1.9]])
    points = ((3.0, 3.0), (-3.0, 3.0), (-3.0, -3.0), (3.0, -3.0), (3.0, 1.0))
    return Scene("corridor", "a closed loop of corridor 2.2 m wide (8.2 m × 8.2 m outside); "
                 "the leader drives one lap on its centre line", box=(-4.1, -4.1, 4.1, 4.1),
                 polygons=(block,), names=("the central block",),
                 defaults=_defaults(path="waypoints", waypoints=points, start=(3.0, -1.0),
                                    start_heading=90.0, layout_spacing=0.3))


PILLAR_RADIUS = 0.12
"""Radius (m) of the pillars of the ``pillars`` scene."""


def pillars() -> Scene:
    """The study's arena and square with a field of round pillars (radius 0.12 m) on a
    staggered 1.2 m grid, none within 0.45 m of the leader's path or 0.35 m of a start
    cell of groups up to 37 robots: the flock has to weave between them."""
    from boids_env.world.layout import follower_cells
    from boids_env.world.leader import PAPER_SQUARE

    spacing = 1.2
    centres = []
    for row in range(-4, 5):
        offset = spacing / 2 if row % 2 else 0.0
        for col in range(-4, 5):
            centres.append((col * spacing + offset, row * spacing * math.sqrt(3) / 2))
    c = np.array(centres)
    path = np.array(((0.0, 0.0), *PAPER_SQUARE))
    on_path = geo.closest_on_segments(c[:, None, :], path[None, :-1], path[None, 1:])[1]
    cells = np.concatenate([[[0.0, 0.0]], follower_cells(37)])
    near_start = np.linalg.norm(c[:, None, :] - cells[None], axis=2).min(axis=1)
    keep = ((on_path.min(axis=1) > 0.45) & (near_start > 0.35)
            & (np.abs(c).max(axis=1) < 5.0 - 0.4))
    c = c[keep]
    return Scene("pillars", f"the study's arena and square with {len(c)} round pillars "
                 f"(radius {PILLAR_RADIUS} m) on a staggered 1.2 m grid", box=(-5.0, -5.0, 5.0,
                                                                                5.0),
                 a=c, b=c, radius=np.full(len(c), PILLAR_RADIUS),
                 names=tuple(f"pillar {k} at ({x:.2f}, {y:.2f})" for k, (x, y) in enumerate(c)),
                 defaults=_defaults())


def lab() -> Scene:
    """A 12 m × 10 m lab floor plan shipped as a ROS map (240 × 200 cells of 5 cm)."""
    from boids_env.world.maps import load_map

    scene = load_map(DATA / "lab.yaml", name="lab")
    return Scene("lab", "a 12 m × 10 m lab floor plan (ROS map, 240 × 200 cells of 5 cm): desks, "
                 "a desk island, a column, a workshop behind a wall with two doors",
                 a=scene.a, b=scene.b, radius=scene.radius, names=scene.names, grid=scene.grid,
                 defaults=_defaults(path="waypoints", waypoints=LAB_PATH, start=(-3.5, -2.5),
                                    start_heading=90.0))


LAB_PATH = ((-3.5, 2.0), (0.5, 2.0), (0.5, -1.0), (4.0, -1.0), (4.0, 3.0), (1.5, 3.0),
            (1.5, 1.0), (-3.5, 1.0))
"""The ``lab`` scene's leader path (m)."""

ROBOTARIUM_BOX = (-1.6, -1.0, 1.6, 1.0)
"""The Robotarium's testbed (m): x in [-1.6, 1.6], y in [-1, 1] (``BOUNDARIES`` of its
``rps/robotarium_abc.py``)."""
ROBOTARIUM_PATH = ((0.0, 0.6), (-1.2, 0.6), (-1.2, -0.6), (1.2, -0.6), (1.2, 0.6),
                   (-1.2, 0.6))
"""The ``robotarium`` scene's leader path (m): the study's square, squeezed into the testbed
(±1.2 m × ±0.6 m; it starts north from the start, as the study's)."""


def robotarium() -> Scene:
    """The Robotarium's 3.2 m × 2 m testbed (GRITSbots; ``boids export robotarium``); the
    study's square squeezed into it, the start grid at 0.3 m cells."""
    return Scene("robotarium", "the Robotarium's 3.2 m × 2 m testbed; the study's square "
                 "squeezed to ±1.2 m × ±0.6 m, start cells 0.3 m apart", box=ROBOTARIUM_BOX,
                 defaults=_defaults(path="waypoints", waypoints=ROBOTARIUM_PATH,
                                    start=(0.0, 0.35), start_heading=90.0,
                                    layout_spacing=0.3))


BUILTIN: dict[str, Callable[[], Scene]] = {
    "arena": arena, "small_room": small_room, "doorway": doorway, "corridor": corridor,
    "pillars": pillars, "lab": lab, "robotarium": robotarium}
"""The built-in scenes by name."""
FILE_SUFFIXES = (".yaml", ".yml", ".toml", ".json")
"""A scene given as a file: a ROS map (YAML) or a shapes list (TOML or JSON)."""


def describe() -> dict[str, str]:
    """Each built-in scene's one-line description."""
    return {name: _builtin(name, 5.0).description for name in BUILTIN}


def load_scene(spec: str, arena_half_size: float = 5.0) -> Scene:
    """The scene a config names: a built-in name, a map YAML or a shapes file (TOML, JSON).

    Files are read once per content (cached on path, size and modification time).
    ``arena_half_size`` sizes the ``arena`` scene (the study's 5 m)."""
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"scene must be one of {sorted(BUILTIN)}, floorplan:SEED (a generated "
                         f"floor plan) or a .yaml map / .toml or .json shapes file, got "
                         f"{spec!r}")
    if spec in BUILTIN:
        return _builtin(spec, float(arena_half_size))
    seed = floorplans.parse(spec)
    if seed is not None:
        return _floorplan(seed)
    path = Path(spec)
    if path.suffix.lower() not in FILE_SUFFIXES:
        raise ValueError(f"scene must be one of {sorted(BUILTIN)}, floorplan:SEED (a generated "
                         f"floor plan) or a .yaml map / .toml or .json shapes file, got "
                         f"{spec!r}")
    try:
        stat = path.stat()
    except OSError as exc:
        raise ValueError(f"scene file {spec} cannot be read: {exc.strerror or exc}") from None
    return _from_file(str(path.resolve()), stat.st_size, stat.st_mtime_ns, path.suffix.lower())


@functools.lru_cache(maxsize=16)
def _builtin(name: str, half_size: float) -> Scene:
    return arena(half_size) if name == "arena" else BUILTIN[name]()


@functools.lru_cache(maxsize=64)
def _floorplan(seed: int) -> Scene:
    return floorplans.floorplan(seed)


@functools.lru_cache(maxsize=16)
def _from_file(path: str, size: int, mtime: int, suffix: str) -> Scene:
    if suffix in (".yaml", ".yml"):  # the name given decides (a symlink's target may differ)
        from boids_env.world.maps import load_map

        return load_map(path)
    from boids_env.world.shapes import load_shapes

    return load_shapes(path)


def scene_key(spec: str) -> str:
    """A file scene's resolved path (so configs made in another folder name the same file),
    a floor plan's name with its generator version (``floorplan@1:7``), a built-in's name
    unchanged."""
    if spec in BUILTIN or not spec:
        return spec
    seed = floorplans.parse(spec)
    if seed is not None:
        return floorplans.key(seed)
    return os.fspath(Path(spec).resolve())


def scene_files(spec: str) -> tuple[Path, ...]:
    """The files scene ``spec`` reads (resolved): none for a built-in or a floor plan, the
    shapes file, or a map's YAML and its image."""
    if spec in BUILTIN or not spec or floorplans.parse(spec) is not None:
        return ()  # built in, or generated from its seed
    path = Path(spec).resolve()
    if path.suffix.lower() in (".yaml", ".yml"):
        from boids_env.world.maps import read_map_yaml

        return path, read_map_yaml(path)["image"]
    return (path,)
