"""Plane geometry on hand-computed values: segments, rays, capsules, polygons."""

import math

import numpy as np
import pytest

from boids_env.world import geometry as geo


def test_closest_point_on_a_segment_and_its_distance():
    a, b = np.array([0.0, 0.0]), np.array([4.0, 0.0])
    pts = np.array([[1.0, 3.0], [-3.0, 4.0], [6.0, 0.0], [2.0, 0.0]])
    closest, d = geo.closest_on_segments(pts, a, b)
    np.testing.assert_array_equal(closest, [[1, 0], [0, 0], [4, 0], [2, 0]])
    np.testing.assert_array_equal(d, [3.0, 5.0, 2.0, 0.0])
    # a degenerate segment is a point
    _, d = geo.closest_on_segments(np.array([[3.0, 4.0]]), a, a)
    assert d[0] == 5.0


def test_distance_between_segments_is_zero_where_they_cross():
    d = geo.segments_distance(np.array([[0.0, -1.0], [0.0, 2.0]]), np.array([[0.0, 1.0],
                                                                            [0.0, 5.0]]),
                              np.array([-1.0, 0.0]), np.array([1.0, 0.0]))
    np.testing.assert_array_equal(d, [0.0, 2.0])
    parallel = geo.segments_distance(np.array([0.0, 1.0]), np.array([2.0, 1.0]),
                                     np.array([0.0, 0.0]), np.array([2.0, 0.0]))
    assert parallel == 1.0


def test_rays_hit_segments_circles_and_capsules_at_hand_computed_distances():
    o = np.array([0.0, 0.0])
    east, north = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    wall_a, wall_b = np.array([3.0, -1.0]), np.array([3.0, 1.0])
    assert geo.ray_segments(o, east, wall_a, wall_b) == 3.0
    assert geo.ray_segments(o, north, wall_a, wall_b) == np.inf
    assert geo.ray_segments(o, -east, wall_a, wall_b) == np.inf, "behind the ray"
    assert geo.ray_circles(o, east, np.array([5.0, 0.0]), np.array(1.0)) == 4.0
    assert geo.ray_circles(o, north, np.array([5.0, 0.0]), np.array(1.0)) == np.inf
    assert geo.ray_circles(o, east, np.array([0.5, 0.0]), np.array(1.0)) == 0.0, "inside"
    # a 0.2 m thick wall at x = 3: its face at 2.9; a ray 45° up meets its round end
    r = np.array(0.1)
    assert geo.ray_capsules(o, east, wall_a, wall_b, r) == pytest.approx(2.9)
    end = geo.ray_capsules(o, north, np.array([0.0, 2.0]), np.array([0.0, 2.0]), r)
    assert end == pytest.approx(1.9)
    diag = np.array([math.sqrt(0.5), math.sqrt(0.5)])
    hit = geo.ray_capsules(o, diag, np.array([3.0, -1.0]), np.array([3.0, 3.0]), r)
    assert hit == pytest.approx(2.9 * math.sqrt(2))


def test_points_in_a_convex_polygon():
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    inside = geo.points_in_polygon(np.array([[1.0, 1.0], [3.0, 1.0], [-0.5, 0.5], [1.0, 1.9]]),
                                   square)
    assert inside.tolist() == [True, False, False, True]
