"""MIPS refinement of the rest control net (docs/design.md section 4b.4).

Minimises, over the control points X (n, m, 2) of the rest map X(u, v),

    E(X) = sum_q w_q f(J_q) / sum_q w_q  +  w_b E_fit(X),
    f(J) = (|J|_F^2 / det J)^2 + w_a (det J / d0 + d0 / det J),

with J = dX/du diag(1/a, 1/b) the Jacobian scaled by the span sizes a, b along u and v -
the mean ones, or for a graded net (conform/grading.py) the wanted ones at the point - so
a grid of square cells of those sizes scores the minimum whatever the panel's size and
control counts. The first term is |J|^2 |J^-1|^2 (MIPS, the paper's choice); the second,
with d0 the mean scaled determinant, evens out the cell areas, which makes the reduced rule
more accurate. E_fit is the side fits' least-squares objective (curve_fit) over the
boundary rows over the squared span size: the boundary may give a little to relax the
interior. The four corners are fixed.

The points q are every point where a simulator rule evaluates the rest Jacobian - 3 x 3
Gauss per knot span (weight 1), and 2 x 2 Gauss and the reduced rule (weight 0.1 each) -
so the barrier keeps all of them away from det J = 0 and no point the simulator uses can
invert. Projected Newton: per-point 4 x 4 Hessians in (X_u, X_v) projected to PSD (Jacobi
eigen-decomposition in a numba kernel that also sums them into 2 x 2 control-point blocks
of a fixed sparsity pattern), CHOLMOD; the line search starts at the largest step that
keeps every det J > 0 (det along a Newton ray is a quadratic in the step) and backtracks
for Armijo.

A start with inverted points is first untangled with Garanzha et al.'s regularisation
("Foldover-free maps in 50 lines of code", 2021): det J in the denominators becomes
chi(d, eps) = (d + sqrt(d^2 + eps^2)) / 2 > 0, with eps shrinking until every determinant
is positive; then the exact barrier takes over.
"""

from __future__ import annotations

import time
from functools import lru_cache
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numba import njit

from sim.bspline import eval_1d_many
from sim.linsolve import CholeskySolver
from sim.quadrature import gauss, reduced_membrane

POWER = 2.0  # f = (|J|^2 / det)^POWER; 2 is |J|^2 |J^-1|^2 of the paper
SIGMA_MIN = 0.3  # slowest eps decrease per untangling step (Garanzha et al.: 0.1; 0.3 measured faster)
STALL_WINDOW = 8  # untangling gives up when min det gains < 1 % over this many steps


class PointSet:
    """Sparse maps from a net's control points to X_u and X_v at parameter points.

    idx (Q, K) flat control-point indices i * m + j of each point's stencil; du, dv (Q, K)
    the derivatives of the basis functions there (0 on padding).
    """

    def __init__(self, n: int, m: int, u: np.ndarray, v: np.ndarray, w: np.ndarray | None = None):
        self.n, self.m = n, m
        self.u, self.v = np.ascontiguousarray(u, float), np.ascontiguousarray(v, float)
        self.w = np.ones_like(self.u) if w is None else np.asarray(w, float)
        fu, Nu, dNu, _ = eval_1d_many(self.u, n)
        fv, Nv, dNv, _ = eval_1d_many(self.v, m)
        width = 4 if (np.any(Nu[:, 3] != 0) or np.any(dNu[:, 3] != 0) or np.any(Nv[:, 3] != 0)
                      or np.any(dNv[:, 3] != 0)) else 3
        a, b = np.meshgrid(np.arange(width), np.arange(width), indexing="ij")
        a, b = a.ravel(), b.ravel()
        I, J = fu[:, None] + a, fv[:, None] + b
        ok = (I < n) & (J < m)
        self.idx = np.where(ok, np.minimum(I, n - 1) * m + np.minimum(J, m - 1), 0)
        self.du = np.where(ok, dNu[:, a] * Nv[:, b], 0.0)
        self.dv = np.where(ok, Nu[:, a] * dNv[:, b], 0.0)
        rows = np.repeat(np.arange(self.u.size), a.size)
        shape = (self.u.size, n * m)
        self.Du = sp.csr_matrix((self.du.ravel(), (rows, self.idx.ravel())), shape=shape)
        self.Dv = sp.csr_matrix((self.dv.ravel(), (rows, self.idx.ravel())), shape=shape)

    def __len__(self) -> int:
        return self.u.size

    def jacobians(self, X2: np.ndarray) -> np.ndarray:
        """(Q, 4) = (X_u.x, X_u.y, X_v.x, X_v.y) for the net X2 (n*m, 2)."""
        return np.concatenate([self.Du @ X2, self.Dv @ X2], axis=1)


def point_scales(pts: PointSet, scale) -> np.ndarray:
    """(Q, 4) factors (1/a, 1/a, 1/b, 1/b) of the Jacobians at the points; a and b are
    numbers or functions of u and v."""
    a, b = (np.broadcast_to(s(t) if callable(s) else float(s), t.shape) for s, t in zip(scale, (pts.u, pts.v)))
    return np.ascontiguousarray(np.stack([1 / a, 1 / a, 1 / b, 1 / b], axis=1))


def det(Y: np.ndarray) -> np.ndarray:
    return Y[:, 0] * Y[:, 3] - Y[:, 1] * Y[:, 2]


@lru_cache(maxsize=32)
def simulator_rules(n: int, m: int) -> dict:
    """The simulator's rules of an n x m net (sim/quadrature.py), built once per size:
    "gauss3", "gauss2" and (n, m >= 5) "reduced"."""
    rules = {"gauss3": gauss(n, m, 3), "gauss2": gauss(n, m, 2)}
    if n >= 5 and m >= 5:
        rules["reduced"] = reduced_membrane(n, m)
    return rules


@lru_cache(maxsize=32)
def rule_points(n: int, m: int, side_weight: float = 0.1) -> PointSet:
    """The points of every simulator rule (sim/quadrature.py) with energy weights: 3 x 3
    Gauss at full weight, 2 x 2 Gauss and the reduced rule (n, m >= 5) at side_weight."""
    R = simulator_rules(n, m)
    rules = [(R["gauss3"], 1.0), (R["gauss2"], side_weight)]
    if "reduced" in R:
        rules.append((R["reduced"], side_weight))
    u = np.concatenate([r.u for r, _ in rules])
    v = np.concatenate([r.v for r, _ in rules])
    w = np.concatenate([r.w * k for r, k in rules])
    return PointSet(n, m, u, v, w)


@dataclass
class BoundaryFit:
    """Quadratic boundary term E_fit(X) = sum_d (X_d^T H X_d - 2 b_d^T X_d + c) / h^2 over
    the flat net X (n*m, 2): H (n*m, n*m) sparse, b (n*m, 2), c scalar, h metres."""

    H: sp.csr_matrix
    b: np.ndarray
    c: float
    h: float

    def value(self, X2):
        return float(((self.H @ X2) * X2).sum() - 2.0 * (self.b * X2).sum() + self.c) / self.h**2

    def gradient(self, X2):
        return 2.0 * (self.H @ X2 - self.b) / self.h**2


@dataclass
class MipsOptions:
    """Solver settings; the defaults are the ones measured in docs/findings.md ("Conforming panels")."""

    w_boundary: float = np.inf  # weight of E_fit; inf fixes the boundary rows
    max_iterations: int = 60
    tolerance: float = 1e-6  # stop when the Newton decrement / 2 < tolerance * E
    untangle_iterations: int = 100
    area_weight: float = 10.0  # weight of the area term d / d0 + d0 / d (d0: mean det)


@dataclass
class MipsResult:
    """The refined net X (n, m, 2); energy is inf when untangling failed."""

    X: np.ndarray
    iterations: int
    untangle_iterations: int
    energy: float
    min_det_ratio: float  # min det / mean det over the points
    converged: bool
    seconds: float
    history: list = field(default_factory=list)


def _chi(d, eps):
    """(d + sqrt(d^2 + eps^2)) / 2, without cancellation for d < 0."""
    r = np.sqrt(d**2 + eps**2)
    with np.errstate(divide="ignore", invalid="ignore"):  # np.where evaluates both branches
        return np.where(d >= 0, 0.5 * (d + r), 0.5 * eps**2 / (r - d))


def _point_terms(Y, scale, eps, area_weight=0.0, d0=1.0, hessian=True, project=True):
    """f, df/dY (Q, 4) and projected d2f/dY2 (Q, 4, 4) of
    f = (|y|^2 / c)^POWER + area_weight (c / d0 + d0 / c), y = Y * scale, c = chi(det y, eps)
    (c = det y when eps == 0)."""
    p = POWER
    y = Y * scale
    A = (y**2).sum(1)
    d = det(y)
    if eps > 0:
        r = np.sqrt(d**2 + eps**2)
        c, c1, c2 = _chi(d, eps), 0.5 * (1.0 + d / r), 0.5 * eps**2 / r**3
    else:
        c, c1, c2 = d, np.ones_like(d), np.zeros_like(d)
    q = A / c
    f = q**p + area_weight * (c / d0 + d0 / c)
    gA = p * q ** (p - 1) / c
    gc = -p * q**p / c + area_weight * (1.0 / d0 - d0 / c**2)
    grad_d = np.stack([y[:, 3], -y[:, 2], -y[:, 1], y[:, 0]], axis=1)
    g = (2.0 * gA)[:, None] * y + (gc * c1)[:, None] * grad_d
    if not hessian:
        return f, g * scale, None
    gAA = p * (p - 1) * q ** (p - 2) / c**2
    gAc = -p * p * q ** (p - 1) / c**2
    gcc = p * (p + 1) * q**p / c**2 + 2.0 * area_weight * d0 / c**3
    H = (4.0 * gAA)[:, None, None] * y[:, :, None] * y[:, None, :]
    cross = y[:, :, None] * grad_d[:, None, :]
    H += (2.0 * gAc * c1)[:, None, None] * (cross + cross.transpose(0, 2, 1))
    H += (gcc * c1**2 + gc * c2)[:, None, None] * grad_d[:, :, None] * grad_d[:, None, :]
    H += (2.0 * gA)[:, None, None] * np.eye(4)
    D2 = np.zeros((4, 4))
    D2[0, 3] = D2[3, 0] = 1.0
    D2[1, 2] = D2[2, 1] = -1.0
    H += (gc * c1)[:, None, None] * D2
    if project:
        lam, V = np.linalg.eigh(H)
        H = np.einsum("qij,qj,qkj->qik", V, np.maximum(lam, 0.0), V)
    S = scale
    return f, g * S, H * S[:, :, None] * S[:, None, :]


@njit(cache=True, inline="always")
def _positive_definite_4(A, L) -> bool:
    """Whether the symmetric 4 x 4 A is positive definite (Cholesky into scratch L)."""
    for j in range(4):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if d <= 0.0:
            return False
        L[j, j] = np.sqrt(d)
        for i in range(j + 1, 4):
            x = A[i, j]
            for k in range(j):
                x -= L[i, k] * L[j, k]
            L[i, j] = x / L[j, j]
    return True


@njit(cache=True, inline="always")
def _project_psd_4(A, out):
    """out = A with negative eigenvalues clamped to 0 (cyclic Jacobi; A is overwritten).
    A positive definite A (Cholesky succeeds: most points near the optimum) is copied."""
    V = np.eye(4)
    if _positive_definite_4(A, out):
        for i in range(4):
            for j in range(4):
                out[i, j] = A[i, j]
        return
    for _ in range(10):
        off, diag = 0.0, 0.0
        for i in range(4):
            diag += A[i, i] * A[i, i]
            for j in range(i + 1, 4):
                off += A[i, j] * A[i, j]
        if off <= 1e-30 * diag:
            break
        for p in range(3):
            for r in range(p + 1, 4):
                if A[p, r] == 0.0:
                    continue
                theta = (A[r, r] - A[p, p]) / (2.0 * A[p, r])
                t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                sn = t * c
                for k in range(4):
                    akp, akr = A[k, p], A[k, r]
                    A[k, p], A[k, r] = c * akp - sn * akr, sn * akp + c * akr
                for k in range(4):
                    apk, ark = A[p, k], A[r, k]
                    A[p, k], A[r, k] = c * apk - sn * ark, sn * apk + c * ark
                for k in range(4):
                    vkp, vkr = V[k, p], V[k, r]
                    V[k, p], V[k, r] = c * vkp - sn * vkr, sn * vkp + c * vkr
    for i in range(4):
        for j in range(4):
            acc = 0.0
            for k in range(4):
                if A[k, k] > 0.0:
                    acc += V[i, k] * A[k, k] * V[j, k]
            out[i, j] = acc


@njit(cache=True)
def _newton_terms(Y, w, scale, eps, area_weight, d0, power, D, slot, n_blocks):
    """Energy sum_q w_q f_q, gradient w.r.t. Y (Q, 4) and the projected Hessian summed into
    2 x 2 control-point blocks (n_blocks, 2, 2) through slot (Q, K, K)."""
    Q, K = D.shape[0], D.shape[2]
    gY = np.zeros((Q, 4))
    blocks = np.zeros((n_blocks, 2, 2))
    E = 0.0
    H = np.zeros((4, 4))
    Hp = np.zeros((4, 4))
    y = np.zeros(4)
    gd = np.zeros(4)
    G = np.zeros((K, 2, 4))
    for q in range(Q):
        for i in range(4):
            y[i] = Y[q, i] * scale[q, i]
        A = y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]
        d = y[0] * y[3] - y[1] * y[2]
        if eps > 0.0:
            r = np.sqrt(d * d + eps * eps)
            c = 0.5 * (d + r) if d >= 0.0 else 0.5 * eps * eps / (r - d)
            c1 = 0.5 * (1.0 + d / r)
            c2 = 0.5 * eps * eps / (r * r * r)
        else:
            c, c1, c2 = d, 1.0, 0.0
        qq = A / c
        f = qq**power + area_weight * (c / d0 + d0 / c)
        gA = power * qq ** (power - 1.0) / c
        gc = -power * qq**power / c + area_weight * (1.0 / d0 - d0 / (c * c))
        gAA = power * (power - 1.0) * qq ** (power - 2.0) / (c * c)
        gAc = -power * power * qq ** (power - 1.0) / (c * c)
        gcc = power * (power + 1.0) * qq**power / (c * c) + 2.0 * area_weight * d0 / (c * c * c)
        gd[0], gd[1], gd[2], gd[3] = y[3], -y[2], -y[1], y[0]
        E += w[q] * f
        for i in range(4):
            gY[q, i] = w[q] * (2.0 * gA * y[i] + gc * c1 * gd[i]) * scale[q, i]
        kdd = gcc * c1 * c1 + gc * c2
        for i in range(4):
            for j in range(4):
                H[i, j] = (4.0 * gAA * y[i] * y[j] + 2.0 * gAc * c1 * (y[i] * gd[j] + gd[i] * y[j])
                           + kdd * gd[i] * gd[j])
            H[i, i] += 2.0 * gA
        H[0, 3] += gc * c1
        H[3, 0] += gc * c1
        H[1, 2] -= gc * c1
        H[2, 1] -= gc * c1
        _project_psd_4(H, Hp)
        for i in range(4):
            for j in range(4):
                Hp[i, j] *= w[q] * scale[q, i] * scale[q, j]
        # y index 2 alpha + d; local block (a, b): sum_alpha,beta D[alpha, a] Hp[2a+d, 2b+e] D[beta, b].
        # G[a] = D[:, a]^T Hp rows first (2 x 4 per a), then the blocks: half the flops.
        for a in range(K):
            du_a, dv_a = D[q, 0, a], D[q, 1, a]
            for dd in range(2):
                for c in range(4):
                    G[a, dd, c] = du_a * Hp[dd, c] + dv_a * Hp[2 + dd, c]
        for a in range(K):
            if D[q, 0, a] == 0.0 and D[q, 1, a] == 0.0:
                continue
            for b in range(K):
                du_b, dv_b = D[q, 0, b], D[q, 1, b]
                if du_b == 0.0 and dv_b == 0.0:
                    continue
                s = slot[q, a, b]
                for dd in range(2):
                    for ee in range(2):
                        blocks[s, dd, ee] += G[a, dd, ee] * du_b + G[a, dd, 2 + ee] * dv_b
    return E, gY, blocks


class _Assembler:
    """Sums per-point 4 x 4 Hessians in (X_u, X_v) into the sparse (2 n m)^2 matrix
    (interleaved x, y) through a pattern of 2 x 2 control-point blocks built once."""

    def __init__(self, pts: PointSet):
        Q, K = pts.idx.shape
        n, m = pts.n, pts.m
        nm = n * m
        # Blocks (a, b) with both basis functions active at some point. Their stencils are
        # at most 4 wide, so b = a + (di, dj) with |di|, |dj| <= 3: code the pair as
        # a * 49 + offset and mark the codes in place of sorting them (np.unique was
        # 0.6 s of a 102 x 36 net).
        active = (pts.du != 0) | (pts.dv != 0)  # (Q, K)
        ia, ja = np.divmod(pts.idx.astype(np.int64), m)
        di = ia[:, None, :] - ia[:, :, None] + 3  # (Q, K, K): row a, column b
        dj = ja[:, None, :] - ja[:, :, None] + 3
        pair = active[:, :, None] & active[:, None, :]
        code = pts.idx[:, :, None].astype(np.int64) * 49 + di * 7 + dj
        code = np.where(pair, code, 0)
        marker = np.zeros(nm * 49, bool)
        marker[code[pair]] = True
        lookup = np.cumsum(marker) - 1
        self.slot = np.where(pair, lookup[code], 0)
        uniq = np.flatnonzero(marker)
        self.n_blocks = uniq.size
        a, off = np.divmod(uniq, 49)
        bi, bj = np.divmod(a, m)
        bi, bj = bi + off // 7 - 3, bj + off % 7 - 3
        br, bc = a, bi * m + bj
        # Block (br, bc) entry (d, e) sits at row 2 br + d, column 2 bc + e.
        rows = (2 * br[:, None, None] + np.arange(2)[None, :, None]).repeat(2, axis=2).ravel()
        cols = (2 * bc[:, None, None] + np.arange(2)[None, None, :]).repeat(2, axis=1).ravel()
        N = 2 * nm
        pattern = sp.csr_matrix((np.arange(1, rows.size + 1, dtype=float), (rows, cols)), shape=(N, N))
        self.indptr, self.indices, self.shape = pattern.indptr, pattern.indices, (N, N)
        self.order = (pattern.data - 1).astype(np.int64)  # csr position -> (block, d, e) flat
        self.D = np.stack([pts.du, pts.dv], axis=1)  # (Q, 2, K): derivative of N_a along u, v

    def matrix(self, blocks: np.ndarray) -> sp.csr_matrix:
        """The sparse matrix of the (n_blocks, 2, 2) block sums."""
        return sp.csr_matrix((blocks.reshape(-1)[self.order], self.indices, self.indptr), shape=self.shape)


class MipsProblem:
    """The energy of one net size, with its point sets and assembly pattern."""

    def __init__(self, n: int, m: int, scale: tuple[float, float], boundary: BoundaryFit | None,
                 fixed: np.ndarray, options: MipsOptions):
        self.n, self.m = n, m
        self.pts = rule_points(n, m)
        self.scale = point_scales(self.pts, scale)
        self.W = float(self.pts.w.sum())
        self.boundary = boundary
        self.options = options
        self.fixed = fixed  # (n*m*2,) bool
        self.free = np.nonzero(~fixed)[0]
        self._asm = None
        self._solver = None
        self.d0 = 1.0
        self._Hb = None

    def _energy(self, X2, eps, hessian):
        pts = self.pts
        Y = pts.jacobians(X2)
        wn = pts.w / self.W
        if hessian:
            if self._asm is None:
                self._asm = _Assembler(pts)
            asm = self._asm
            E, gY, blocks = _newton_terms(Y, wn, self.scale, float(eps), self.options.area_weight,
                                          self.d0, POWER, asm.D, asm.slot, asm.n_blocks)
            Hs = asm.matrix(blocks)
        else:
            f, g, _ = _point_terms(Y, self.scale, eps, self.options.area_weight, self.d0, False)
            E = float(wn @ f)
            gY = g * wn[:, None]
            Hs = None
        grad = np.stack([pts.Du.T @ gY[:, 0] + pts.Dv.T @ gY[:, 2],
                         pts.Du.T @ gY[:, 1] + pts.Dv.T @ gY[:, 3]], axis=1)
        if self.boundary is not None and np.isfinite(self.options.w_boundary):
            wb = self.options.w_boundary
            E += wb * self.boundary.value(X2)
            grad = grad + wb * self.boundary.gradient(X2)
            if hessian:
                if self._Hb is None:
                    self._Hb = sp.kron(self.boundary.H, sp.eye(2), format="csr") * (2.0 * wb / self.boundary.h**2)
                Hs = Hs + self._Hb
        return E, grad, Hs

    def value(self, X2, eps=0.0) -> float:
        return self._energy(X2, eps, False)[0]

    def newton(self, X2, eps=0.0):
        """Energy, Newton decrement and the Newton step (n*m, 2) at X2."""
        E, g, H = self._energy(X2, eps, True)
        gz = g.ravel()[self.free]
        Hff = H[self.free][:, self.free]
        Hff = Hff + sp.eye(Hff.shape[0]) * (1e-10 * float(Hff.diagonal().mean()))
        lower = sp.tril(Hff, format="csc")
        if self._solver is None:
            self._solver = CholeskySolver(lower)
        self._solver.factorize(lower)
        dz = -self._solver.solve(gz)
        d = np.zeros(2 * self.n * self.m)
        d[self.free] = dz
        return E, -float(gz @ dz), d.reshape(-1, 2)

    def dets(self, X2) -> np.ndarray:
        """Scaled det J at every point."""
        return det(self.pts.jacobians(X2) * self.scale)

    def max_step(self, X2, D2) -> float:
        """The first alpha > 0 at which some det J reaches 0 along X + alpha D (inf: none)."""
        Y = self.pts.jacobians(X2) * self.scale
        dY = self.pts.jacobians(D2) * self.scale
        c0 = det(Y)
        c2 = det(dY)
        c1 = Y[:, 0] * dY[:, 3] + dY[:, 0] * Y[:, 3] - Y[:, 1] * dY[:, 2] - dY[:, 1] * Y[:, 2]
        # Smallest positive root of c0 + c1 a + c2 a^2 (c0 > 0), in the stable form.
        with np.errstate(divide="ignore", invalid="ignore"):
            disc = c1**2 - 4.0 * c2 * c0
            q = -0.5 * (c1 + np.copysign(np.sqrt(np.maximum(disc, 0.0)), c1))
            r1, r2 = q / c2, c0 / q
            r1 = np.where((disc >= 0) & (r1 > 0), r1, np.inf)
            r2 = np.where((disc >= 0) & (r2 > 0), r2, np.inf)
        alpha = np.minimum(r1, r2)
        return float(min(alpha.min(), np.inf))


def _untangle(prob: MipsProblem, X2, options: MipsOptions, history):
    """Newton steps on the eps-regularised energy with Garanzha et al.'s eps update:
    mu = (1 - sigma) chi(D-, eps), eps = 2 sqrt(mu (mu - D-)) where D- is the smallest
    determinant and sigma = 1 - E_k / E_k-1 clamped to [SIGMA_MIN, 0.5]. Stops once every
    determinant is positive."""
    D = float(prob.dets(X2).min())
    mu = 0.1 * prob.d0
    eps = 2.0 * np.sqrt(mu * (mu - D)) if D < mu else 1e-8 * prob.d0
    its = 0
    for its in range(1, options.untangle_iterations + 1):
        E, dec, D2 = prob.newton(X2, eps)
        alpha = 1.0
        for _ in range(30):
            E_new = prob.value(X2 + alpha * D2, eps)
            if E_new <= E - 1e-4 * alpha * dec:
                break
            alpha *= 0.5
        X2 = X2 + alpha * D2
        D = float(prob.dets(X2).min())
        history.append(("untangle", eps, D))
        if D > 0:
            break
        recent = [h[2] for h in history[-STALL_WINDOW:] if h[0] == "untangle"]
        if len(recent) == STALL_WINDOW and recent[-1] - recent[0] < 0.01 * abs(recent[0]):
            break  # stalled: this boundary admits no valid interior at this resolution
        sigma = min(max(1.0 - E_new / E, SIGMA_MIN), 0.5)  # capped: a big first drop must not zero eps
        mu = (1.0 - sigma) * float(_chi(np.array(D), eps))
        eps = 2.0 * np.sqrt(mu * (mu - D)) if D < mu else 1e-8 * prob.d0
    return X2, its


def refine(X: np.ndarray, scale, boundary: BoundaryFit | None, fixed_points: np.ndarray,
           options: MipsOptions | None = None) -> MipsResult:
    """MIPS-refine the net X (n, m, 2); scale: span sizes (a, b) along u and v, m, each a
    number (the mean) or a function of the parameter (a graded net: Grading.span);
    fixed_points (n, m) bool marks control points that never move (the corners, or the
    whole boundary when w_boundary is inf)."""
    options = options or MipsOptions()
    start = time.perf_counter()
    n, m = X.shape[:2]
    fixed = np.repeat(np.asarray(fixed_points, bool).reshape(-1), 2)
    prob = MipsProblem(n, m, scale, boundary, fixed, options)
    X2 = X.reshape(-1, 2).copy()
    history = []
    d = prob.dets(X2)
    prob.d0 = float(abs(prob.pts.w @ d) / prob.W)  # the boundary fixes the total area

    # 1. Untangle, if some determinant is not positive.
    untangle_it = 0
    if d.min() <= 0:
        X2, untangle_it = _untangle(prob, X2, options, history)
        d = prob.dets(X2)
        if d.min() <= 0:
            return MipsResult(X2.reshape(n, m, 2), 0, untangle_it, np.inf,
                              float(d.min() / abs(d).mean()), False, time.perf_counter() - start, history)

    # 2. MIPS with the exact barrier.
    converged = False
    it = 0
    E = prob.value(X2)
    for it in range(1, options.max_iterations + 1):
        E, dec, D2 = prob.newton(X2)
        history.append(("mips", E, dec))
        if dec / 2 < options.tolerance * E:
            converged = True
            break
        alpha = min(1.0, 0.9 * prob.max_step(X2, D2))
        accepted = False
        for _ in range(40):
            E_new = prob.value(X2 + alpha * D2)
            if E_new <= E - 1e-4 * alpha * dec:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            converged = True  # no decrease left above round-off
            break
        X2 = X2 + alpha * D2
        if (E - E_new) < 1e-10 * E:
            E = E_new
            converged = True
            break
    d = prob.dets(X2)
    return MipsResult(X2.reshape(n, m, 2), it, untangle_it, prob.value(X2), float(d.min() / d.mean()),
                      converged, time.perf_counter() - start, history)
