"""Least-squares quadratic B-spline fits of the four sides (docs/design.md section 4b.2).

A side is the outline polyline from one corner to the next. It is sampled densely (every
polyline vertex plus points in between, each weighted by the arc length it stands for),
given chord-length parameters u_a = (n - 2) s_a / L (or graded ones, conform/grading.py), and fitted by n control points with the
end points pinned to the corners and a second-difference penalty against zig-zags:

    min_C  sum_a (w_a / L) |C(u_a) - P_a|^2  +  lam / (n - 2) sum_i |D2 C|_i^2

D2 takes second divided differences over the Greville abscissae (C_i-1 - 2 C_i + C_i+1
inside), so a uniformly parametrised straight line costs nothing. Both terms are mean
squares in m^2, so `lam` means the same on every side and at every resolution; on a smooth
curve |D2 C| ~ h^2 / R is tiny and the penalty only matters where the data leave control
points undetermined (spans shorter than the input edges).

The fit error that matters is the largest distance, so the weights are then reweighted a
few times, w_a <- w_a (1 + (r_a / mean r)^2) (iteratively reweighted least squares towards
a minimax fit): this about halves the error at sharp features such as dart tips at the
same control count.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from sim.patches import Patch
from sim.bspline import WINDOW, eval_1d_many

from .grading import Grading

LAMBDA = 1e-4
REWEIGHT = 6


@dataclass
class SideSamples:
    """Dense samples of one side: points (K, 2), arc length s (K,) from the start corner,
    weights w (K,) (arc length each sample stands for, m), total length L (m); grading:
    the parameter map along the side in its loop direction (None: chord length)."""

    points: np.ndarray
    s: np.ndarray
    w: np.ndarray
    grading: Grading | None = None

    @property
    def length(self) -> float:
        return float(self.s[-1])

    def parameters(self, n: int) -> np.ndarray:
        """Chord-length (or graded) parameters in [0, n - 2]."""
        if self.grading is not None:
            return self.grading.parameter(self.s / self.length, n)
        return (n - 2) * self.s / self.length

    def abscissae(self, n: int) -> np.ndarray:
        """The Greville abscissae in chord-length units (n - 2) * arc fraction, where the
        second-difference penalty measures: a straight side costs nothing when graded too."""
        g = Patch.greville(n)
        return g if self.grading is None else (n - 2) * self.grading.fraction(g, n)


def sample_polyline(poly: np.ndarray, spacing: float, grading: Grading | None = None) -> SideSamples:
    """Polyline vertices plus evenly spaced points so no gap exceeds `spacing`."""
    seg = np.diff(poly, axis=0)
    lens = np.linalg.norm(seg, axis=1)
    pts, s = [poly[:1]], [np.zeros(1)]
    s0 = 0.0
    for k in range(seg.shape[0]):
        count = max(int(np.ceil(lens[k] / spacing)), 1)
        t = np.arange(1, count + 1) / count
        pts.append(poly[k] + t[:, None] * seg[k])
        s.append(s0 + t * lens[k])
        s0 += lens[k]
    P, S = np.concatenate(pts), np.concatenate(s)
    gaps = np.diff(S)
    w = np.zeros_like(S)
    w[:-1] += 0.5 * gaps
    w[1:] += 0.5 * gaps
    return SideSamples(points=P, s=S, w=w, grading=grading)


def second_difference(n: int, g: np.ndarray | None = None) -> np.ndarray:
    """(n - 2, n) matrix of second divided differences of control points over abscissae g
    (default: the Greville abscissae 0, 0.5, 1.5, ..., n-2): C_i-1 - 2 C_i + C_i+1 inside,
    weighted at the ends so that a uniformly parametrised straight line (linear precision)
    costs 0."""
    g = Patch.greville(n) if g is None else g
    D = np.zeros((n - 2, n))
    for i in range(1, n - 1):
        a, b = 1.0 / (g[i] - g[i - 1]), 1.0 / (g[i + 1] - g[i])
        D[i - 1, i - 1], D[i - 1, i], D[i - 1, i + 1] = a, -(a + b), b
    return D


def local_basis(u: np.ndarray, n: int) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The nonzero basis functions at parameters u (P,): control indices (P, 4) and the
    values of N, N', N'' (P, 4 each; 0 on padding). Banded: O(P), no (P, n) matrix."""
    u = np.ascontiguousarray(u, dtype=np.float64)
    first, N, dN, d2N = eval_1d_many(u, n)
    idx = first[:, None] + np.arange(WINDOW)
    ok = idx < n
    return np.minimum(idx, n - 1), (np.where(ok, N, 0.0), np.where(ok, dN, 0.0), np.where(ok, d2N, 0.0))


def normal_equations(u: np.ndarray, n: int, w: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A = sum_a w_a N(u_a) N(u_a)^T (n, n) and b = sum_a w_a N(u_a) P_a^T (n, 2)."""
    idx, (N, _, _) = local_basis(u, n)
    wN = w[:, None] * N
    key = (idx[:, :, None] * n + idx[:, None, :]).ravel()
    A = np.bincount(key, weights=(wN[:, :, None] * N[:, None, :]).ravel(), minlength=n * n).reshape(n, n)
    b = np.stack([np.bincount(idx.ravel(), weights=(wN * points[:, d, None]).ravel(), minlength=n)
                  for d in range(2)], axis=1)
    return A, b


def fit_side(side: SideSamples, n: int, lam: float = LAMBDA) -> np.ndarray:
    """Control points (n, 2) of the regularised least-squares fit, ends pinned."""
    if n < 3:
        raise ValueError("a quadratic side needs at least 3 control points")
    u = side.parameters(n)
    L = side.length
    A, b = normal_equations(u, n, side.w / L, side.points)
    D = second_difference(n, side.abscissae(n)) * np.sqrt(lam / (n - 2))
    A = A + D.T @ D
    C = np.empty((n, 2))
    C[0], C[-1] = side.points[0], side.points[-1]
    free = slice(1, n - 1)
    rhs = b[free] - A[free][:, [0, n - 1]] @ C[[0, n - 1]]
    C[free] = np.linalg.solve(A[free, free], rhs)
    return C


def fit_side_reweighted(side: SideSamples, n: int, lam: float = LAMBDA,
                        iterations: int = REWEIGHT) -> tuple[np.ndarray, SideSamples]:
    """fit_side with IRLS towards the minimax fit; returns the control points and the
    samples with their final weights."""
    floor = 1e-7 * side.length  # residuals below this are round-off: no reweighting
    for it in range(iterations + 1):
        C = fit_side(side, n, lam)
        if it == iterations:
            break
        r = np.linalg.norm(evaluate(C, side.parameters(n)) - side.points, axis=1)
        mean = float(r.mean())
        if mean <= floor:
            break
        w = side.w * (1.0 + (r / mean) ** 2)
        side = dataclasses.replace(side, w=w * (side.w.sum() / w.sum()))  # same total weight
    return C, side


def evaluate(ctrl: np.ndarray, u: np.ndarray, derivative: int = 0) -> np.ndarray:
    """Curve points (or derivatives) at parameters u."""
    idx, vals = local_basis(np.atleast_1d(np.asarray(u, float)), ctrl.shape[0])
    return np.einsum("pk,pkd->pd", vals[derivative], ctrl[idx])


def project(ctrl: np.ndarray, points: np.ndarray, u0: np.ndarray | None = None,
            samples_per_span: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Closest parameters u (P,) on the curve to points (P, 2) and the distances (P,).

    Starts from the nearest of a dense sampling (or from u0) and polishes with Newton."""
    n = ctrl.shape[0]
    points = np.atleast_2d(np.asarray(points, float))
    if u0 is None:
        grid = np.linspace(0.0, n - 2.0, samples_per_span * (n - 2) + 1)
        G = evaluate(ctrl, grid)
        d2 = ((points[:, None, :] - G[None, :, :]) ** 2).sum(-1)
        u = grid[np.argmin(d2, axis=1)]
    else:
        u = np.asarray(u0, float).copy()
    for _ in range(8):
        idx, (N, dN, d2N) = local_basis(u, n)  # one basis evaluation for all three
        C = ctrl[idx]
        p = np.einsum("pk,pkd->pd", N, C)
        dp = np.einsum("pk,pkd->pd", dN, C)
        ddp = np.einsum("pk,pkd->pd", d2N, C)
        r = p - points
        g = (r * dp).sum(1)
        H = (dp * dp).sum(1) + (r * ddp).sum(1)
        step = np.where(H > 1e-300, -g / np.where(H > 1e-300, H, 1.0), 0.0)
        u = np.clip(u + step, 0.0, n - 2.0)
    dist = np.linalg.norm(evaluate(ctrl, u) - points, axis=1)
    return u, dist
