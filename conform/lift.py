"""Lifting the rest control net to the panel's 3D placement (docs/design.md section 4b.5).

The placement is the piecewise-linear map rest -> world of the panel's triangles. The
world control net is the least-squares fit of the surface (not of the control net) to
that map at 3 x 3 parameter samples per span: interpolating the control net instead
would shrink a curved placement (a draped garment) by about h^2 kappa / 8 (2 mm at 40 mm
spans around a limb), pushing it into the body it was draped on. Flat placements are
affine maps, which quadratic B-splines reproduce, so both give the same net there.

A sample inside the rest mesh takes the barycentric combination of the 3D positions of
its containing triangle. One outside (the boundary curve may leave the outline by its
fitting error) uses the nearest triangle, its barycentric coordinates clamped to
[-0.5, 1.5] (and renormalised) so the extrapolation stays local.
Panels placed by a rigid transform (GarmentCode) map the rest points directly.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from sim.patches import Panel
from sim.embedding import interpolation_matrix


def barycentric(P: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(K, 3) barycentric coordinates of points P (K, 2) in triangles tri (K, 3, 2)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, P - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    return np.stack([1.0 - l1 - l2, l1, l2], axis=1)


def locate(panel: Panel, P: np.ndarray, k: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For rest points P (K, 2): triangle index (K,), barycentric coordinates (K, 3) and
    whether the point is inside that triangle (K,) - else the nearest triangle.
    The k triangles with the nearest centroids are tried first, then 8 k."""
    X, F = panel.rest, panel.faces
    centroids = X[F].mean(axis=1)
    tree = cKDTree(centroids)
    k = min(k, F.shape[0])
    _, near = tree.query(P, k=k)
    near = near.reshape(P.shape[0], k)
    tri = np.empty(P.shape[0], np.int64)
    bary = np.empty((P.shape[0], 3))
    inside = np.zeros(P.shape[0], bool)
    for j in range(k):  # nearest first; take the first triangle that contains the point
        todo = ~inside
        if not todo.any():
            break
        t = near[todo, j]
        b = barycentric(P[todo], X[F[t]])
        hit = b.min(axis=1) >= -1e-9
        idx = np.nonzero(todo)[0][hit]
        tri[idx], bary[idx], inside[idx] = t[hit], b[hit], True
    # Not among the nearest centroids (skinny triangles, or a point outside the mesh): look
    # wider (8 k candidates, every triangle of a small mesh), take the containing triangle,
    # else the one nearest by distance, so a point just outside the boundary extrapolates
    # from the triangle it is next to.
    todo = np.nonzero(~inside)[0]
    if todo.size:
        wide = F.shape[0] if F.shape[0] <= 512 else 8 * k
        cand = tree.query(P[todo], k=wide)[1].reshape(todo.size, wide) if wide < F.shape[0] else \
            np.broadcast_to(np.arange(F.shape[0]), (todo.size, F.shape[0]))
        for start in range(0, todo.size, 16):
            ids, C = todo[start:start + 16], cand[start:start + 16]
            Kc, W = C.shape
            T = X[F[C]].reshape(Kc * W, 3, 2)
            Q = np.repeat(P[ids], W, axis=0)
            b = barycentric(Q, T).reshape(Kc, W, 3)
            dist = _triangle_distance(Q, T).reshape(Kc, W)
            dist[b.min(axis=2) >= -1e-9] = 0.0  # containing triangles first
            j = np.argmin(dist, axis=1)
            r = np.arange(Kc)
            bb = b[r, j]
            hit = dist[r, j] == 0.0
            bb = np.where(hit[:, None], bb, np.clip(bb, -0.5, 1.5))
            tri[ids], bary[ids], inside[ids] = C[r, j], bb / bb.sum(axis=1, keepdims=True), hit
    return tri, bary, inside


def _triangle_distance(Q: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Distance from each point Q (K, 2) to the edges of its triangle T (K, 3, 2)."""
    best = np.full(Q.shape[0], np.inf)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        A, e = T[:, a], T[:, b] - T[:, a]
        t = np.clip(((Q - A) * e).sum(1) / np.maximum((e**2).sum(1), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(Q - (A + t[:, None] * e), axis=1))
    return best


SAMPLES_PER_SPAN = 3
# Weight of the control net's second differences, relative to the fit's mean diagonal:
# keeps the fit from folding on itself where the drape wrinkles below the knot span
# (0.01 leaves the dress_knife drape free of self-intersections and moves it < 1 mm).
SMOOTHING = 0.01


def lift(panel: Panel, X: np.ndarray, warp=None) -> np.ndarray:
    """World control net (n, m, 3) for the rest net X (n, m, 2); warp: rest points (P, 2)
    -> displacement (P, 3) added to the placement (folded pleats)."""
    n, m = X.shape[:2]
    mesh = panel.world is not None and panel.faces is not None
    if not mesh and warp is None:
        return panel.place(X.reshape(-1, 2)).reshape(n, m, 3)
    u = np.linspace(0.0, n - 2, SAMPLES_PER_SPAN * (n - 2) + 1)
    v = np.linspace(0.0, m - 2, SAMPLES_PER_SPAN * (m - 2) + 1)
    U, V = np.meshgrid(u, v, indexing="ij")
    N = interpolation_matrix(U.ravel(), V.ravel(), n, m, 0, n * m)
    P = N @ X.reshape(-1, 2)
    if mesh:
        tri, bary, _ = locate(panel, P)
        target = np.einsum("kj,kjd->kd", bary, panel.world[panel.faces[tri]])
        # Smooth the departure from the best affine placement, so flat (affine)
        # placements, which quadratic B-splines reproduce, come out exact.
        C_affine = np.c_[X.reshape(-1, 2), np.ones(n * m)] @ affine_map(panel)
    else:
        target, C_affine = panel.place(P), panel.place(X.reshape(-1, 2))
    if warp is not None:  # the warp evaluated exactly, not through the mesh's chords
        target = target + warp(P)
        C_affine = C_affine + warp(X.reshape(-1, 2))
    D = _second_differences(n, m)
    A = N.T @ N
    w = SMOOTHING * A.diagonal().mean()
    C = spsolve((A + w * (D.T @ D)).tocsc(), N.T @ target + w * (D.T @ (D @ C_affine)))
    return C.reshape(n, m, 3)


def affine_map(panel: Panel) -> np.ndarray:
    """(3, 3) M of the least-squares affine placement world ~ [rest, 1] M (the rigid
    transform's, for a panel without a 3D layout)."""
    R = np.c_[panel.rest, np.ones(len(panel.rest))]
    return np.linalg.lstsq(R, panel.positions(), rcond=None)[0]


def _second_differences(n: int, m: int):
    """Second differences of an n x m control net along u, v and across (rows of D)."""
    def second(k):
        return sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(k - 2, k))

    def first(k):
        return sp.diags([-1.0, 1.0], [0, 1], shape=(k - 1, k))

    return sp.vstack([sp.kron(second(n), sp.identity(m)), sp.kron(sp.identity(n), second(m)),
                      sp.kron(first(n), first(m))]).tocsr()
