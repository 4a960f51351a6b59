"""The one interface every energy offers (value, gradient, Hessian), as in IPC Toolkit.

Positions C are (n_cp, 3) arrays of all control points in metres. Gradients are added
into an (n_cp, 3) array (pinned points included, so reaction forces can be read);
Hessians are added into the `data` array of the shared lower-triangular block pattern
(sim/assembly.py), restricted to free control points.
"""

from __future__ import annotations

import numpy as np

from ..assembly import BlockPattern


class Energy:
    #: True when the Hessian does not depend on C (it is then assembled once per pattern).
    constant_hessian: bool = False
    #: True when the Hessian's pattern changes with C (contact): it is then returned by
    #: `hessian_matrix` as a sparse matrix on all control-point DOFs instead.
    variable_pattern: bool = False

    def stencils(self) -> list[np.ndarray]:
        """Control-point stencils (Q, K) whose pairs the Hessian pattern must hold."""
        return []

    def bind(self, pattern: BlockPattern) -> None:
        """Precompute whatever maps this energy needs onto `pattern`."""

    def value(self, C: np.ndarray) -> float:
        raise NotImplementedError

    def add_gradient(self, C: np.ndarray, out: np.ndarray) -> None:
        raise NotImplementedError

    def add_hessian(self, C: np.ndarray, data: np.ndarray, project: bool = True) -> None:
        """Add the (PSD-projected when `project`) Hessian into pattern data."""
        raise NotImplementedError

    def hessian_matrix(self, C: np.ndarray, project: bool = True):
        """Variable-pattern energies: the (3 n_cp)^2 scipy Hessian, or None when zero."""
        return None

    def max_step(self, C0: np.ndarray, C1: np.ndarray, B1: np.ndarray | None = None) -> float:
        """Largest fraction of the step C0 -> C1 this energy allows (CCD for contact; the
        bodies move to B1 meanwhile when given)."""
        return 1.0

    def coupling(self, C: np.ndarray, dB: np.ndarray) -> np.ndarray:
        """Contact energies: (n_cp, 3) change of the gradient when bodies move by dB."""
        return np.zeros_like(C)
