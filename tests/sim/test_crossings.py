"""The crossing searches of sim/contact/mesh.py against a brute-force search over every
edge-triangle pair (no broad phase, no filtering of candidates)."""

import itertools

import ipctk
import numpy as np

from sim.contact.mesh import _crossings, crossings_at


def grid(n, origin, du, dv, rng):
    """An n x n vertex sheet, jittered, and its triangles."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    V = origin + i.reshape(-1, 1) / (n - 1) * du + j.reshape(-1, 1) / (n - 1) * dv
    V = V + 0.01 * rng.standard_normal(V.shape)
    k = (i[:-1, :-1] * n + j[:-1, :-1]).ravel()
    F = np.concatenate([np.c_[k, k + n, k + 1], np.c_[k + 1, k + n, k + n + 1]])
    return V, F


def scene():
    """Cloth: a sheet in z = 0 and one through it in y = 0.5. Body: two sheets through each
    other (bodies may cross themselves) and through the first cloth sheet."""
    rng = np.random.default_rng(3)
    parts = [grid(7, np.array([0.0, 0.0, 0.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), rng),
             grid(6, np.array([0.1, 0.5, -0.4]), np.array([0.8, 0, 0]), np.array([0, 0.02, 0.8]), rng),
             grid(5, np.array([0.6, 0.1, -0.3]), np.array([0, 0.8, 0]), np.array([0.03, 0, 0.6]), rng),
             grid(5, np.array([0.3, 0.3, 0.2]), np.array([0.6, 0, 0]), np.array([0.0, 0.5, -0.5]), rng)]
    V, F, offset = [], [], 0
    for X, T in parts:
        V.append(X)
        F.append(T + offset)
        offset += len(X)
    V, F = np.concatenate(V), np.concatenate(F).astype(np.int32)
    mesh = ipctk.CollisionMesh(V, ipctk.edges(F), F)
    return mesh, np.asfortranarray(V), len(parts[0][0]) + len(parts[1][0])


def brute_force(mesh, x, n_cloth):
    found = set()
    for e, f in itertools.product(mesh.edges, mesh.faces):
        if set(e) & set(f) or min(e.min(), f.min()) >= n_cloth:
            continue
        if ipctk.is_edge_intersecting_triangle(x[e[0]], x[e[1]], x[f[0]], x[f[1]], x[f[2]]):
            found.add((tuple(sorted(e)), tuple(sorted(f))))
    return found


def test_crossings_match_a_brute_force_search_whole_and_around_chosen_vertices():
    mesh, x, n_cloth = scene()
    truth = brute_force(mesh, x, n_cloth)
    assert len(truth) > 20  # the sheets do cross, cloth with cloth and cloth with body
    assert any(min(f) >= n_cloth for _, f in truth) and any(max(e) < n_cloth for e, _ in truth)
    found = [(tuple(sorted(e)), tuple(sorted(f))) for e, f in _crossings(mesh, x, n_cloth)]
    assert len(found) == len(set(found)) and set(found) == truth
    rng = np.random.default_rng(0)
    for vertices in (np.arange(n_cloth), rng.choice(len(x), 12, replace=False), np.array([0])):
        near = [(tuple(sorted(e)), tuple(sorted(f))) for e, f in _crossings(mesh, x, n_cloth, vertices)]
        mine = set(vertices.tolist())
        expected = {(e, f) for e, f in truth if mine & set(e + f)}
        assert len(near) == len(set(near)) and set(near) == expected
        hit = {v for e, f in expected for v in e + f if v in mine}
        np.testing.assert_array_equal(crossings_at(mesh, x, n_cloth, vertices), sorted(hit))
