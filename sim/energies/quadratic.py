"""Energies quadratic in C with a constant scalar matrix: E = 1/2 tr(C^T K C).

K (n_cp x n_cp, symmetric PSD) acts on each coordinate alike, so the 3D Hessian is
K (x) I3, assembled once into the constant part of the pattern (bending, seams).
"""

from __future__ import annotations

import numpy as np

from ..assembly import add_scalar_matrix
from .base import Energy


class QuadraticEnergy(Energy):
    constant_hessian = True
    K = None  # set by the subclass: scipy sparse (n_cp, n_cp)

    def bind(self, pattern):
        self._pattern = pattern

    def value(self, C):
        return 0.5 * float(np.sum(C * (self.K @ C)))

    def add_gradient(self, C, out):
        out += self.K @ C

    def add_hessian(self, C, data, project=True):
        add_scalar_matrix(self._pattern, self.K, data)
