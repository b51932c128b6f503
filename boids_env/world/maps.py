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

from boids_env.untrusted import excerpt, parse_yaml, quote_path, read_bytes, read_text
from boids_env.world.occupancy import OccupancyGrid
from boids_env.world.scene import MAX_SPAN, STUDY_DEFAULTS, Scene

MAX_YAML_BYTES = 64 * 1024
"""A map YAML larger than this is refused (they are a few hundred bytes)."""
MAX_CELLS = 4096 * 4096
"""A map image with more cells than this is refused before it is decoded."""
MAX_IMAGE_BYTES = 64 * 1024 * 1024
"""A map image file larger than this (64 MiB) is refused before it is read."""
MAX_EDGES = 400_000
"""A map whose free space has more cell edges on its boundary than this is refused before its
contours are traced (the lab's has 1,464; a checkerboard of 4096² cells 33 million)."""
SIGNATURES = {b"\x89PNG\r\n\x1a\n": "PNG", b"P2": "PPM", b"P5": "PPM"}
"""The image formats a map may use, by their first bytes: PNG and PGM (Pillow's ``PPM``
reader); nothing else reaches Pillow, so no other decoder (GIF, TIFF, EPS through
Ghostscript, ...) ever runs on a map."""
CONTOUR_RADIUS = 0.005
"""Radius (m) of the capsules along a map's contours (thin: the contours lie on cell edges)."""
SIMPLIFY = 0.5
"""Douglas–Peucker tolerance of the contours, in cells."""
KEYS = {"image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode"}


def read_map_yaml(path: str | Path) -> dict[str, Any]:
    """The checked fields of a map YAML; ``ValueError`` naming the file and the field."""
    path = Path(path)
    where = f"map {quote_path(path)}"
    data = parse_yaml(read_text(path, "map", MAX_YAML_BYTES), where)
    if not isinstance(data, dict):
        raise ValueError(f"{where}: a map YAML is a mapping with image, resolution, origin, "
                         f"negate, occupied_thresh and free_thresh")
    missing = sorted({"image", "resolution", "origin"} - set(data))
    if missing:
        raise ValueError(f"{where}: missing {missing}")
    out: dict[str, Any] = {
        "image": data["image"],
        "resolution": _real(where, "resolution", data["resolution"], 1e-4, 100.0),
        "negate": data.get("negate", 0),
        "occupied_thresh": _real(where, "occupied_thresh", data.get("occupied_thresh", 0.65),
                                 0.0, 1.0),
        "free_thresh": _real(where, "free_thresh", data.get("free_thresh", 0.196), 0.0, 1.0),
        "mode": data.get("mode", "trinary"),
    }
    origin = data["origin"]
    if not (isinstance(origin, list) and len(origin) == 3):
        raise ValueError(f"{where}: origin must be [x, y, yaw] (m, m, rad), got "
                         f"{excerpt(origin)}")
    out["origin"] = tuple(_real(where, f"origin[{k}]", v, -1e6, 1e6) for k, v in
                          enumerate(origin))
    if out["negate"] not in (0, 1) or isinstance(out["negate"], float):
        raise ValueError(f"{where}: negate must be 0 or 1, got {excerpt(out['negate'])}")
    if out["free_thresh"] >= out["occupied_thresh"]:
        raise ValueError(f"{where}: free_thresh ({out['free_thresh']}) must be below "
                         f"occupied_thresh ({out['occupied_thresh']})")
    if out["mode"] not in ("trinary", "scale"):
        raise ValueError(f"{where}: mode must be trinary or scale, got {excerpt(out['mode'])}")
    out["image"] = _image_path(path, out["image"])
    return out


def _real(where: str, name: str, value: Any, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            math.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{where}: {name} must be a number in [{lo:g}, {hi:g}], "
                         f"got {excerpt(value)}")
    return float(value)


def _image_path(yaml_path: Path, image: Any) -> Path:
    """The image file, which must be inside the YAML's folder once every symlink is followed.

    ``image`` may be relative to the YAML (the ROS convention) or absolute, as
    ``map_saver -f /abs/path`` writes it; either way a map never reads outside its folder."""
    where = f"map {quote_path(yaml_path)}"
    if not isinstance(image, str) or not image:
        raise ValueError(f"{where}: image must be a file name, got {excerpt(image)}")
    folder = yaml_path.resolve().parent
    resolved = (folder / image).resolve()  # an absolute image replaces the folder
    if folder not in resolved.parents:
        raise ValueError(f"{where}: image {excerpt(image)} leads outside the map's folder "
                         f"(a map file is not trusted to read elsewhere); move the image beside "
                         f"the YAML and make image: relative, e.g. image: "
                         f"{excerpt(Path(image).name)}")
    if not resolved.is_file():
        raise ValueError(f"{where}: image {excerpt(image)} not found beside it")
    return resolved


def read_occupancy(fields: dict[str, Any], name: str = "map") -> npt.NDArray[np.int8]:
    """The map's cells (rows from the bottom, as ``OccupancyGrid``): 100 occupied, 0 free,
    −1 unknown.

    The image is refused, before it is decoded, unless it is a PNG or a PGM of at most
    :data:`MAX_IMAGE_BYTES` bytes and :data:`MAX_CELLS` cells whose extent (cells ×
    ``resolution``) is at most :data:`~boids_env.world.scene.MAX_SPAN` m; and after, if its
    free space has more than :data:`MAX_EDGES` boundary edges."""
    import io

    from PIL import Image

    path = fields["image"]
    where = f"map {quote_path(name)}: image {quote_path(path.name)}"
    raw = read_bytes(path, f"map {quote_path(name)}: image", MAX_IMAGE_BYTES)
    formats = [f for sig, f in SIGNATURES.items() if raw.startswith(sig)]
    if not formats:
        raise ValueError(f"{where} is not a PNG or PGM file (its first bytes are "
                         f"{excerpt(raw[:8])}); map images are PNG or PGM")
    try:
        with Image.open(io.BytesIO(raw), formats=formats) as img:
            _check_size(where, img.size, fields["resolution"])
            levels, values, white = _grey_levels(img, where)
    except ValueError:
        raise
    except Exception as exc:  # Pillow raises many kinds for a bad file
        raise ValueError(f"{where}: cannot be read ({excerpt(str(exc), 120)})") from None
    # each grey level classified once (as map_server does per pixel), then looked up: the
    # same values as per pixel in float64, without a float64 copy of the image
    p = values / white if fields["negate"] else (white - values) / white
    table = np.full(p.shape, -1, dtype=np.int8)
    table[p > fields["occupied_thresh"]] = 100
    table[p < fields["free_thresh"]] = 0
    cells = table[levels[::-1]]  # image row 0 is the top; grid row 0 the bottom
    edges = boundary_edges(cells)
    if edges > MAX_EDGES:
        raise ValueError(f"{where}: its free space has {edges:,} boundary cell edges, more than "
                         f"the {MAX_EDGES:,} allowed (is it noise or a pattern rather than a "
                         f"floor plan?)")
    return cells


def _check_size(where: str, size: tuple[int, int], resolution: float) -> None:
    width, height = size
    if width * height > MAX_CELLS or width < 1 or height < 1:
        raise ValueError(f"{where} has {width} × {height} cells; at most {MAX_CELLS} are read")
    if max(width, height) * resolution > MAX_SPAN:
        raise ValueError(f"{where}: {width} × {height} cells of resolution {resolution:g} m "
                         f"span {width * resolution:g} m × {height * resolution:g} m; a "
                         f"scene may span at most {MAX_SPAN:g} m")


def boundary_edges(cells: npt.NDArray[np.int8]) -> int:
    """How many cell edges separate free from non-free cells (the map's border a wall): what
    tracing the contours costs."""
    solid = np.pad(cells != 0, 1, constant_values=True)
    return int(np.count_nonzero(solid[1:] != solid[:-1])
               + np.count_nonzero(solid[:, 1:] != solid[:, :-1]))


WIDE_MODES = ("I", "I;16", "I;16B", "I;16L", "I;16N")
"""Pillow's modes of 16-bit grey images (a 16-bit PNG, a PGM with maxval above 255)."""


def _grey_levels(img: Any, what: str) -> tuple[npt.NDArray[Any], npt.NDArray[np.float64],
                                               float]:
    """The image's grey levels as integers, each level's grey value and the value of white,
    the image's own maximum: a PGM's maxval (1..65535; 2-byte samples above 255), 65535 for a
    16-bit PNG, 255 for 8 bits. Colour images average their channels, as ``map_server``
    does (the level is the channels' sum, its value a third of it)."""
    maxval = _pnm_maxval(img)  # read before decoding: Pillow drops the tile once loaded
    if img.mode in WIDE_MODES:
        levels: npt.NDArray[Any] = np.asarray(img)
        full = 65535
        if levels.size and not 0 <= levels.min() <= levels.max() <= full:
            raise ValueError(f"{what}: grey levels must lie in [0, 65535], got "
                             f"[{levels.min()}, {levels.max()}] (mode {img.mode})")
    elif img.mode in ("L", "P", "1", "F"):
        levels, full = np.asarray(img.convert("L")), 255
    else:  # Pillow gives colour at 8 bits whatever the file's depth: white is 255
        levels = np.asarray(img.convert("RGB")).sum(axis=2, dtype=np.uint16)
        return levels, np.arange(766, dtype=np.float64) / 3.0, 255.0
    values = np.arange(full + 1, dtype=np.float64)
    if maxval is None or maxval == full:
        return levels, values, float(full)
    # Pillow stretches a PGM's levels 0..maxval to 0..full, rounded: undo it exactly (one
    # stretched step is at least one level, so rounding back recovers every level)
    return levels, np.round(values * (maxval / full)), float(maxval)


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
