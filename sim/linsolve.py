"""Sparse Cholesky through CHOLMOD (scikit-sparse), symbolic analysis reused.

The fill-reducing ordering and supernodal structure depend only on the pattern, so they
are computed once per pattern; every Newton iteration refactors numerically in place.
"""

from __future__ import annotations

import ctypes
import os
from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp
from sksparse.cholmod import CholmodNotPositiveDefiniteError, analyze

# CHOLMOD's supernodal factorization spends its time in dense BLAS on the fronts. BLAS
# runs on one thread by default (garment/_threads.py: small systems lose more to hand-offs
# with numba than they gain); large ones gain from more. Merged dress Hessian, 2 cores,
# analysis + factorization: 61K rows 1.23 -> 0.99 s with 2 threads, 17K rows no gain.
PARALLEL_ROWS = 30_000
LARGE_THREADS = int(os.environ.get("GARMENT_CHOLMOD_THREADS", min(2, os.cpu_count() or 1)))


def _system_openblas():
    """The system OpenBLAS that Debian's CHOLMOD links, or None (another BLAS)."""
    try:
        lib = ctypes.CDLL("libopenblas.so.0")
        return lib if hasattr(lib, "openblas_set_num_threads") else None
    except OSError:
        return None


_OPENBLAS = _system_openblas()


@contextmanager
def blas_threads(rows: int):
    """LARGE_THREADS BLAS threads for a factorization of `rows` rows, if that many pay."""
    if _OPENBLAS is None or rows < PARALLEL_ROWS or LARGE_THREADS <= 1:
        yield
        return
    before = _OPENBLAS.openblas_get_num_threads()
    _OPENBLAS.openblas_set_num_threads(LARGE_THREADS)
    try:
        yield
    finally:
        _OPENBLAS.openblas_set_num_threads(before)


class CholeskySolver:
    """Solves H x = b for the lower-triangular CSC matrices of one fixed pattern.

    ordering: CHOLMOD's ordering method (its default tries AMD and METIS)."""

    def __init__(self, A_lower: sp.csc_matrix, ordering: str = "default"):
        self._factor = analyze(A_lower, mode="supernodal", ordering_method=ordering)
        self.n_factorizations = 0

    def _refactor(self, A_lower: sp.csc_matrix, shift: float) -> None:
        with blas_threads(A_lower.shape[0]):
            self._factor.cholesky_inplace(A_lower, beta=shift)
        self.n_factorizations += 1

    def try_factorize(self, A_lower: sp.csc_matrix) -> bool:
        """Factor A if it is positive definite; False (and no usable factor) if not."""
        try:
            self._refactor(A_lower, 0.0)
        except CholmodNotPositiveDefiniteError:
            return False
        return True

    def factorize(self, A_lower: sp.csc_matrix) -> float:
        """Factor A (+ shift I if A is not positive definite); returns the shift used."""
        shift = 0.0
        scale = float(np.abs(A_lower.diagonal()).max()) or 1.0
        while True:
            try:
                self._refactor(A_lower, shift)
                return shift
            except CholmodNotPositiveDefiniteError:
                # Only reachable without inertia (quasi-static) or with an unprojected
                # Hessian: regularise like Levenberg-Marquardt.
                shift = max(1e-10 * scale, 10.0 * shift)
                if shift > scale:
                    raise

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._factor(b)


def solve_once(A_lower: sp.csc_matrix, b: np.ndarray, allow_shift: bool = True) -> np.ndarray | None:
    """Solve with a matrix whose pattern is seen once: analyse, factor (shifted if not
    positive definite, or None when `allow_shift` is off), solve.

    Ordered by AMD alone: CHOLMOD's default also tries METIS, which on the 61K-DOF dress
    (contact couplings merged) spends 1.0 s to save 0.2 s of the 0.9 s factorization;
    AMD analyses in 0.13 s."""
    return _factor_and_solve(CholeskySolver(A_lower, ordering="amd"), A_lower, b, allow_shift)


def _factor_and_solve(solver: CholeskySolver, A_lower, b, allow_shift: bool) -> np.ndarray | None:
    if allow_shift:
        solver.factorize(A_lower)
    elif not solver.try_factorize(A_lower):
        return None
    return solver.solve(b)


# A pattern is analysed afresh (rather than joined to the one analysed) when the join
# would hold this many times the entries in use: stale entries only add fill.
STALE_ENTRIES = 1.1


class MergedSolver:
    """Solves F - diag(shift) + tril(B) for a lower matrix F of a fixed pattern and
    couplings B outside it, both changing from one Newton iteration to the next (contact
    merged back, sim/newton.py), reusing one symbolic analysis while they can.

    The pattern is F's nonzero entries (its contact blocks are mostly zero: factoring
    them would add a third to the fill) and B's, joined with those since the last
    analysis; a matrix that falls inside it is padded with zeros and only refactored.
    Contacts come and go slowly, so most iterations skip the ordering (AMD: 0.14 s of a
    1.07 s solve on the 61K-DOF dress)."""

    def __init__(self):
        self.analyses = 0
        self.reuses = 0
        self._slots = None  # which of F's entries the pattern analysed holds
        self._keys = None  # its couplings: sorted keys column * n + row

    def solve(self, F: sp.csc_matrix, shift: np.ndarray, B: sp.spmatrix, b: np.ndarray,
              allow_shift: bool = True) -> np.ndarray | None:
        n = F.shape[0]
        low = sp.tril(B, format="coo")
        on_diagonal = low.row == low.col  # in F already
        shift = shift - np.bincount(low.row[on_diagonal], low.data[on_diagonal], minlength=n)
        low = sp.tril(B, -1, format="coo")
        keys = low.col.astype(np.int64) * n + low.row
        order = np.argsort(keys)
        keys, values = keys[order], low.data[order]
        slots = F.data != 0.0
        slots[F.indptr[:-1]] = True  # the diagonal (first in each column), shifted
        if self._covers(F, slots, keys):
            self.reuses += 1
        else:
            analyse = slots, keys
            if self._slots is not None and self._slots.size == slots.size:
                joined = slots | self._slots, np.union1d(self._keys, keys)
                if np.count_nonzero(joined[0]) + joined[1].size <= \
                        STALE_ENTRIES * (np.count_nonzero(slots) + keys.size):
                    analyse = joined
            self._analyse(F, *analyse)
            self.analyses += 1
        data = np.zeros(self._pattern.nnz)
        data[self._fixed] = F.data[self._slots]
        data[self._diagonal] -= shift
        data[self._coupled[np.searchsorted(self._keys, keys)]] = values
        A = sp.csc_matrix((data, self._pattern.indices, self._pattern.indptr), shape=(n, n))
        return _factor_and_solve(self._solver, A, b, allow_shift)

    def _covers(self, F, slots, keys) -> bool:
        if self._slots is None or self._slots.size != slots.size or np.any(slots & ~self._slots):
            return False
        at = np.minimum(np.searchsorted(self._keys, keys), self._keys.size - 1)
        return bool(np.all(self._keys[at] == keys)) if keys.size else True

    def _analyse(self, F: sp.csc_matrix, slots: np.ndarray, keys: np.ndarray) -> None:
        n = F.shape[0]
        if not F.has_sorted_indices or not np.array_equal(F.indices[F.indptr[:-1]], np.arange(n)):
            raise ValueError("MergedSolver: F needs sorted rows, the diagonal first in each column")
        # F's entries in use tagged 1, the couplings 2: disjoint, so the sum's (sorted)
        # entries say where each lands, F's in their own order.
        cols = np.repeat(np.arange(n), np.diff(F.indptr))[slots]
        F1 = sp.csc_matrix((np.ones(cols.size), (F.indices[slots], cols)), shape=F.shape)
        K = sp.csc_matrix((np.full(keys.size, 2.0), (keys % n, keys // n)), shape=F.shape)
        P = (F1 + K).tocsc()
        P.sort_indices()
        self._pattern = P
        self._fixed = np.flatnonzero(P.data == 1.0)
        self._coupled = np.flatnonzero(P.data == 2.0)
        self._slots, self._keys = slots, keys
        # The diagonal's place among F's entries in use, then in P.
        self._diagonal = self._fixed[np.cumsum(slots)[F.indptr[:-1]] - 1]
        self._solver = CholeskySolver(P, ordering="amd")


def pcg(apply_A, b: np.ndarray, precondition, x0: np.ndarray, rtol: float, max_iterations: int):
    """Preconditioned conjugate gradients for the SPD system A x = b from x0.

    Returns (x, iterations, converged). Every iterate lowers the quadratic model
    x.A x / 2 - b.x, so an early stop still gives a descent direction for Newton.
    """
    x = x0.copy()
    r = b - apply_A(x)
    stop = rtol * np.linalg.norm(b)
    if np.linalg.norm(r) <= stop:
        return x, 0, True
    z = precondition(r)
    d = z.copy()
    rz = float(r @ z)
    for k in range(1, max_iterations + 1):
        Ad = apply_A(d)
        dAd = float(d @ Ad)
        if dAd <= 0.0:
            return x, k, False
        a = rz / dAd
        x += a * d
        r -= a * Ad
        if np.linalg.norm(r) <= stop:
            return x, k, True
        z = precondition(r)
        rz_new = float(r @ z)
        d = z + (rz_new / rz) * d
        rz = rz_new
    return x, max_iterations, False


def neumann(apply_A, b: np.ndarray, precondition, x0: np.ndarray, rtol: float, max_terms: int):
    """Neumann series for A x = b with A = M - N, M^-1 = `precondition`:
    x = sum_k (M^-1 N)^k M^-1 b, i.e. x <- x + M^-1 (b - A x) from x0 = M^-1 b. Converges
    when ||M^-1 N|| < 1 (the Gershgorin test). Returns (x, terms, converged)."""
    x = x0.copy()
    stop = rtol * np.linalg.norm(b)
    for k in range(1, max_terms + 1):
        r = b - apply_A(x)
        if np.linalg.norm(r) <= stop:
            return x, k - 1, True
        x += precondition(r)
    return x, max_terms, bool(np.linalg.norm(b - apply_A(x)) <= stop)
