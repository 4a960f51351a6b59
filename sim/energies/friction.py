"""Lagged, smoothed IPC friction (Li et al. 2020 section 5; ipctk's convergent form),
mapped to control points.

D(C) = dt sum_k mu lambda_k f0(|T_k^T v_k|),  v = (x(C) - x_n) / dt,

with x_n the collision-mesh vertices at the start of the step (bodies included, so a moving
body drags the cloth), and the normal forces lambda_k and tangent bases T_k lagged there:
re-linearised once per step (`lag`). ipctk evaluates D and its derivatives in v; in C,
grad = W^T dD/dv and Hess = W^T d2D/dv2 W / dt.
"""

from __future__ import annotations

import ipctk
import numpy as np

from .barrier import BarrierEnergy, in_order
from .contact import ContactEnergy


class FrictionEnergy(ContactEnergy):
    def __init__(self, barrier: BarrierEnergy, mu: float, eps_v: float, dt: float):
        self.barrier = barrier
        self.mu = float(mu)
        self.dt = float(dt)
        self.potential = ipctk.FrictionPotential(float(eps_v))
        self.tangential = ipctk.TangentialCollisions()
        self.x_n = None

    @property
    def contact(self):
        """The barrier's contact mesh (it changes when the seams merge)."""
        return self.barrier.contact

    def stencils(self):
        return self.barrier.stencils()

    @property
    def hmap(self):
        """The barrier's Hessian map: same contact mesh, same pattern."""
        return self.barrier.hmap

    def lag(self, C: np.ndarray) -> None:
        """Re-linearise at the start of a step: contacts, normal forces and bases at C."""
        self.x_n = self.contact.vertices(C)
        self.barrier._update(C)
        normal = ipctk.BarrierPotential(self.barrier.barrier, self.barrier.dhat, self.barrier.kappa)
        with in_order():
            self.tangential.build(self.contact.mesh, self.x_n, self.barrier.collisions, normal, self.mu)

    @property
    def active(self) -> bool:
        return self.x_n is not None and len(self.tangential) > 0

    def _v(self, C):
        return np.asfortranarray((self.contact.vertices(C) - self.x_n) / self.dt)

    def value(self, C):
        if not self.active:
            return 0.0
        with in_order():
            return self.dt * float(self.potential(self.tangential, self.contact.mesh, self._v(C)))

    def add_gradient(self, C, out):
        if not self.active:
            return
        with in_order():
            g = self.contact.cloth_part(self.potential.gradient(self.tangential, self.contact.mesh, self._v(C)))
        out += (self.contact.W3.T @ g).reshape(-1, 3)

    def _ipctk_hessian(self, C, method):
        if not self.active:
            return None
        with in_order():
            return self.potential.hessian(self.tangential, self.contact.mesh, self._v(C), method) / self.dt
