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
        self.full = np.asarray(forces, float)  # (n_cp, 3) N
        self.forces = self.full
        # s: loads off before window[0], ramped in linearly until window[1]. A garment
        # sewn weightless around a body does not drop off it before the seams hold.
        self.window = (0.0, 0.0)

    def set_time(self, t: float) -> None:
        t0, t1 = self.window
        s = 1.0 if t >= t1 else 0.0 if t <= t0 else (t - t0) / (t1 - t0)
        self.forces = self.full * s

    def value(self, C):
        return -float(np.sum(self.forces * C))

    def add_gradient(self, C, out):
        out -= self.forces

    def add_hessian(self, C, data, project=True):
        pass
