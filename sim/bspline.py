"""Quadratic B-spline basis on open uniform integer knots (docs/design.md section 2).

With n control points in a direction the knots are [0, 0, 0, 1, ..., n-3, n-2, n-2, n-2]
and the parameter domain is [0, n-2]. Basis function i is supported on [i-2, i+1]
(clamped to the domain).

`eval_1d` returns a window of 4 consecutive functions starting at `first`: inside a span
the 3 active ones (4th is zero); exactly on an interior knot k the window is k-1..k+2 and
N'' is the average of its left and right limits (the exact mean of N'' over the dual
cell), which keeps sum_i N_i'' = 0 so rigid and linear motions carry no bending energy.
Zeros are exact zeros: a function that vanishes with its first derivative at a knot
comes out as 0.0, so stencils can be read off structurally.
"""

from __future__ import annotations

import numpy as np
from numba import njit

WINDOW = 4


@njit(cache=True, inline="always")
def _knot(j: int, n: int) -> float:
    """Knot t_j of the open uniform quadratic knot vector for n control points."""
    return float(min(max(j - 2, 0), n - 2))


@njit(cache=True, inline="always")
def _ratio(a: float, b: float) -> float:
    # Cox-de Boor convention: terms over repeated knots (b == 0) vanish.
    return a / b if b != 0.0 else 0.0


@njit(cache=True)
def _span_basis(s: int, u: float, n: int, N, dN, d2N, offset: int) -> None:
    """Add the 3 functions active on span [s, s+1] into window slots offset..offset+2."""
    j = s + 2  # knot interval [t_j, t_{j+1}] holds span s
    tj, tj1 = _knot(j, n), _knot(j + 1, n)
    h = tj1 - tj
    # Degree-1 functions N_{j-1,1}, N_{j,1} on this interval and their slopes.
    lin = np.zeros(4)  # N_{i,1} for i = j-2 .. j+1
    dlin = np.zeros(4)
    lin[1] = _ratio(tj1 - u, h)
    lin[2] = _ratio(u - tj, h)
    dlin[1] = -_ratio(1.0, h)
    dlin[2] = _ratio(1.0, h)
    for k in range(3):
        i = j - 2 + k
        ti, ti1, ti2, ti3 = _knot(i, n), _knot(i + 1, n), _knot(i + 2, n), _knot(i + 3, n)
        a = _ratio(1.0, ti2 - ti)
        b = _ratio(1.0, ti3 - ti1)
        N[offset + k] += (u - ti) * a * lin[k] + (ti3 - u) * b * lin[k + 1]
        dN[offset + k] += 2.0 * (a * lin[k] - b * lin[k + 1])
        d2N[offset + k] += 2.0 * (a * dlin[k] - b * dlin[k + 1])


@njit(cache=True)
def eval_1d(u: float, n: int, N, dN, d2N) -> int:
    """Values, first and second derivatives of the window of 4 functions at u.

    Fills N, dN, d2N (length 4) and returns the index of the first function.
    """
    for k in range(WINDOW):
        N[k] = 0.0
        dN[k] = 0.0
        d2N[k] = 0.0
    last_span = n - 3
    k = int(np.floor(u))
    if u == k and 1 <= k <= last_span:
        # Interior knot: average the one-sided limits (N, N' agree; N'' jumps).
        _span_basis(k - 1, u, n, N, dN, d2N, 0)
        _span_basis(k, u, n, N, dN, d2N, 1)
        for i in range(WINDOW):
            N[i] *= 0.5
            dN[i] *= 0.5
            d2N[i] *= 0.5
        return k - 1
    s = min(max(k, 0), last_span)
    _span_basis(s, u, n, N, dN, d2N, 0)
    return s


@njit(cache=True)
def eval_1d_many(u, n: int):
    """Vectorised eval_1d: returns first (P,), N, dN, d2N (P, 4)."""
    P = u.shape[0]
    first = np.empty(P, np.int64)
    N = np.empty((P, WINDOW))
    dN = np.empty((P, WINDOW))
    d2N = np.empty((P, WINDOW))
    for p in range(P):
        first[p] = eval_1d(u[p], n, N[p], dN[p], d2N[p])
    return first, N, dN, d2N


def basis_matrix(u: np.ndarray, n: int, derivative: int = 0) -> np.ndarray:
    """Dense (P, n) matrix of N_i^(derivative)(u_p); for tests and small problems."""
    u = np.ascontiguousarray(u, dtype=np.float64)
    first, N, dN, d2N = eval_1d_many(u, n)
    vals = (N, dN, d2N)[derivative]
    out = np.zeros((u.shape[0], n))
    for k in range(WINDOW):
        i = first + k
        ok = i < n
        out[np.nonzero(ok)[0], i[ok]] += vals[ok, k]
    return out


def knots(n: int) -> np.ndarray:
    """The open uniform knot vector for n quadratic control points."""
    return np.array([_knot(j, n) for j in range(n + 3)])
