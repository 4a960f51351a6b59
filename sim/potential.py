"""The incremental potential: a sum of energies over one fixed Hessian pattern.

Constant Hessians (inertia, bending, loads) are assembled once into `const_data`; each
Newton iteration copies them and lets the state-dependent energies add their blocks.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .assembly import BlockPattern
from .energies.base import Energy
from .linsolve import CholeskySolver


class IncrementalPotential:
    """energies: the terms; free: (n_cp,) bool mask of unknown control points."""

    def __init__(self, energies: list[Energy], free_mask: np.ndarray):
        self.energies = energies
        self.n_cp = free_mask.shape[0]
        self.free_points = np.flatnonzero(free_mask)
        free = -np.ones(self.n_cp, np.int64)
        free[self.free_points] = np.arange(self.free_points.size)
        self.pattern = BlockPattern.from_stencils(free, [s for e in energies for s in e.stencils()])
        for e in energies:
            e.bind(self.pattern)
        self.refresh_constant()
        self.data = self.const_data.copy()
        self.matrix = self.pattern.matrix(self.data)
        self._diagonal = None  # of matrix, once asked for after an assembly (diagonal())
        self.moved_entries = 0  # off-pattern contact entries moved to the diagonal, last assembly
        self.correction = None
        self.variable = [e for e in energies if e.variable_pattern]
        # Without contact the whole pattern fills: factor it as is, analysed once, in a
        # METIS ordering (the hanging sheet at 75^2: 5.9M values in L against AMD's 6.5M).
        self.solver = CholeskySolver(self.matrix, ordering="default" if self.variable else "metis",
                                     nonzeros=bool(self.variable))
        self.drive = None  # sim.contact.drive.BodyDrive when bodies move
        self.projection_backoff = (0, 1)  # Newton's projection-on-demand state (newton.py)
        # Called with each accepted Newton iterate; True when it changed an energy (the
        # adaptive barrier stiffness doubling within a step, sim/contact/stiffness.py).
        self.on_iterate = None
        self.should_stop = None  # asked before every Newton iteration (sim/recovery.py)

    def restart(self) -> None:
        """A new time step: the solver's analysis may depend only on this step's matrices
        (a resumed run then repeats the uninterrupted one bit for bit)."""
        self.solver.restart()

    def refresh_constant(self) -> None:
        """(Re)assemble the constant Hessian terms (after a time-step change)."""
        self.const_data = np.zeros(self.pattern.nnz)
        for e in self.energies:
            if e.constant_hessian:
                e.add_hessian(None, self.const_data)

    def value(self, C: np.ndarray) -> float:
        return sum(e.value(C) for e in self.energies)

    def gradient(self, C: np.ndarray) -> np.ndarray:
        """(n_cp, 3) gradient, pinned points included."""
        g = np.zeros((self.n_cp, 3))
        for e in self.energies:
            e.add_gradient(C, g)
        return g

    def assemble(self, C: np.ndarray, project: bool = True) -> None:
        """Write the Hessian at C (free DOFs, lower triangle) into `self.matrix`.

        Variable-pattern (contact) Hessians are merged into the same fixed pattern, so the
        solver's symbolic analysis never changes."""
        self.data[:] = self.const_data
        self._diagonal = None
        for e in self.energies:
            if not e.constant_hessian:
                e.add_hessian(C, self.data, project)
        self.moved_entries = sum(e.moved_entries for e in self.variable)
        self._collect_correction()

    def _collect_correction(self) -> None:
        """`correction` = (B, shift): the exact Hessian is matrix - diag(shift) + B, where B
        holds the couplings outside the pattern (symmetric); None when nothing moved."""
        parts = [e for e in self.variable if e.off_pattern is not None]
        self.correction = None
        if not parts:
            return
        n = self.pattern.n_dofs
        r = np.concatenate([e.off_pattern[0] for e in parts])
        c = np.concatenate([e.off_pattern[1] for e in parts])
        v = np.concatenate([e.off_pattern[2] for e in parts])
        L = sp.csr_matrix((v, (r, c)), shape=(n, n))
        self.correction = ((L + L.T).tocsr(), sum(e.shift for e in parts))

    def diagonal(self) -> np.ndarray:
        """The assembled matrix's diagonal, kept until the next assembly (every CG
        iteration's Hessian product needs it: 1.7 ms a time at 9.5K DOFs)."""
        if self._diagonal is None:
            self._diagonal = self.matrix.diagonal()
        return self._diagonal

    def coupling_bound(self) -> float:
        """Gershgorin bound on ||D^-1 B||_inf, D the in-pattern Hessian, B the moved
        couplings (0 when nothing moved): below 1, the factor of D (plus the moved
        diagonal) preconditions the exact system well (paper section 5.3)."""
        if self.correction is None:
            return 0.0
        shift = self.correction[1]
        d = self.diagonal() - shift
        with np.errstate(over="ignore"):  # a coupling on a (near) zero diagonal: unbounded
            return float(np.max(shift / np.maximum(d, 1e-300)))

    def exact_lower(self) -> sp.csc_matrix:
        """Lower triangle of the exact Hessian, moved couplings merged back (a pattern
        of its own, for a one-off factorization)."""
        L = self.matrix.copy()
        if self.correction is not None:
            B, shift = self.correction
            L = (L - sp.diags(shift) + sp.tril(B)).tocsc()
        return L

    def apply_hessian(self, p: np.ndarray) -> np.ndarray:
        """The exact assembled Hessian (free DOFs) times p, moved couplings included."""
        L = self.matrix
        y = L @ p + L.T @ p - self.diagonal() * p
        if self.correction is not None:
            B, shift = self.correction
            y += B @ p - shift * p
        return y

    def max_step(self, C0: np.ndarray, C1: np.ndarray, B1: np.ndarray | None = None, driven: bool = False) -> float:
        """Largest fraction of C0 -> C1 every energy allows (collision-free for contact),
        with the bodies moving to B1 (when given) meanwhile."""
        return min([1.0] + [e.max_step(C0, C1, B1, driven) for e in self.variable])

    def body_clearance(self, C: np.ndarray, reach: float) -> np.ndarray | None:
        """(Vo,) how far each obstacle vertex may move on its own with the cloth held at C
        (the least any contact energy allows), or None when none limits it."""
        limits = [c for c in (e.body_clearance(C, reach) for e in self.variable) if c is not None]
        return np.minimum.reduce(limits) if limits else None

    def coupling(self, C: np.ndarray, dB: np.ndarray) -> np.ndarray:
        """(n_cp, 3) first-order gradient change when the bodies move by dB."""
        return sum((e.coupling(C, dB) for e in self.variable), np.zeros((self.n_cp, 3)))

    def full_hessian(self):
        """The assembled symmetric matrix (both triangles), for tests and diagnostics."""
        return self.pattern.full(self.data)
