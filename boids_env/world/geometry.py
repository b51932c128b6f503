"""Plane geometry on numpy arrays: capsules, rays, polygons. No pymunk, no state.

A *capsule* is a segment ``a``–``b`` swept by a disc of radius ``r``: a wall of thickness
``2r``, a round pillar (``a == b``), or a thin map contour (small ``r``). Every function
broadcasts over leading axes and uses only elementwise arithmetic and ``sqrt`` (correctly
rounded in IEEE 754), no BLAS and no transcendental functions, so its results are the same
bit for bit on every CPU.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def dot(u: FloatArray, v: FloatArray) -> FloatArray:
    """Dot product over the last axis (size 2) with a fixed order of operations."""
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]


def cross(u: FloatArray, v: FloatArray) -> FloatArray:
    """The z component of the cross product of 2-vectors (last axis)."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def norm(u: FloatArray) -> FloatArray:
    """Euclidean length over the last axis (size 2)."""
    return np.sqrt(dot(u, u))


def closest_on_segments(points: FloatArray, a: FloatArray, b: FloatArray
                        ) -> tuple[FloatArray, FloatArray]:
    """The point of each segment ``a``–``b`` nearest to ``points`` and its distance.

    Args:
        points, a, b: (..., 2), broadcast against each other.

    Returns:
        ``(closest (..., 2), distance (...))``; a degenerate segment (``a == b``) is a point.
    """
    ab = b - a
    length2 = dot(ab, ab)
    t = np.clip(dot(points - a, ab) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    closest = a + t[..., None] * ab
    return closest, norm(points - closest)


def segments_distance(p0: FloatArray, p1: FloatArray, a: FloatArray, b: FloatArray
                      ) -> FloatArray:
    """Smallest distance between segments ``p0``–``p1`` and ``a``–``b`` (0 where they cross),
    broadcast over leading axes."""
    d = np.minimum(np.minimum(closest_on_segments(p0, a, b)[1],
                              closest_on_segments(p1, a, b)[1]),
                   np.minimum(closest_on_segments(a, p0, p1)[1],
                              closest_on_segments(b, p0, p1)[1]))
    u, v, w = p1 - p0, b - a, a - p0
    denom = cross(u, v)
    safe = np.where(denom != 0, denom, 1.0)
    s = cross(w, v) / safe  # along p0-p1
    t = cross(w, u) / safe  # along a-b
    crossing = (denom != 0) & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    return np.where(crossing, 0.0, d)


def ray_segments(origins: FloatArray, directions: FloatArray, a: FloatArray, b: FloatArray
                 ) -> FloatArray:
    """Distance along unit rays to segments (inf where a ray misses).

    Args:
        origins: (..., 2) ray starts; directions: (..., 2) unit vectors; a, b: (..., 2)
            segment ends; all broadcast.
    """
    v = b - a
    w = a - origins
    denom = cross(directions, v)
    safe = np.where(denom != 0, denom, 1.0)
    t = cross(w, v) / safe  # along the ray
    s = cross(w, directions) / safe  # along the segment
    hit = (denom != 0) & (t >= 0) & (s >= 0) & (s <= 1)
    return np.where(hit, t, np.inf)


def ray_circles(origins: FloatArray, directions: FloatArray, centres: FloatArray,
                radii: FloatArray) -> FloatArray:
    """Distance along unit rays to the first crossing of circles (0 for a ray starting inside
    one, inf where it misses), broadcast over leading axes."""
    rel = centres - origins
    along = dot(rel, directions)
    across2 = dot(rel, rel) - along * along
    disc = radii * radii - across2
    root = np.sqrt(np.maximum(disc, 0.0))
    inside = dot(rel, rel) <= radii * radii
    t = along - root
    hit = (disc >= 0) & (along + root >= 0)
    return np.where(inside, 0.0, np.where(hit & (t >= 0), t, np.inf))


def ray_capsules(origins: FloatArray, directions: FloatArray, a: FloatArray, b: FloatArray,
                 radii: FloatArray) -> FloatArray:
    """Distance along unit rays to capsules (``a``–``b`` swept by ``radii``): the nearer of
    its two end discs and its two flat sides; 0 for a ray starting inside."""
    ends = np.minimum(ray_circles(origins, directions, a, radii),
                      ray_circles(origins, directions, b, radii))
    v = b - a
    length = norm(v)
    long = length > 0
    normal = np.stack([-v[..., 1], v[..., 0]], axis=-1) / np.where(long, length, 1.0)[..., None]
    offset = normal * radii[..., None]
    sides = np.minimum(ray_segments(origins, directions, a + offset, b + offset),
                       ray_segments(origins, directions, a - offset, b - offset))
    inside = closest_on_segments(origins, a, b)[1] <= radii
    best = np.minimum(ends, np.where(long, sides, np.inf))
    return np.where(inside, 0.0, best)


def points_in_polygon(points: FloatArray, polygon: FloatArray) -> BoolArray:
    """Whether each point (P, 2) lies inside the polygon (V, 2) (even-odd rule; a point on
    the boundary may count either way)."""
    x, y = points[:, 0:1], points[:, 1:2]
    x0, y0 = polygon[:, 0][None], polygon[:, 1][None]
    x1, y1 = np.roll(polygon[:, 0], -1)[None], np.roll(polygon[:, 1], -1)[None]
    straddles = (y0 > y) != (y1 > y)
    safe = np.where(y1 != y0, y1 - y0, 1.0)
    at = x0 + (y - y0) * (x1 - x0) / safe
    crossings = straddles & (x < at)
    return (crossings.sum(axis=1) % 2) == 1
