"""What the contact energies (barrier, friction) share: a Hessian that ipctk gives on the
collision-mesh vertices, mapped to control points through W.

A subclass supplies `_ipctk_hessian(C, method)`, the (3V, 3V) vertex Hessian or None when
it has no contacts, and `hmap` (sim/contact/hessian_map.py). From it follow the pattern
assembly (couplings outside the pattern moved onto the diagonal and kept for exact solves),
the cloth x obstacle block H_cb for moving bodies, and a full matrix for tests.
"""

from __future__ import annotations

import ipctk
import numpy as np
import scipy.sparse as sp

from .base import Energy, projection_code

_METHODS = (ipctk.PSDProjectionMethod.NONE, ipctk.PSDProjectionMethod.CLAMP, ipctk.PSDProjectionMethod.ABS)


class ContactEnergy(Energy):
    variable_pattern = True
    moved_entries = 0
    _H_cb = None  # cloth-rows x obstacle-columns block of the last vertex Hessian

    def _ipctk_hessian(self, C, method):
        raise NotImplementedError

    def _prepare(self, C) -> None:
        """Bring cached contact data up to C (the barrier rebuilds its collision set)."""

    def _vertex_hessian(self, C, project=True):
        """The vertex Hessian at C, or None; keeps its cloth x obstacle block."""
        method = _METHODS[projection_code(project)]
        H = self._ipctk_hessian(C, method)
        n = 3 * self.contact.n_cloth
        self._H_cb = None if H is None else H.tocsr()[:n, n:]
        return H

    def hessian_matrix(self, C, project=True) -> sp.csr_matrix | None:
        """H_C = W3^T H_x W3 (3 n_cp square) or None without contacts (tests, tools)."""
        H = self._vertex_hessian(C, project)
        if H is None:
            return None
        n = 3 * self.contact.n_cloth
        W3 = self.contact.W3
        return (W3.T @ H.tocsr()[:n, :n] @ W3).tocsr()

    def add_hessian(self, C, data, project=True):
        """Map the vertex Hessian through W into the pattern in parallel (paper Alg. 1);
        couplings outside the pattern (distant self-contact) move onto the diagonal."""
        H = self._vertex_hessian(C, project)
        self.moved_entries = 0 if H is None else self.hmap.add(H, data)
        self.off_pattern, self.shift = (self.hmap.off_pattern, self.hmap.shift) if self.moved_entries else (None, None)

    def coupling(self, C, dB) -> np.ndarray:
        """(n_cp, 3) W^T H_cb dB: the first-order change of the cloth gradient when the
        obstacles move by dB (Vo, 3), from the Hessian assembled last at this state."""
        self._prepare(C)
        if self._H_cb is None:
            self._vertex_hessian(C)
        if self._H_cb is None:
            return np.zeros((self.contact.W.shape[1], 3))
        return (self.contact.W3.T @ (self._H_cb @ self.contact.active(dB).ravel())).reshape(-1, 3)
