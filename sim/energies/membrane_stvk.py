"""Isotropic St. Venant-Kirchhoff membrane (for the wrinkling benchmark and stiff sheets).

Psi = h (mu |G|^2 + lambda/2 tr(G)^2), G = (F^T F - I) / 2, with plane-stress Lame
parameters. P = h F S, S = 2 mu G + lambda tr(G) I;
d2Psi/dF_{i a} dF_{j b} = h [delta_ij S_ab + mu (delta_ab (F F^T)_ij + F_ib F_ja)
+ lambda F_ia F_jb]. StVK has no closed-form eigensystem in F, so the 6x6 Hessian is
projected by a small symmetric eigen-solve per point.
params per point: (h mu, h lambda).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .membrane import MembraneEnergy


@njit(parallel=True, cache=True)
def stvk_density(F, params, project, psi, P, H):
    Q = F.shape[0]
    for q in prange(Q):
        Fq = F[q]
        mu, lam = params[q, 0], params[q, 1]
        G = 0.5 * (Fq.T @ Fq - np.eye(2))
        tr = G[0, 0] + G[1, 1]
        psi[q] = mu * (G[0, 0] ** 2 + 2.0 * G[0, 1] ** 2 + G[1, 1] ** 2) + 0.5 * lam * tr * tr
        S = 2.0 * mu * G + lam * tr * np.eye(2)
        P[q] = Fq @ S
        FFt = Fq @ Fq.T
        Hq = np.zeros((6, 6))
        for a in range(2):
            for b in range(2):
                for i in range(3):
                    for j in range(3):
                        v = mu * Fq[i, b] * Fq[j, a] + lam * Fq[i, a] * Fq[j, b]
                        if i == j:
                            v += S[a, b]
                        if a == b:
                            v += mu * FFt[i, j]
                        Hq[3 * a + i, 3 * b + j] = v
        if project:
            vals, vecs = np.linalg.eigh(Hq)
            if vals[0] < 0.0:
                Hq = (vecs * (np.maximum(vals, 0.0) if project == 1 else np.abs(vals))) @ vecs.T
        H[q] = Hq


class MembraneStVK(MembraneEnergy):
    density = stvk_density
