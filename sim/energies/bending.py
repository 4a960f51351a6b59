"""Laplacian bending (flat rest shape): Psi = D/2 |Laplacian phi|^2 per unit rest area.

Laplacian phi at point q is sum_a lap[q, a] C_a, so the energy is quadratic in C:
E = 1/2 tr(C^T K C) with the constant scalar matrix K = sum_q w_q D lap_q lap_q^T; the
3D Hessian K (x) I3 is precomputed once and never projected (it is PSD by construction).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..rest import PointData
from .quadratic import QuadraticEnergy


class BendingEnergy(QuadraticEnergy):
    def __init__(self, points: PointData, stiffness: np.ndarray, n_cp: int):
        """stiffness: (Q,) bending stiffness D (N m) per point."""
        self.points = points
        Q, K = points.idx.shape
        rows = np.repeat(points.idx, K, axis=1).ravel()
        cols = np.tile(points.idx, (1, K)).ravel()
        coef = (points.w * stiffness)[:, None, None] * points.lap[:, :, None] * points.lap[:, None, :]
        ok = (rows >= 0) & (cols >= 0)
        self.K = sp.coo_matrix((coef.ravel()[ok], (rows[ok], cols[ok])), shape=(n_cp, n_cp)).tocsr()

    def stencils(self):
        return [self.points.idx]
