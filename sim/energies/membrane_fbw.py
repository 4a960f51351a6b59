"""FEM Baraff-Witkin membrane (Kim 2020) with the reference implementation's constants.

Psi = h [ k_st ((|f1| - 1)^2 + (|f2| - 1)^2) + k_sh (f1 . f2)^2 ],  f_i = F e_i,
k_st = E_st / (2 (1 + nu)), k_sh = (E_sh / E_st) k_st (garment/materials.py).

The Hessian is projected to PSD analytically, term by term (a sum of PSD parts is PSD):
- stretch: d2/df2 of k(|f| - 1)^2 = 2k [f^ f^T + (1 - 1/|f|)(I - f^ f^T)]: clamp the
  second eigenvalue at 0, or flip its sign (project 2, "abs"; it is negative under
  compression);
- shear: 2k (g g^T + I6 S) with g = [f2; f1] and S = [[0, I], [I, 0]]. S splits R^6 into
  its +1 space (p = P+ g) and -1 space (m = P- g); on span{p^, m^} the Hessian is the 2x2
  matrix [[|p|^2 + I6, |p||m|], [|p||m|, |m|^2 - I6]], on the rest of the +1 / -1 spaces
  it is +I6 / -I6. Every eigenpair is closed-form.
params per point: (h k_st, h k_sh).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .membrane import MembraneEnergy

_EPS = 1e-12


@njit(cache=True, inline="always")
def _normalise(x, fallback):
    """(x / |x|, |x|), or (fallback, 0) when x vanishes (its coefficient is then zero)."""
    n = np.sqrt(x @ x)
    if n > _EPS:
        return x / n, n
    return fallback, 0.0


@njit(cache=True, inline="always")
def _stretch(f, k, project, P_col, H, off):
    l = np.sqrt(f @ f)
    if l < _EPS:
        l = _EPS
    psi = k * (l - 1.0) ** 2
    for d in range(3):
        P_col[d] = 2.0 * k * (l - 1.0) * f[d] / l
    lam_perp = 1.0 - 1.0 / l
    if project and lam_perp < 0.0:
        lam_perp = 0.0 if project == 1 else -lam_perp
    for i in range(3):
        for j in range(3):
            nn = f[i] * f[j] / (l * l)
            H[off + i, off + j] += 2.0 * k * (nn + lam_perp * ((1.0 if i == j else 0.0) - nn))
    return psi


@njit(cache=True, inline="always")
def _shear(f1, f2, k, project, P, H):
    I6 = f1 @ f2
    psi = k * I6 * I6
    for d in range(3):
        P[d, 0] += 2.0 * k * I6 * f2[d]
        P[d, 1] += 2.0 * k * I6 * f1[d]
    gvec = np.empty(6)
    gvec[:3] = f2
    gvec[3:] = f1
    if not project:
        for i in range(6):
            for j in range(6):
                H[i, j] += 2.0 * k * gvec[i] * gvec[j]
        for i in range(3):
            H[i, 3 + i] += 2.0 * k * I6
            H[3 + i, i] += 2.0 * k * I6
        return psi
    s = f1 + f2
    t = f2 - f1
    pv = np.empty(6)
    mv = np.empty(6)
    pv[:3] = 0.5 * s
    pv[3:] = 0.5 * s
    mv[:3] = 0.5 * t
    mv[3:] = -0.5 * t
    r = np.sqrt(0.5)
    ph, pn = _normalise(pv, np.array([r, 0.0, 0.0, r, 0.0, 0.0]))
    mh, mn = _normalise(mv, np.array([r, 0.0, 0.0, -r, 0.0, 0.0]))
    # 2x2 block on span{p^, m^}.
    a = pn * pn + I6
    b = pn * mn
    c = mn * mn - I6
    mean = 0.5 * (a + c)
    rad = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    for sign in (1.0, -1.0):
        lam = mean + sign * rad
        if lam <= 0.0 and project == 1:
            continue
        # Eigenvector of [[a, b], [b, c]] for lam.
        if abs(b) > _EPS * (abs(a) + abs(c) + 1.0):
            ex, ey = b, lam - a
        elif (a >= c) == (sign > 0):
            ex, ey = 1.0, 0.0
        else:
            ex, ey = 0.0, 1.0
        nrm = np.sqrt(ex * ex + ey * ey)
        e = (ex * ph + ey * mh) / nrm
        for i in range(6):
            for j in range(6):
                H[i, j] += 2.0 * k * abs(lam) * e[i] * e[j]
    # Remaining +1 space (eigenvalue I6) and -1 space (eigenvalue -I6): clamping keeps
    # whichever is >= 0, abs keeps both at |I6|.
    if I6 > 0.0 or project == 2:
        for i in range(6):
            for j in range(6):
                proj = 0.5 * ((1.0 if i == j else 0.0) + (1.0 if abs(i - j) == 3 else 0.0))
                H[i, j] += 2.0 * k * abs(I6) * (proj - ph[i] * ph[j])
    if I6 < 0.0 or project == 2:
        for i in range(6):
            for j in range(6):
                proj = 0.5 * ((1.0 if i == j else 0.0) - (1.0 if abs(i - j) == 3 else 0.0))
                H[i, j] += 2.0 * k * abs(I6) * (proj - mh[i] * mh[j])
    return psi


@njit(parallel=True, cache=True)
def fbw_density(F, params, project, psi, P, H):
    Q = F.shape[0]
    for q in prange(Q):
        f1 = F[q, :, 0].copy()
        f2 = F[q, :, 1].copy()
        kst, ksh = params[q, 0], params[q, 1]
        H[q, :, :] = 0.0
        P[q, :, :] = 0.0
        Pq = P[q]
        Hq = H[q]
        p1 = np.zeros(3)
        p2 = np.zeros(3)
        e = _stretch(f1, kst, project, p1, Hq, 0)
        e += _stretch(f2, kst, project, p2, Hq, 3)
        for d in range(3):
            Pq[d, 0] = p1[d]
            Pq[d, 1] = p2[d]
        e += _shear(f1, f2, ksh, project, Pq, Hq)
        psi[q] = e


class MembraneFBW(MembraneEnergy):
    density = fbw_density
