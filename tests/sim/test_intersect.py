"""sim/intersect.py: the vectorised segment-triangle test agrees with ipctk's, pair by pair."""

import ipctk
import numpy as np

from sim.intersect import crossing_pairs, segments_cross_triangles


def test_segment_triangle_test_agrees_with_ipctk():
    rng = np.random.default_rng(3)
    n = 4000
    a, b, c = (rng.normal(size=(n, 3)) for _ in range(3))
    # Segments through points near each triangle's centroid, long enough to reach it often.
    m = (a + b + c) / 3 + 0.3 * rng.normal(size=(n, 3))
    d = rng.normal(size=(n, 3))
    p, q = m - d * rng.uniform(0, 1, (n, 1)), m + d * rng.uniform(0, 1, (n, 1))
    ours = segments_cross_triangles(p, q, a, b, c)
    theirs = np.array([ipctk.is_edge_intersecting_triangle(*v) for v in zip(p, q, a, b, c)])
    assert 0.2 * n < ours.sum() < 0.8 * n  # both outcomes well represented
    assert np.array_equal(ours, theirs)


def test_segments_in_the_plane_or_on_a_border_are_decided_as_ipctk_does():
    """GarmentCode lays panels flat in one plane and edge to edge: coplanar overlaps (two
    back panels of skirt_02 lie over each other) and ends on a border count as ipctk
    counts them, whatever round-off says."""
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    cases = [((0.1, 0.1, 0.0), (0.9, 0.05, 0.0)),   # in the plane, inside
             ((-1.0, 0.2, 0.0), (2.0, 0.2, 0.0)),   # in the plane, across
             ((2.0, 2.0, 0.0), (3.0, 2.0, 0.0)),    # in the plane, beside
             ((0.2, 0.2, 0.0), (0.2, 0.2, 1.0)),    # an end on the triangle
             ((0.5, 0.5, -1.0), (0.5, 0.5, 1.0)),   # through the hypotenuse
             ((0.0, 0.0, -1.0), (0.0, 0.0, 1.0)),   # through a corner
             ((0.3, 0.3, 1e-17), (0.6, 0.1, -1e-17))]  # across the plane at round-off
    p, q = (np.array([case[i] for case in cases]) for i in (0, 1))
    A, B, C = (np.tile(v, (len(cases), 1)) for v in (a, b, c))
    theirs = [ipctk.is_edge_intersecting_triangle(*v) for v in zip(p, q, A, B, C)]
    assert segments_cross_triangles(p, q, A, B, C).tolist() == theirs


def test_crossing_pairs_finds_a_segment_through_a_triangle_and_skips_neighbours():
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0],  # triangle 0
                  [0.2, 0.2, -1], [0.2, 0.2, 1],    # segment 0 through it
                  [2, 2, -1], [2, 2, 1],            # segment 1 beside it
                  [0, 0, 1.0]], float)              # with vertex 0: segment 2 from a corner
    edges = np.array([[3, 4], [5, 6], [0, 7]])
    faces = np.array([[0, 1, 2]])
    assert crossing_pairs(x, edges, faces).tolist() == [[0, 0]]
