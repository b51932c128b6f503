"""Scenes given as a list of shapes in a TOML or JSON file.

```toml
name = "my lab corner"          # optional
box = [-4.0, -3.0, 4.0, 3.0]    # optional: enclosing walls' inner faces xmin, ymin, xmax, ymax

[[circle]]                      # a round pillar
center = [1.0, 0.5]
radius = 0.15

[[segment]]                     # a wall: a segment swept by a radius (half its thickness)
a = [-2.0, 1.0]
b = [2.0, 1.0]
radius = 0.05

[[polygon]]                     # a convex solid block, corners in order
points = [[2.0, -2.0], [3.0, -2.0], [3.0, -1.0], [2.0, -1.0]]

[defaults]                      # optional scenario fields: the scene's leader path and start
path = "waypoints"
waypoints = [[3.0, 0.0], [-3.0, 0.0]]
start = [-3.0, -1.0]
start_heading = 0.0
```

JSON takes the same keys. Every value is checked (finite numbers in range, convex polygons)
and unknown keys are refused; nothing in the file is executed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from boids_env.untrusted import (
    excerpt,
    parse_json,
    parse_toml,
    printable,
    quote_path,
    read_text,
    safe_name,
)
from boids_env.world import geometry as geo
from boids_env.world.scene import MAX_SPAN, SCENE_FIELDS, STUDY_DEFAULTS, Scene

MAX_BYTES = 1024 * 1024
"""A shapes file larger than this is refused."""
MAX_SHAPES = 10_000
"""At most this many shapes (and polygon corners) in one file."""
LIMIT = 1e4
"""Coordinates and radii are bounded by this (m)."""
TOP_KEYS = {"name", "description", "box", "circle", "segment", "polygon", "defaults"}


def load_shapes(path: str | Path) -> Scene:
    """The scene of a shapes file (TOML or JSON); ``ValueError`` naming the file and entry."""
    path = Path(path)
    where = f"scene {quote_path(path)}"
    text = read_text(path, "scene", MAX_BYTES)
    data = parse_json(text, where) if path.suffix.lower() == ".json" else parse_toml(text, where)
    if not isinstance(data, dict):
        raise ValueError(f"{where}: the file must hold a table of shapes")
    return shapes_scene(data, quote_path(path))


def shapes_scene(data: dict[str, Any], name: str) -> Scene:
    """A scene from the parsed content of a shapes file (see the module's description)."""
    unknown = sorted(set(data) - TOP_KEYS)
    if unknown:
        raise ValueError(f"scene {name}: unknown key(s) {unknown}; allowed: {sorted(TOP_KEYS)}")
    box: tuple[float, float, float, float] | None = None
    if "box" in data:
        x0, y0, x1, y1 = _numbers(name, "box", data["box"], 4)
        box = (x0, y0, x1, y1)
        if not (box[0] < box[2] and box[1] < box[3]):
            raise ValueError(f"scene {name}: box must be [xmin, ymin, xmax, ymax] with min < "
                             f"max, got {list(box)}")
        if max(box[2] - box[0], box[3] - box[1]) > MAX_SPAN:
            raise ValueError(f"scene {name}: box spans {box[2] - box[0]:g} m × "
                             f"{box[3] - box[1]:g} m; a scene may span at most {MAX_SPAN:g} m")
    a, b, r, names = [], [], [], []
    for k, entry in enumerate(_entries(name, data, "circle", {"center", "radius"})):
        c = _numbers(name, f"circle {k} center", entry.get("center"), 2)
        a.append(c)
        b.append(c)
        r.append(_radius(name, f"circle {k} radius", entry.get("radius"), positive=True))
        names.append(f"circle {k} at ({c[0]:g}, {c[1]:g})")
    for k, entry in enumerate(_entries(name, data, "segment", {"a", "b", "radius"})):
        a.append(_numbers(name, f"segment {k} a", entry.get("a"), 2))
        b.append(_numbers(name, f"segment {k} b", entry.get("b"), 2))
        r.append(_radius(name, f"segment {k} radius", entry.get("radius", 0.05)))
        names.append(f"segment {k} from ({a[-1][0]:g}, {a[-1][1]:g}) to ({b[-1][0]:g}, "
                     f"{b[-1][1]:g})")
    polygons = []
    for k, entry in enumerate(_entries(name, data, "polygon", {"points"})):
        polygons.append(_convex(name, k, entry.get("points")))
        names.append(f"polygon {k}")
    if box is None and not names:
        raise ValueError(f"scene {name}: no box and no shapes")
    defaults = dict(STUDY_DEFAULTS)
    given = data.get("defaults", {})
    if not isinstance(given, dict) or set(given) - set(SCENE_FIELDS):
        raise ValueError(f"scene {name}: defaults must be a table of scenario fields among "
                         f"{list(SCENE_FIELDS)}, got {excerpt(given)}")
    defaults.update({k: tuple(map(tuple, v)) if k == "waypoints" and isinstance(v, list)
                     else tuple(v) if k == "start" and isinstance(v, list) else v
                     for k, v in given.items()})
    description = data.get("description", f"shapes file {Path(name).name}")
    if not isinstance(description, str):
        raise ValueError(f"scene {name}: description must be a string, got "
                         f"{excerpt(description)}")
    description = printable(description, 400)
    scene_name = safe_name(data.get("name", name), f"scene {name}: name", limit=300)
    return Scene(scene_name, description, box=box,
                 a=np.array(a).reshape(-1, 2), b=np.array(b).reshape(-1, 2), radius=np.array(r),
                 polygons=tuple(polygons), names=tuple(names), defaults=defaults)


def _entries(name: str, data: dict[str, Any], key: str, allowed: set[str]
             ) -> list[dict[str, Any]]:
    entries = data.get(key, [])
    if not isinstance(entries, list) or len(entries) > MAX_SHAPES:
        raise ValueError(f"scene {name}: {key} must be a list of at most {MAX_SHAPES} tables")
    for k, entry in enumerate(entries):
        if not isinstance(entry, dict) or set(entry) - allowed:
            raise ValueError(f"scene {name}: {key} {k} must be a table with keys "
                             f"{sorted(allowed)}, got {excerpt(entry)}")
    return entries


def _numbers(name: str, what: str, value: Any, count: int) -> list[float]:
    ok = isinstance(value, list) and len(value) == count and all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
        and abs(v) <= LIMIT for v in value)
    if not ok:
        raise ValueError(f"scene {name}: {what} must be {count} finite numbers within "
                         f"±{LIMIT:g} m, got {excerpt(value)}")
    return [float(v) for v in value]


def _radius(name: str, what: str, value: Any, positive: bool = False) -> float:
    ok = (isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
          and (value > 0 if positive else value >= 0) and value <= LIMIT)
    if not ok:
        bound = "(0" if positive else "[0"
        raise ValueError(f"scene {name}: {what} must be in {bound}, {LIMIT:g}] m, got "
                         f"{excerpt(value)}")
    return float(value)


def _convex(name: str, k: int, points: Any) -> np.ndarray:
    """A polygon's corners, counter-clockwise; ``ValueError`` unless convex with ≥ 3."""
    if not isinstance(points, list) or not 3 <= len(points) <= MAX_SHAPES:
        raise ValueError(f"scene {name}: polygon {k} points must be a list of 3 to {MAX_SHAPES} "
                         f"[x, y] corners, got {excerpt(points)}")
    p = np.array([_numbers(name, f"polygon {k} corner {i}", q, 2) for i, q in enumerate(points)])
    turns = geo.cross(np.roll(p, -1, axis=0) - p, np.roll(p, -2, axis=0) - np.roll(p, -1, axis=0))
    if not (np.all(turns > 0) or np.all(turns < 0)):
        raise ValueError(f"scene {name}: polygon {k} must be convex with distinct corners (split a "
                         f"concave block into convex ones)")
    return p if turns[0] > 0 else p[::-1].copy()
