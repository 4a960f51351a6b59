"""Dead loads: gravity and uniform pressure, linear in C.

E = - sum_a f_a . C_a with f_a = m_a g + p A_a d_a: m_a lumped mass (kg), A_a = int N_a dX
(m^2), p in Pa along the fixed direction d_a (a cloth's initial normal or a given
direction). The pressure is a dead load (it does not follow the deforming normal), which is
what the small-deflection plate benchmark assumes.
"""

from __future__ import annotations

import numpy as np

from .base import Energy


class ExternalForceEnergy(Energy):
    constant_hessian = True

    def __init__(self, forces: np.ndarray):
        self.forces = np.asarray(forces, float)  # (n_cp, 3) N

    def value(self, C):
        return -float(np.sum(self.forces * C))

    def add_gradient(self, C, out):
        out -= self.forces

    def add_hessian(self, C, data, project=True):
        pass
