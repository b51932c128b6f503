"""ROS ``map_server`` maps as scenes: the YAML and its PGM/PNG image, read as specified.

A map YAML holds ``image`` (a path relative to the YAML), ``resolution`` (m per cell),
``origin`` ([x, y, yaw] of the lower-left pixel), ``negate`` (0/1), ``occupied_thresh``
(0.65) and ``free_thresh`` (0.196); ``mode`` may be ``trinary`` (the default) or ``scale``,
which read the thresholds the same way here. With ``negate: 0`` a pixel's occupancy is
p = (white − value) / white: occupied if p > occupied_thresh, free if p < free_thresh, unknown
between, where white is the image's own maximum (255 for 8 bits, 65535 for a 16-bit PNG, a
PGM's maxval, whose samples are 2-byte big-endian above 255). Image row 0 is the top of the
map.

The occupied and unknown cells (and the map's border: nothing leaves the map) become static
geometry: pymunk's marching squares (:func:`pymunk.autogeometry.march_hard`) trace the
boundary between free and non-free cells along the cell edges, Douglas–Peucker
(:func:`pymunk.autogeometry.simplify_curves`, half a cell) merges straight runs, and each
segment becomes a thin capsule. The cells themselves stay in the scene to tell free space
from walls exactly as the map does.

Maps come from elsewhere: the YAML is parsed with ``yaml.safe_load`` (no objects), the image
must lie in the YAML's folder once every symlink is followed (a relative path, or an absolute
one into that folder as ``map_saver -f /abs/path`` writes; never ``..`` or a symlink out), and
the sizes are bounded before anything large is allocated.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from boids_env.world.scene import STUDY_DEFAULTS, OccupancyGrid, Scene

MAX_YAML_BYTES = 64 * 1024
"""A map YAML larger than this is refused (they are a few hundred bytes)."""
MAX_CELLS = 4096 * 4096
"""A map image with more cells than this is refused before it is decoded."""
CONTOUR_RADIUS = 0.005
"""Radius (m) of the capsules along a map's contours (thin: the contours lie on cell edges)."""
SIMPLIFY = 0.5
"""Douglas–Peucker tolerance of the contours, in cells."""
KEYS = {"image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode"}


def read_map_yaml(path: str | Path) -> dict[str, Any]:
    """The checked fields of a map YAML; ``ValueError`` naming the file and the field."""
    import yaml

    path = Path(path)
    try:
        raw = path.read_bytes() if path.stat().st_size <= MAX_YAML_BYTES else None
    except OSError as exc:
        raise ValueError(f"map {path}: cannot read it ({exc.strerror or exc})") from None
    if raw is None:
        raise ValueError(f"map {path}: larger than {MAX_YAML_BYTES // 1024} KiB, not a map YAML")
    try:
        data = yaml.safe_load(raw.decode("utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"map {path}: not valid YAML ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"map {path}: a map YAML is a mapping with image, resolution, origin, "
                         f"negate, occupied_thresh and free_thresh")
    missing = sorted({"image", "resolution", "origin"} - set(data))
    if missing:
        raise ValueError(f"map {path}: missing {missing}")
    out: dict[str, Any] = {
        "image": data["image"],
        "resolution": _real(path, "resolution", data["resolution"], 1e-4, 100.0),
        "negate": data.get("negate", 0),
        "occupied_thresh": _real(path, "occupied_thresh", data.get("occupied_thresh", 0.65),
                                 0.0, 1.0),
        "free_thresh": _real(path, "free_thresh", data.get("free_thresh", 0.196), 0.0, 1.0),
        "mode": data.get("mode", "trinary"),
    }
    origin = data["origin"]
    if not (isinstance(origin, list) and len(origin) == 3):
        raise ValueError(f"map {path}: origin must be [x, y, yaw] (m, m, rad), got {origin!r}")
    out["origin"] = tuple(_real(path, f"origin[{k}]", v, -1e6, 1e6) for k, v in
                          enumerate(origin))
    if out["negate"] not in (0, 1) or isinstance(out["negate"], float):
        raise ValueError(f"map {path}: negate must be 0 or 1, got {out['negate']!r}")
    if out["free_thresh"] >= out["occupied_thresh"]:
        raise ValueError(f"map {path}: free_thresh ({out['free_thresh']}) must be below "
                         f"occupied_thresh ({out['occupied_thresh']})")
    if out["mode"] not in ("trinary", "scale"):
        raise ValueError(f"map {path}: mode must be trinary or scale, got {out['mode']!r}")
    out["image"] = _image_path(path, out["image"])
    return out


def _real(path: Path, name: str, value: Any, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            math.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"map {path}: {name} must be a number in [{lo:g}, {hi:g}], "
                         f"got {value!r}")
    return float(value)


def _image_path(yaml_path: Path, image: Any) -> Path:
    """The image file, which must be inside the YAML's folder once every symlink is followed.

    ``image`` may be relative to the YAML (the ROS convention) or absolute, as
    ``map_saver -f /abs/path`` writes it; either way a map never reads outside its folder."""
    if not isinstance(image, str) or not image:
        raise ValueError(f"map {yaml_path}: image must be a file name, got {image!r}")
    folder = yaml_path.resolve().parent
    resolved = (folder / image).resolve()  # an absolute image replaces the folder
    if folder not in resolved.parents:
        raise ValueError(f"map {yaml_path}: image {image!r} leads to {resolved}, outside the "
                         f"map's folder {folder} (a map file is not trusted to read elsewhere); "
                         f"move the image beside the YAML and make image: relative, e.g. "
                         f"image: {Path(image).name}")
    if not resolved.is_file():
        raise ValueError(f"map {yaml_path}: image {image!r} not found beside it")
    return resolved


def read_occupancy(fields: dict[str, Any], name: str = "map") -> npt.NDArray[np.int8]:
    """The map's cells (rows from the bottom, as ``OccupancyGrid``): 100 occupied, 0 free,
    −1 unknown."""
    from PIL import Image

    path = fields["image"]
    try:
        with Image.open(path) as img:
            width, height = img.size
            if width * height > MAX_CELLS or width < 1 or height < 1:
                raise ValueError(f"map {name}: image {path.name} has {width} × {height} cells; "
                                 f"at most {MAX_CELLS} are read")
            values, white = _grey_levels(img, f"map {name}: image {path.name}")
    except ValueError:
        raise
    except Exception as exc:  # Pillow raises many kinds for a bad file
        raise ValueError(f"map {name}: cannot read image {path.name} ({exc})") from None
    p = values / white if fields["negate"] else (white - values) / white
    cells = np.full(p.shape, -1, dtype=np.int8)
    cells[p > fields["occupied_thresh"]] = 100
    cells[p < fields["free_thresh"]] = 0
    return cells[::-1].copy()  # image row 0 is the top; grid row 0 the bottom


WIDE_MODES = ("I", "I;16", "I;16B", "I;16L", "I;16N")
"""Pillow's modes of 16-bit grey images (a 16-bit PNG, a PGM with maxval above 255)."""


def _grey_levels(img: Any, what: str) -> tuple[npt.NDArray[np.float64], float]:
    """The image's grey levels and the level of white, its own maximum: a PGM's maxval
    (1..65535; 2-byte samples above 255), 65535 for a 16-bit PNG, 255 for 8 bits. Colour
    images average their channels, as ``map_server`` does."""
    maxval = _pnm_maxval(img)  # read before decoding: Pillow drops the tile once loaded
    if img.mode in WIDE_MODES:
        values, full = np.asarray(img, dtype=np.float64), 65535.0
        if values.size and not 0.0 <= values.min() <= values.max() <= full:
            raise ValueError(f"{what}: grey levels must lie in [0, 65535], got "
                             f"[{values.min():g}, {values.max():g}] (mode {img.mode})")
    elif img.mode in ("L", "P", "1", "F"):
        values, full = np.asarray(img.convert("L"), dtype=np.float64), 255.0
    else:  # Pillow gives colour at 8 bits whatever the file's depth: white is 255
        return np.asarray(img.convert("RGB"), dtype=np.float64).mean(axis=2), 255.0
    if maxval is None or maxval == full:
        return values, full
    # Pillow stretches a PGM's levels 0..maxval to 0..full, rounded: undo it exactly (one
    # stretched step is at least one level, so rounding back recovers every level)
    return np.round(values * (maxval / full)), float(maxval)


def _pnm_maxval(img: Any) -> int | None:
    """A PGM/PPM's maxval from its header (None for other formats and bitmaps)."""
    if img.format != "PPM" or img.mode == "1" or not img.tile:
        return None
    args = img.tile[0][3]  # (decoder, extents, offset, args)
    if isinstance(args, tuple) and args and isinstance(args[-1], int):
        return int(args[-1])  # the "ppm" decoders take (rawmode, maxval)
    return 65535 if img.mode in WIDE_MODES else 255  # the raw decoder: maxval 255 or 65535


def contours(cells: npt.NDArray[np.int8], resolution: float,
             origin: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Segments (starts, ends) along the boundary between free and non-free cells (the map's
    border counts as a wall), in metres, and a name for each."""
    import pymunk
    from pymunk.autogeometry import march_hard, simplify_curves

    solid = np.pad(cells != 0, 1, constant_values=True)  # unknown and off-map are walls
    h, w = solid.shape
    values = solid.astype(np.float64)

    def sample(point: tuple[float, float]) -> float:
        return values[int(point[1]), int(point[0])]

    lines = march_hard(pymunk.BB(0.5, 0.5, w - 0.5, h - 0.5), w, h, 0.5, sample)
    x0, y0, yaw = origin
    c, s = math.cos(yaw), math.sin(yaw)
    starts, ends, names = [], [], []
    for k, line in enumerate(lines):
        simple = simplify_curves(line, SIMPLIFY)
        # padded cell units -> metres in the map frame -> the world (yaw about the origin)
        pts = (np.array([(p.x, p.y) for p in simple]) - 1.0) * resolution
        world = np.column_stack([x0 + c * pts[:, 0] - s * pts[:, 1],
                                 y0 + s * pts[:, 0] + c * pts[:, 1]])
        for i in range(len(world) - 1):
            if np.any(world[i] != world[i + 1]):
                starts.append(world[i])
                ends.append(world[i + 1])
                names.append(f"map contour {k} near ({world[i][0]:.2f}, {world[i][1]:.2f})")
    return np.array(starts).reshape(-1, 2), np.array(ends).reshape(-1, 2), names


def load_map(path: str | Path, name: str | None = None) -> Scene:
    """A ``map_server`` map as a scene (see the module's description)."""
    path = Path(path)
    fields = read_map_yaml(path)
    cells = read_occupancy(fields, str(path))
    starts, ends, names = contours(cells, fields["resolution"], fields["origin"])
    grid = OccupancyGrid(cells, fields["resolution"], fields["origin"])
    h, w = cells.shape
    return Scene(name or str(path), f"map {path.name}: {w} × {h} cells of "
                 f"{fields['resolution']:g} m", a=starts, b=ends,
                 radius=np.full(len(starts), CONTOUR_RADIUS), names=tuple(names), grid=grid,
                 defaults=dict(STUDY_DEFAULTS))


def write_map(path: str | Path, cells: npt.NDArray[np.int8], resolution: float,
              origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Path:
    """Writes ``cells`` (rows from the bottom: 100 occupied, 0 free, −1 unknown) as a
    ``map_server`` map: ``path`` (YAML) and a PGM beside it, as ``map_saver`` does (occupied
    0, free 254, unknown 205). Returns the YAML's path."""
    from PIL import Image

    path = Path(path)
    pixels = np.full(cells.shape, 205, dtype=np.uint8)
    pixels[cells == 100] = 0
    pixels[cells == 0] = 254
    image = path.with_suffix(".pgm")
    Image.fromarray(pixels[::-1]).save(image)
    path.write_text(f"image: {image.name}\nresolution: {resolution}\n"
                    f"origin: [{origin[0]}, {origin[1]}, {origin[2]}]\nnegate: 0\n"
                    f"occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return path
