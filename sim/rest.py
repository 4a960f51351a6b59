"""Rest-shape precomputation per quadrature point (docs/design.md section 2).

Everything here depends only on the rest control net X (n, m, 2) and a quadrature rule,
so it is computed once. For each point q we keep the stencil of control points whose
basis functions act there (padded with -1) and, per stencil entry a:

- g[q, a]   = dN_a/dX (2,): the membrane's deformation gradient is F = sum_a C_a g_a^T.
- lap[q, a] = coefficient of C_a in the Laplacian of phi (paper eq. "Laplacian in
  parametric space"), with u_i, u_ij from the inverse function theorem; complete only
  for stencils built with second_order=True.
- N[q, a]   = N_a, for masses and loads.
- w[q]      = parametric weight x |det dX/du|.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .bspline import WINDOW, eval_1d_many
from .quadrature import Rule


@dataclass
class PointData:
    """Flat per-point arrays for one quadrature rule on one or more patches.

    idx: (Q, K) int64 global control-point indices (-1 = padding); g: (Q, K, 2) 1/m;
    lap: (Q, K) 1/m^2; N: (Q, K); w: (Q,) m^2; det: (Q,) |dX/du| (m^2 per unit
    parameter area).
    """

    idx: np.ndarray
    g: np.ndarray
    lap: np.ndarray
    N: np.ndarray
    w: np.ndarray
    det: np.ndarray

    @property
    def n_points(self) -> int:
        return self.w.shape[0]

    @staticmethod
    def concatenate(parts: list["PointData"]) -> "PointData":
        K = max(p.idx.shape[1] for p in parts)

        def pad(a, fill):
            widths = [(0, 0), (0, K - a.shape[1])] + [(0, 0)] * (a.ndim - 2)
            return np.pad(a, widths, constant_values=fill)

        return PointData(
            idx=np.concatenate([pad(p.idx, -1) for p in parts]),
            g=np.concatenate([pad(p.g, 0.0) for p in parts]),
            lap=np.concatenate([pad(p.lap, 0.0) for p in parts]),
            N=np.concatenate([pad(p.N, 0.0) for p in parts]),
            w=np.concatenate([p.w for p in parts]),
            det=np.concatenate([p.det for p in parts]),
        )


@njit(cache=True)
def _point_kernel(X, fu, Nu, dNu, d2Nu, fv, Nv, dNv, d2Nv, wpar, second_order):
    """Per-point geometry on the 4 x 4 window of candidate functions.

    X: (n, m, 2) rest control points. Returns idx, g, lap, N over the 16 candidates
    (idx = -1 where the function is structurally zero for the requested order) and the
    weights and Jacobian determinants.
    """
    n, m = X.shape[0], X.shape[1]
    Q = wpar.shape[0]
    C = WINDOW * WINDOW
    idx = -np.ones((Q, C), np.int64)
    g = np.zeros((Q, C, 2))
    lap = np.zeros((Q, C))
    Nval = np.zeros((Q, C))
    w = np.zeros(Q)
    det = np.zeros(Q)
    for q in range(Q):
        # Rest map derivatives X_u, X_v, X_uu, X_uv, X_vv at the point.
        Xu = np.zeros(2)
        Xv = np.zeros(2)
        Xuu = np.zeros(2)
        Xuv = np.zeros(2)
        Xvv = np.zeros(2)
        for a in range(WINDOW):
            i = fu[q] + a
            if i >= n:
                continue
            for b in range(WINDOW):
                j = fv[q] + b
                if j >= m:
                    continue
                for d in range(2):
                    x = X[i, j, d]
                    Xu[d] += dNu[q, a] * Nv[q, b] * x
                    Xv[d] += Nu[q, a] * dNv[q, b] * x
                    Xuu[d] += d2Nu[q, a] * Nv[q, b] * x
                    Xuv[d] += dNu[q, a] * dNv[q, b] * x
                    Xvv[d] += Nu[q, a] * d2Nv[q, b] * x
        J = Xu[0] * Xv[1] - Xu[1] * Xv[0]
        det[q] = J  # signed: the caller rejects singular and folded rest maps
        w[q] = wpar[q] * abs(J)
        if J == 0.0:
            continue
        # A = (dX/du)^-1: rows are grad u = (u_1, u_2) and grad v = (v_1, v_2).
        A = np.empty((2, 2))
        A[0, 0] = Xv[1] / J
        A[0, 1] = -Xv[0] / J
        A[1, 0] = -Xu[1] / J
        A[1, 1] = Xu[0] / J
        # Second derivatives of (u, v) w.r.t. X from differentiating X(u(X)) = X:
        # u^k_ij = -A[k, l] X_l,mn A[m, i] A[n, j]; only the traces u_11 + u_22 are needed.
        lap_uv = np.zeros(2)  # (u_11 + u_22, v_11 + v_22)
        for k in range(2):
            s = 0.0
            for i in range(2):
                for l in range(2):
                    hess_mn = (A[0, i] * A[0, i] * Xuu[l] + 2.0 * A[0, i] * A[1, i] * Xuv[l]
                               + A[1, i] * A[1, i] * Xvv[l])
                    s -= A[k, l] * hess_mn
            lap_uv[k] = s
        guu = A[0, 0] ** 2 + A[0, 1] ** 2
        gvv = A[1, 0] ** 2 + A[1, 1] ** 2
        guv = A[0, 0] * A[1, 0] + A[0, 1] * A[1, 1]
        for a in range(WINDOW):
            i = fu[q] + a
            for b in range(WINDOW):
                j = fv[q] + b
                c = a * WINDOW + b
                if i >= n or j >= m:
                    continue
                n_u = dNu[q, a] * Nv[q, b]
                n_v = Nu[q, a] * dNv[q, b]
                n_uu = d2Nu[q, a] * Nv[q, b]
                n_vv = Nu[q, a] * d2Nv[q, b]
                n_uv = dNu[q, a] * dNv[q, b]
                active = n_u != 0.0 or n_v != 0.0 or Nu[q, a] * Nv[q, b] != 0.0
                if second_order:
                    active = active or n_uu != 0.0 or n_vv != 0.0 or n_uv != 0.0
                if not active:
                    continue
                idx[q, c] = i * m + j
                Nval[q, c] = Nu[q, a] * Nv[q, b]
                g[q, c, 0] = n_u * A[0, 0] + n_v * A[1, 0]
                g[q, c, 1] = n_u * A[0, 1] + n_v * A[1, 1]
                lap[q, c] = (guu * n_uu + gvv * n_vv + 2.0 * guv * n_uv
                             + lap_uv[0] * n_u + lap_uv[1] * n_v)
    return idx, g, lap, Nval, w, det


def point_data(X: np.ndarray, rule: Rule, offset: int = 0, second_order: bool = False) -> PointData:
    """Precompute per-point data of `rule` on the rest net X (n, m, 2).

    `offset` shifts control-point indices (patches share one global numbering);
    `second_order` keeps functions that act only through N'' (bending stencils).
    Stencils are compacted to the widest point's width.
    """
    X = np.ascontiguousarray(X, dtype=np.float64)
    n, m = X.shape[:2]
    fu, Nu, dNu, d2Nu = eval_1d_many(np.ascontiguousarray(rule.u), n)
    fv, Nv, dNv, d2Nv = eval_1d_many(np.ascontiguousarray(rule.v), m)
    idx, g, lap, N, w, det = _point_kernel(X, fu, Nu, dNu, d2Nu, fv, Nv, dNv, d2Nv,
                                           np.ascontiguousarray(rule.w), second_order)
    if not np.all(np.isfinite(det)) or np.any(det == 0.0):
        raise ValueError("rest map is degenerate: dX/du is singular at a quadrature point")
    if np.any(det > 0.0) and np.any(det < 0.0):
        raise ValueError("rest map folds over: det dX/du changes sign between quadrature points")
    det = np.abs(det)
    # Compact: move active entries to the front of each row.
    order = np.argsort(idx < 0, axis=1, kind="stable")
    K = int((idx >= 0).sum(axis=1).max())
    take = order[:, :K]
    rows = np.arange(idx.shape[0])[:, None]
    idx = idx[rows, take]
    idx = np.where(idx >= 0, idx + offset, -1)
    return PointData(idx=idx, g=g[rows, take], lap=lap[rows, take], N=N[rows, take], w=w, det=det)
