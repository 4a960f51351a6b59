"""The one interface every energy offers (value, gradient, Hessian), as in IPC Toolkit.

Positions C are (n_cp, 3) arrays of all control points in metres. Gradients are added
into an (n_cp, 3) array (pinned points included, so reaction forces can be read);
Hessians are added into the `data` array of the shared lower-triangular block pattern
(sim/assembly.py), restricted to free control points.
"""

from __future__ import annotations

import numpy as np

from ..assembly import BlockPattern

#: PSD projections of an element Hessian: negative eigenvalues set to zero ("clamp", IPC's)
#: or to their magnitude ("abs", Chen et al. 2024, "Positive-Definite Fixes for Second-Order
#: Optimization": it keeps curvature in compressed directions; on the dress it took more
#: Newton iterations than clamp, docs/findings.md, "Sliding friction and extrapolation").
PROJECTIONS = ("clamp", "abs")


def projection_code(project: bool | str) -> int:
    """`project` as numba kernels take it: 0 exact, 1 clamp (also True), 2 abs."""
    if project is False or project is None:
        return 0
    if project is True:
        return 1
    if project not in PROJECTIONS:
        raise ValueError(f"projection must be one of {PROJECTIONS}, not {project!r}")
    return 1 + PROJECTIONS.index(project)


class Energy:
    #: True when the Hessian does not depend on C (it is then assembled once per pattern).
    constant_hessian: bool = False
    #: True for contact energies: their couplings change with C (those outside the fixed
    #: pattern are moved onto the diagonal), they bound steps (CCD) and feel moving bodies.
    variable_pattern: bool = False
    moved_entries: int = 0
    #: Contact energies, last assembly: the couplings moved out of the pattern (rows, cols,
    #: values on free DOFs, one triangle) and the diagonal added in their place.
    off_pattern = None
    shift = None

    def stencils(self) -> list[np.ndarray]:
        """Control-point stencils (Q, K) whose pairs the Hessian pattern must hold."""
        return []

    def bind(self, pattern: BlockPattern) -> None:
        """Precompute whatever maps this energy needs onto `pattern`."""

    def value(self, C: np.ndarray) -> float:
        raise NotImplementedError

    def add_gradient(self, C: np.ndarray, out: np.ndarray) -> None:
        raise NotImplementedError

    def add_hessian(self, C: np.ndarray, data: np.ndarray, project: bool | str = True) -> None:
        """Add the Hessian into pattern data, exact or PSD-projected (`project` is False,
        True = "clamp", or "abs"; see PROJECTIONS)."""
        raise NotImplementedError

    def max_step(self, C0: np.ndarray, C1: np.ndarray, B1: np.ndarray | None = None, driven: bool = False) -> float:
        """Largest fraction of the step C0 -> C1 this energy allows (CCD for contact; the
        bodies move to B1 meanwhile when given; driven: that motion is the bodies'
        prescribed one, which stops short of the cloth)."""
        return 1.0

    def coupling(self, C: np.ndarray, dB: np.ndarray) -> np.ndarray:
        """Contact energies: (n_cp, 3) change of the gradient when bodies move by dB."""
        return np.zeros_like(C)

    def body_clearance(self, C: np.ndarray, reach: float) -> np.ndarray | None:
        """Contact energies: (Vo,) how far (m, at most reach) each obstacle vertex may move,
        in any direction and on its own, with the cloth held at C; None: no limit."""
        return None
