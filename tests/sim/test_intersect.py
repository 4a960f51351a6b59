"""sim/intersect.py and sim/bvh.py: the float test agrees with ipctk's pair by pair, and
the tree finds every crossing pair that testing all pairs with ipctk finds."""

import ipctk
import numpy as np
import pytest

from sim import bvh
from sim.intersect import Triangles, crossing_pairs


def test_segment_triangle_verdict_agrees_with_ipctk():
    rng = np.random.default_rng(3)
    n = 4000
    a, b, c = (rng.normal(size=(n, 3)) for _ in range(3))
    # Segments through points near each triangle's centroid, long enough to reach it often.
    m = (a + b + c) / 3 + 0.3 * rng.normal(size=(n, 3))
    d = rng.normal(size=(n, 3))
    p, q = m - d * rng.uniform(0, 1, (n, 1)), m + d * rng.uniform(0, 1, (n, 1))
    ours = np.array([bvh.verdict(*v, 1e-9) for v in zip(p, q, a, b, c)])
    theirs = np.array([ipctk.is_edge_intersecting_triangle(*v) for v in zip(p, q, a, b, c)])
    assert (ours == bvh.UNSURE).sum() == 0  # generic positions: the float test decides
    assert 0.2 * n < (ours == bvh.HIT).sum() < 0.8 * n  # both outcomes well represented
    assert np.array_equal(ours == bvh.HIT, theirs)


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
             ((0.3, 0.3, 1e-17), (0.6, 0.1, -1e-17)),  # across the plane at round-off
             ((0.3, 0.3, 1e-12), (0.6, 0.1, 1e-12))]   # parallel, just above the plane
    x = np.concatenate([[a, b, c], np.array(cases).reshape(-1, 3)])
    edges = 3 + np.arange(2 * len(cases)).reshape(-1, 2)
    theirs = [k for k, (p, q) in enumerate(cases) if ipctk.is_edge_intersecting_triangle(p, q, a, b, c)]
    assert 0 < len(theirs) < len(cases)
    assert crossing_pairs(x, edges, np.array([[0, 1, 2]]))[:, 0].tolist() == theirs


def _sheet(n, lift, rng):
    """An n x n grid of unit size, its vertices jittered in its plane z = lift (a flat
    panel) and its triangles."""
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    x = np.stack([u, v, np.full_like(u, lift)], -1).reshape(-1, 3)
    x[:, :2] += rng.uniform(-0.2, 0.2, (len(x), 2)) / n
    i = np.arange(n * n).reshape(n, n)
    quads = np.stack([i[:-1, :-1], i[:-1, 1:], i[1:, 1:], i[1:, :-1]], -1).reshape(-1, 4)
    return x, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


@pytest.mark.parametrize("n_segments", [30, 600])  # tree over the triangles, then over the segments
def test_crossing_pairs_are_the_pairs_ipctk_finds_testing_every_pair(n_segments):
    """Two sheets in one plane (GarmentCode's overlapping panels: borders and coplanar
    pairs everywhere), a third crumpled across them, and random segments from short to
    as long as the scene, some sharing a vertex with a triangle."""
    rng = np.random.default_rng(n_segments)
    x0, f0 = _sheet(8, 0.0, rng)
    x1, f1 = _sheet(8, 0.0, rng)
    x1[:, :2] += 0.3
    x2, f2 = _sheet(8, 0.0, rng)
    x2[:, 2] = 0.3 * np.sin(7 * x2[:, 0]) * np.cos(5 * x2[:, 1])
    x = np.concatenate([x0, x1, x2])
    faces = np.concatenate([f0, f1 + len(x0), f2 + len(x0) + len(x1)])
    starts = rng.integers(len(x), size=n_segments)  # segments from mesh vertices ...
    ends = len(x) + np.arange(n_segments)
    x = np.concatenate([x, x[starts] + rng.normal(size=(n_segments, 3)) * rng.uniform(0.01, 1, (n_segments, 1))])
    edges = np.stack([starts, ends], 1)
    x = np.concatenate([x, x[ends[::3]] + 0.3 * rng.normal(size=(len(ends[::3]), 3))])
    edges[::3, 0] = len(x) - len(ends[::3]) + np.arange(len(ends[::3]))  # ... and every third from a free point
    theirs = {(e, f) for e, (i, j) in enumerate(edges) for f, tri in enumerate(faces)
              if not set(tri) & {i, j} and ipctk.is_edge_intersecting_triangle(x[i], x[j], *x[tri])}
    ours = crossing_pairs(x, edges, faces)
    assert len(theirs) >= n_segments // 10  # crossings well represented
    assert {tuple(p) for p in ours.tolist()} == theirs


def test_a_flat_panels_own_edges_and_triangles_are_decided_without_the_exact_test():
    """A flat panel's edges lie in its triangles' plane, so the plane test cannot tell;
    seen along the normal they are clear of the triangles they share no vertex with, and
    that decides them (dress_04's layout: 2.2M such pairs, 24 s in ipctk's test)."""
    rng = np.random.default_rng(5)
    x, faces = _sheet(12, 0.0, rng)
    x = x @ np.linalg.qr(rng.normal(size=(3, 3)))[0]  # a tilted plane: round-off in every coordinate
    edges = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    tree = bvh.build(x, faces)
    found = bvh.crossings(x, edges, faces, *tree, 1e-7, 1e-9, True)
    assert len(found) == 0  # neither hits nor pairs left to ipctk
    # Pairs that do meet in the plane still go to ipctk: each edge against a triangle that
    # a copy of the sheet, shifted by a quarter cell, puts across it.
    y = np.concatenate([x, x + 0.25 / 11 * (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])])
    found = bvh.crossings(y, edges + len(x), faces, *bvh.build(y, faces), 1e-7, 1e-9, True)
    assert len(found) > len(edges) and (found[:, 2] == bvh.UNSURE).all()


def test_crossing_pairs_finds_a_segment_through_a_triangle_and_skips_neighbours():
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0],  # triangle 0
                  [0.2, 0.2, -1], [0.2, 0.2, 1],    # segment 0 through it
                  [2, 2, -1], [2, 2, 1],            # segment 1 beside it
                  [0, 0, 1.0]], float)              # with vertex 0: segment 2 from a corner
    edges = np.array([[3, 4], [5, 6], [0, 7]])
    faces = np.array([[0, 1, 2]])
    assert crossing_pairs(x, edges, faces).tolist() == [[0, 0]]


def test_a_body_tree_built_once_serves_every_segment_set():
    """Triangles keeps one tree for the body; seam routes test ten sets of paths a step."""
    rng = np.random.default_rng(7)
    V, F = _sheet(10, 0.0, rng)
    V[:, 2] = 0.2 * np.sin(6 * V[:, 0])
    body = Triangles(V, F)
    for _ in range(3):
        p, q = rng.uniform(-0.2, 1.2, (200, 3)), rng.uniform(-0.2, 1.2, (200, 3))
        x = np.concatenate([np.stack([p, q], 1).reshape(-1, 3), V])
        fresh = crossing_pairs(x, np.arange(400).reshape(-1, 2), F + 400)
        assert len(fresh) > 10
        assert np.array_equal(body.crossed(p, q), fresh)
