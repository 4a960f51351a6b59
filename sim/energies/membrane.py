"""Shared machinery of membrane energies Psi(F), F = d phi / dX (3 x 2).

A concrete model supplies one numba kernel, `density(F, params, project, psi, P, H)`,
filling per point the energy density psi (Q,), its first derivative P = dPsi/dF (Q, 3, 2)
and its second derivative H (Q, 6, 6), exact (project 0) or PSD-projected (1 clamp,
2 abs), in the column-stacked layout [F e1; F e2]. This module turns those into energy,
gradient and Hessian blocks on the control points through the precomputed stencils and
gather maps.
"""

from __future__ import annotations

import numpy as np

from ..assembly import deformation_gradients, gather_gradient_F, gather_hessian_F, gather_map
from ..rest import PointData
from .base import Energy, projection_code


class MembraneEnergy(Energy):
    density = None  # numba kernel, set by subclasses

    def __init__(self, points: PointData, params: np.ndarray, n_cp: int):
        """params: (Q, k) per-point material constants, as the model's kernel expects."""
        self.points = points
        self.params = np.ascontiguousarray(params, dtype=np.float64)
        self.n_cp = n_cp
        Q = points.n_points
        self._F = np.zeros((Q, 3, 2))
        self._psi = np.zeros(Q)
        self._P = np.zeros((Q, 3, 2))
        self._H = np.zeros((Q, 6, 6))
        self._map = None
        self._pos = None

    def stencils(self):
        return [self.points.idx]

    def bind(self, pattern):
        self._map = gather_map(pattern, self.points.idx, self.n_cp)
        self._pos = pattern.pos

    def _evaluate(self, C, project):
        deformation_gradients(C, self.points.idx, self.points.g, self._F)
        type(self).density(self._F, self.params, projection_code(project), self._psi, self._P, self._H)

    def value(self, C):
        self._evaluate(C, False)
        return float(self._psi @ self.points.w)

    def add_gradient(self, C, out):
        self._evaluate(C, False)
        m = self._map
        gather_gradient_F(m.gptr, m.gpoint, m.ga, self.points.g, self.points.w, self._P, out)

    def add_hessian(self, C, data, project=True):
        self._evaluate(C, project)
        m = self._map
        gather_hessian_F(m.ptr, m.point, m.a, m.b, self.points.g, self.points.w, self._H, self._pos, data)
