"""Triangle meshes embedded in patches at fixed parameters: x = W C.

The render/export (and, later, contact) mesh samples each patch on a regular (u, v) grid;
its vertices are fixed linear combinations of control points, so W is a constant sparse
matrix (V x n_cp) with at most 9 non-zeros per row.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .bspline import WINDOW, eval_1d_many


def grid_faces(a: int, b: int) -> np.ndarray:
    """Triangles of an a x b vertex grid (row-major, index i * b + j), diagonals
    alternating so the mesh has no preferred shear direction."""
    i, j = np.meshgrid(np.arange(a - 1), np.arange(b - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    v00 = i * b + j
    v10, v01, v11 = v00 + b, v00 + 1, v00 + b + 1
    flip = (i + j) % 2 == 1
    t1 = np.where(flip[:, None], np.c_[v00, v10, v01], np.c_[v00, v10, v11])
    t2 = np.where(flip[:, None], np.c_[v10, v11, v01], np.c_[v00, v11, v01])
    return np.concatenate([t1, t2]).astype(np.int32)


def interpolation_matrix(u: np.ndarray, v: np.ndarray, n: int, m: int, offset: int, n_cp: int) -> sp.csr_matrix:
    """W with W[p, offset + i*m + j] = N_i(u_p) N_j(v_p)."""
    fu, Nu, _, _ = eval_1d_many(np.ascontiguousarray(u, float), n)
    fv, Nv, _, _ = eval_1d_many(np.ascontiguousarray(v, float), m)
    P = u.shape[0]
    a, b = np.meshgrid(np.arange(WINDOW), np.arange(WINDOW), indexing="ij")
    a, b = a.ravel(), b.ravel()
    I = fu[:, None] + a[None, :]
    J = fv[:, None] + b[None, :]
    val = Nu[:, a] * Nv[:, b]
    ok = (I < n) & (J < m) & (val != 0.0)
    rows = np.broadcast_to(np.arange(P)[:, None], I.shape)[ok]
    return sp.csr_matrix((val[ok], (rows, offset + I[ok] * m + J[ok])), shape=(P, n_cp))


def points_at(net: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Points (K, d) of the control net (n, m, d) at parameters uv (K, 2)."""
    uv = np.asarray(uv, float)
    n, m = net.shape[:2]
    return interpolation_matrix(uv[:, 0], uv[:, 1], n, m, 0, n * m) @ net.reshape(n * m, -1)


def default_resolution(n: int, m: int, density: float) -> tuple[int, int]:
    """About `density` vertices per control point (garment.scene.ContactSpec.mesh_density)."""
    s = np.sqrt(density)
    return max(2, int(round(s * n))), max(2, int(round(s * m)))


def sample_grid(n: int, m: int, resolution: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Parameters (u, v) of a resolution[0] x resolution[1] grid over [0, n-2] x [0, m-2]."""
    a, b = resolution
    U, V = np.meshgrid(np.linspace(0.0, n - 2.0, a), np.linspace(0.0, m - 2.0, b), indexing="ij")
    return U.ravel(), V.ravel()
