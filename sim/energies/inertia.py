"""Inertia term of implicit Euler: 1/(2 dt^2) ||C - C_hat||_M^2 with lumped masses."""

from __future__ import annotations

import numpy as np

from ..assembly import BlockPattern, add_diagonal
from .base import Energy


class InertiaEnergy(Energy):
    """mass: (n_cp,) lumped masses in kg; dt in s; `target` (n_cp, 3) is C_hat = C_n + dt v_n."""

    constant_hessian = True

    def __init__(self, mass: np.ndarray, dt: float):
        self.mass = np.asarray(mass, float)
        self.dt = float(dt)
        self.target = None
        self._pattern: BlockPattern | None = None

    def bind(self, pattern: BlockPattern) -> None:
        self._pattern = pattern

    def value(self, C):
        d = C - self.target
        return 0.5 / self.dt**2 * float(np.einsum("i,ij,ij->", self.mass, d, d))

    def add_gradient(self, C, out):
        out += (self.mass / self.dt**2)[:, None] * (C - self.target)

    def add_hessian(self, C, data, project=True):
        add_diagonal(self._pattern, self.mass / self.dt**2, data)
