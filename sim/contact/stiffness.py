"""Adaptive barrier stiffness, IPC's rule (Li et al. 2020, section 4.3) for our barrier.

kappa balances the barrier gradient against the rest of the incremental potential's
gradient at the start of every step with contacts, kappa = -g_E . g_B / |g_B|^2, clamped
to [kappa_min, 1e4 kappa_min], and doubles between steps while the closest distance keeps
shrinking below d_hat / 10, and between Newton iterations while it shrinks below
d_hat / 1000. ipctk's own initial_barrier_stiffness assumes the plain
barrier on squared distances and mass units; ours is the normalised, area-weighted barrier
whose kappa is a pressure, so the floor is physical instead: at half of d_hat the barrier
holds the cloth's weight plus the inertia of moving d_hat within one step,
kappa_min |b'(1/2)| / d_hat = rho h (|g| + d_hat / dt^2).
"""

from __future__ import annotations

import numpy as np

_B_PRIME_HALF = 2.0 * 0.5 * np.log(0.5) - 0.25 / 0.5  # d/dx of -(x-1)^2 ln x at x = 1/2
_RANGE = 1e4


class AdaptiveStiffness:
    """barrier: sim.energies.barrier.BarrierEnergy; areal_density in kg/m^2."""

    def __init__(self, barrier, areal_density: float, gravity: float, dt: float):
        self.barrier = barrier
        pressure = areal_density * (gravity + barrier.dhat / dt**2)
        self.kappa_min = pressure * barrier.dhat / abs(_B_PRIME_HALF)
        self.kappa_max = _RANGE * self.kappa_min
        self.floor = self.kappa_min
        self.prev_d = np.inf
        self._iterate_d = np.inf
        barrier.kappa = self.kappa_min

    def update(self, potential, C: np.ndarray) -> float:
        """Set the barrier's kappa for the step starting at C; returns it."""
        b = self.barrier
        if b.n_collisions_at(C) == 0:
            return b.kappa
        free = potential.free_points
        # Each gradient once: the barrier's at unit stiffness, the rest of the potential's.
        g_B = np.zeros_like(C)
        b.add_gradient(C, g_B)
        g_B /= b.kappa
        g_E = np.zeros_like(C)
        for e in potential.energies:
            if e is not b:
                e.add_gradient(C, g_E)
        gB, gE = g_B[free].ravel(), g_E[free].ravel()
        k0 = -float(gE @ gB) / max(float(gB @ gB), 1e-300)
        d = b.min_distance(C)
        if d < 0.1 * b.dhat and d < self.prev_d:
            self.floor = min(2.0 * self.floor, self.kappa_max)
        self.prev_d = d
        self._iterate_d = np.inf
        b.kappa = float(np.clip(max(k0, self.floor), self.kappa_min, self.kappa_max))
        return b.kappa

    def on_iterate(self, C: np.ndarray) -> bool:
        """Within a step, as IPC does after each Newton iteration: double kappa while the
        closest distance is below d_hat / 1000 and still shrinking. A stiffness chosen at
        the step's start cannot hold cloth that a seam or a body then presses harder: the
        cloth sinks to 1e-7 m, where the barrier's Hessian spans 10 orders of magnitude
        and Newton stalls at its iteration cap."""
        b = self.barrier
        d = b.min_distance(C)
        shrinking = d < 1e-3 * b.dhat and d < self._iterate_d
        self._iterate_d = d
        if shrinking and b.kappa < self.kappa_max:
            b.kappa = min(2.0 * b.kappa, self.kappa_max)
            self.floor = max(self.floor, b.kappa)
            return True
        return False
