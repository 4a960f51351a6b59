"""Linear triangles as membrane quadrature points: one point per triangle with the
constant shape-function gradients, so the B-spline membranes (FBW, StVK) and their
kernels and gather maps run on them unchanged.

For a triangle x_0 x_1 x_2 with rest edge matrix Dm = [X_1 - X_0, X_2 - X_0] (2 x 2),
F = [x_1 - x_0, x_2 - x_0] Dm^-1 = sum_a x_a g_a^T with g_1, g_2 the rows of Dm^-1 and
g_0 = -g_1 - g_2 (1/m); the weight is the rest area.
"""

from __future__ import annotations

import numpy as np

from ..rest import PointData
from .mesh import TriangleMesh


def triangle_points(mesh: TriangleMesh) -> PointData:
    """PointData with one point per face: idx (T, 3), g (T, 3, 2), N = 1/3, w = area."""
    F = mesh.faces
    a, b, c = (mesh.rest[F[:, k]] for k in range(3))
    Dm = np.stack([b - a, c - a], axis=2)  # columns are rest edges
    inv = np.linalg.inv(Dm)
    g = np.empty((F.shape[0], 3, 2))
    g[:, 1] = inv[:, 0, :]
    g[:, 2] = inv[:, 1, :]
    g[:, 0] = -g[:, 1] - g[:, 2]
    area = 0.5 * np.abs(np.linalg.det(Dm))
    T = F.shape[0]
    return PointData(idx=F.astype(np.int64), g=g, lap=np.zeros((T, 3)), N=np.full((T, 3), 1.0 / 3.0),
                     w=area, det=area)


def lumped_areas(mesh: TriangleMesh) -> np.ndarray:
    """(V,) vertex areas: a third of each adjacent face, m^2."""
    return np.bincount(mesh.faces.ravel(), np.repeat(np.abs(mesh.areas()) / 3.0, 3), minlength=mesh.n_vertices)
