"""An elastic drawstring: springs along a chain of cloth-mesh edges that pull only when
stretched, as an elastic band threaded through a waistband.

Each segment s joins two embedded-mesh vertices, d_s = g_s C with g_s the difference of
their interpolation rows (a fixed combination of control points, like a seam's sides),
and stores E_s = EA / (2 r_s) max(0, |d_s| - r_s)^2: EA the band's axial stiffness (N),
r_s its rest length, so the tension is EA times the strain. Stretched (l = |d| > r) its
Hessian in d, EA / r [(1 - r / l) I + (r / l) d d^T / l^2], is positive definite; slack,
zero. No Hessian projection is needed.

A garment's top opening wider than the body's trunk (skirt_06's 157 cm waistband on a
107 cm trunk) has nothing to rest on and slides off; garment/dress/drawstring.py draws
such an opening in with this energy. Rest lengths move linearly from `rest_from` to
`rest_to` over `window` (s), so the band tightens as the garment's weight comes on.

The segments are given only once the opening is found, after the seams close, so they
add no stencils: couplings outside the Hessian pattern go onto its diagonal
(assembly.add_dof_matrix; a segment spans at most two knot spans of one piece).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..assembly import add_dof_matrix
from .base import Energy


class DrawstringEnergy(Energy):
    """stiffness: EA in N. Inactive (no segments) until `draw`."""

    def __init__(self, n_cp: int, stiffness: float = 40.0):
        self.n_cp = int(n_cp)
        self.stiffness = float(stiffness)
        self.G = sp.csr_matrix((0, self.n_cp))
        self.rest_from = self.rest_to = self.rest = np.zeros(0)
        self.window = (0.0, 0.0)

    @property
    def active(self) -> bool:
        return self.G.shape[0] > 0

    def bind(self, pattern):
        self._pattern = pattern

    def draw(self, G: sp.spmatrix, rest_from: np.ndarray, rest_to: np.ndarray, window: tuple[float, float]) -> None:
        """Segments as rows of G (S, n_cp): d_s = G[s] C. Their rest lengths (m) go from
        rest_from to rest_to over the time window (t0, t1)."""
        self.G = sp.csr_matrix(G)
        self.rest_from = np.asarray(rest_from, float)
        self.rest_to = np.asarray(rest_to, float)
        self.window = (float(window[0]), float(window[1]))
        self.rest = self.rest_from.copy()

    def set_time(self, t: float) -> None:
        if not self.active:
            return
        t0, t1 = self.window
        s = 1.0 if t >= t1 else 0.0 if t <= t0 else (t - t0) / (t1 - t0)
        self.rest = self.rest_from + s * (self.rest_to - self.rest_from)

    def _stretch(self, C):
        """d (S, 3), l (S,), and the stretched segments' mask."""
        d = self.G @ C
        length = np.linalg.norm(d, axis=1)
        return d, length, length > self.rest

    def lengths(self, C: np.ndarray) -> np.ndarray:
        """(S,) segment lengths, m."""
        return np.linalg.norm(self.G @ C, axis=1)

    def value(self, C):
        if not self.active:
            return 0.0
        _, length, on = self._stretch(C)
        r = self.rest[on]
        return float(np.sum(0.5 * self.stiffness / r * (length[on] - r) ** 2))

    def add_gradient(self, C, out):
        if not self.active:
            return
        d, length, on = self._stretch(C)
        f = np.zeros_like(d)
        r = self.rest[on]
        f[on] = (self.stiffness / r * (length[on] - r) / length[on])[:, None] * d[on]
        out += self.G.T @ f

    def add_hessian(self, C, data, project=True):
        if not self.active:
            return
        H = self.hessian(C).tocoo()
        if H.nnz == 0:
            return
        free = self._pattern.free
        dof = np.where(np.repeat(free < 0, 3), -1, (3 * free[:, None] + np.arange(3)).ravel())
        keep = (dof[H.row] >= 0) & (dof[H.col] >= 0)
        n = self._pattern.n_dofs
        add_dof_matrix(self._pattern, sp.coo_matrix((H.data[keep], (dof[H.row[keep]], dof[H.col[keep]])), shape=(n, n)),
                       data)

    def hessian(self, C: np.ndarray) -> sp.csr_matrix:
        """The (3 n_cp)^2 Hessian: sum_s (g_s g_s^T) (x) H_s over the stretched segments,
        as (G (x) I3)^T blockdiag(H_s) (G (x) I3)."""
        d, length, on = self._stretch(C)
        r, l, dn = self.rest[on], length[on], d[on] / length[on][:, None]
        k = self.stiffness / r
        Hs = (k * (1.0 - r / l))[:, None, None] * np.eye(3) + (k * r / l)[:, None, None] * dn[:, :, None] * dn[:, None, :]
        S = len(r)
        blocks = sp.bsr_matrix((Hs, np.arange(S), np.arange(S + 1)), shape=(3 * S, 3 * S))
        Gx = sp.kron(self.G[np.flatnonzero(on)], sp.eye(3), format="csr")
        return (Gx.T @ blocks @ Gx).tocsr()
