"""Lifting the rest control net to the panel's 3D placement (DESIGN.md section 4b.5).

A control point inside the rest mesh takes the barycentric combination of the 3D positions
of its containing triangle. One outside (control points of a convex boundary lie slightly
outside the outline) uses the nearest triangle, its barycentric coordinates clamped to
[-0.5, 1.5] (and renormalised) so the extrapolation stays local.
Panels placed by a rigid transform (GarmentCode) map the rest points directly.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from garment.model import Panel


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


def lift(panel: Panel, X: np.ndarray) -> np.ndarray:
    """World control net (n, m, 3) for the rest net X (n, m, 2)."""
    shape = X.shape[:-1]
    P = X.reshape(-1, 2)
    if panel.world is None or panel.faces is None:
        return panel.place(P).reshape(*shape, 3)
    tri, bary, _ = locate(panel, P)
    W = panel.world[panel.faces[tri]]  # (K, 3, 3)
    return np.einsum("kj,kjd->kd", bary, W).reshape(*shape, 3)
