"""Sparse Cholesky, symbolic analysis reused.

MKL's PARDISO (sim/pardiso.py) factors where MKL is installed (x86_64 Linux): about 3x
faster than CHOLMOD on the cloth's Hessians, with the same fill. Elsewhere, or with
GARMENT_SOLVER=cholmod, CHOLMOD is called through sim/supernodal.py (relaxed supernodes,
faster on cloth Hessians) where it recognises the library, through scikit-sparse otherwise.

The fill-reducing ordering and supernodal structure depend only on the pattern, so they
are computed once per pattern of nonzeros (CholeskySolver: a contact Hessian's fixed
pattern is mostly zeros, and only its nonzero part is factored); every Newton iteration
refactors numerically in place while its nonzeros stay inside the analysed pattern.
"""

from __future__ import annotations

import ctypes
import os
from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp
from sksparse.cholmod import CholmodNotPositiveDefiniteError, analyze

from . import pardiso, supernodal

# CHOLMOD's supernodal factorization spends its time in dense BLAS on the fronts. BLAS
# runs on one thread by default (sim/threads.py: numba's kernels and BLAS would compete
# for the cores), and only a factorization, where numba is idle, gets more. Measured on
# 2 cores with the relaxed supernodes (stop 66): merged dress_04 Hessian (20K rows)
# 210 -> 130 ms a refactorization; seeded hanging sheet, whole Newton iterations,
# 75^2 (17K) 251 -> 172 ms, 60^2 (11K) 135 -> 88 ms, 45^2 (6K) 70 -> 48 ms, 30^2 (2.7K)
# 21 -> 23 ms (below this threshold one thread). Merged 61K dress: 1.23 -> 0.99 s.
PARALLEL_ROWS = 5_000
LARGE_THREADS = int(os.environ.get("GARMENT_CHOLMOD_THREADS", min(2, os.cpu_count() or 1)))


def _system_openblas():
    """The system OpenBLAS that Debian's CHOLMOD links, or None (another BLAS)."""
    try:
        lib = ctypes.CDLL("libopenblas.so.0")
        return lib if hasattr(lib, "openblas_set_num_threads") else None
    except OSError:
        return None


_OPENBLAS = _system_openblas()

# Every merged contact solve analyses a new pattern, so CHOLMOD allocates a new factor
# (200 MB at 61K rows) and frees the last. glibc serves blocks above 32 MB with mmap, so
# each factor was faulted in page by page and handed back; from the heap it reuses the
# pages the last one left. Dumped 61K merged systems, analysis + factor + solve: median
# 1.15-1.29 s -> 0.93-0.99 s. The heap then keeps up to 2 GB it could return to the OS.
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3


def _keep_large_blocks_on_heap() -> None:
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return  # not glibc: nothing to tune
    libc.mallopt(M_MMAP_THRESHOLD, 1 << 30)
    libc.mallopt(M_TRIM_THRESHOLD, 1 << 31)


_keep_large_blocks_on_heap()


def factor_threads(rows: int) -> int:
    """Threads for a factorization of `rows` rows: LARGE_THREADS where that many pay."""
    return LARGE_THREADS if rows >= PARALLEL_ROWS else 1


@contextmanager
def blas_threads(rows: int):
    """factor_threads(rows) OpenBLAS threads for a CHOLMOD factorization."""
    if _OPENBLAS is None or factor_threads(rows) <= 1:
        yield
        return
    before = _OPENBLAS.openblas_get_num_threads()
    _OPENBLAS.openblas_set_num_threads(LARGE_THREADS)
    try:
        yield
    finally:
        _OPENBLAS.openblas_set_num_threads(before)


class _ScikitFactor:
    """scikit-sparse's CHOLMOD factor behind RelaxedFactor's interface: the fallback
    where sim/supernodal.py does not recognise the CHOLMOD it finds."""

    def __init__(self, A_lower: sp.csc_matrix, ordering: str):
        self._factor = analyze(A_lower, mode="supernodal", ordering_method=ordering)

    def factorize(self, A_lower: sp.csc_matrix, shift: float) -> bool:
        try:
            self._factor.cholesky_inplace(A_lower, beta=shift)
        except CholmodNotPositiveDefiniteError:
            return False
        return True

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._factor(b)


def _factor(A_lower: sp.csc_matrix, ordering: str):
    if pardiso.available():
        return pardiso.PardisoFactor(A_lower, ordering, factor_threads(A_lower.shape[0]))
    make = supernodal.RelaxedFactor if supernodal.available() else _ScikitFactor
    return make(A_lower, ordering)


# Of the entries a re-analysis keeps, the share that may be zero now: a pattern kept a
# little wider than the nonzeros lets contacts come and go without a new analysis.
SLACK = 0.25


class CholeskySolver:
    """Solves H x = b for the lower-triangular CSC matrices of one fixed pattern.

    Only the pattern's nonzero part is factored. A contact Hessian's pattern holds the
    stencil of every cloth triangle, as any may touch, and few do: in dress_02's sewing
    (9.5K DOFs) 286K of 587K entries were nonzero, and L held 2.2M values instead of 4.1M
    (factorization 55 ms against 123 ms, plus 24 ms for an AMD analysis). The analysis
    is kept while the nonzeros stay inside it, redone when one falls outside, and at the
    start of a step (`restart`) when the nonzeros differ from it: the analysis then
    depends on that step's matrices alone, so a run resumed from a checkpoint repeats the
    uninterrupted one bit for bit.

    ordering: CHOLMOD's ordering method (its default tries AMD and METIS).
    nonzeros: False factors the whole pattern, analysed once: for a pattern that fills
    (no contact), where masking each matrix only costs (the hanging sheet: 8 %)."""

    def __init__(self, A_lower: sp.csc_matrix, ordering: str = "default", nonzeros: bool = True):
        self._ordering = ordering
        self._nonzeros = nonzeros
        self.n_factorizations = 0
        self.n_analyses = 0
        self._adopt(A_lower)

    def _adopt(self, A_lower: sp.csc_matrix) -> None:
        """Take A's pattern as the fixed one; nothing analysed yet."""
        self._indptr, self._indices = A_lower.indptr.copy(), A_lower.indices.copy()
        if self._nonzeros:  # what picking out the nonzeros needs: each entry's column, the diagonal
            self._columns = np.repeat(np.arange(A_lower.shape[1]), np.diff(A_lower.indptr))
            self._diagonal = A_lower.indices == self._columns
        self._kept = None  # (nnz,) bool: the entries of the analysed pattern
        self._exact = True  # the next analysis: of the nonzeros alone, unless they are the kept ones
        self._factor = None

    def restart(self) -> None:
        """A new time step: its first factorization analyses anew unless the nonzeros are
        exactly the analysed pattern."""
        self._exact = True

    def _part(self, A_lower: sp.csc_matrix) -> sp.csc_matrix:
        """The analysed part of A, analysed anew when a nonzero of A falls outside it."""
        if not (np.array_equal(A_lower.indptr, self._indptr) and np.array_equal(A_lower.indices, self._indices)):
            # Another pattern (scipy drops entries that cancel to zero in a sum: a conform
            # Hessian lost one and 356 values met a 357-entry pattern): start over with it.
            self._adopt(A_lower)
        if not self._nonzeros:
            if self._factor is None:
                self._factor = _factor(A_lower, self._ordering)
                self.n_analyses += 1
            return A_lower
        nonzero = (A_lower.data != 0.0) | self._diagonal
        exact, self._exact = self._exact, False
        if self._kept is None or (nonzero & ~self._kept).any() or (exact and (nonzero != self._kept).any()):
            wider = nonzero if self._kept is None or exact else nonzero | self._kept
            self._kept = wider if wider.sum() <= (1.0 + SLACK) * nonzero.sum() else nonzero
            indptr = np.concatenate([[0], np.cumsum(np.bincount(self._columns[self._kept], minlength=A_lower.shape[1]))])
            self._A = sp.csc_matrix((A_lower.data[self._kept], A_lower.indices[self._kept], indptr),
                                    shape=A_lower.shape)
            self._factor = _factor(self._A, self._ordering)
            self.n_analyses += 1
        else:
            self._A.data[:] = A_lower.data[self._kept]
        return self._A

    def _refactor(self, A_lower: sp.csc_matrix, shift: float) -> bool:
        A = self._part(A_lower)
        with blas_threads(A.shape[0]):
            ok = self._factor.factorize(A, shift)
        self.n_factorizations += 1
        return ok

    def try_factorize(self, A_lower: sp.csc_matrix) -> bool:
        """Factor A if it is positive definite; False (and no usable factor) if not."""
        return self._refactor(A_lower, 0.0)

    def factorize(self, A_lower: sp.csc_matrix) -> float:
        """Factor A (+ shift I if A is not positive definite); returns the shift used."""
        shift, scale = 0.0, None
        while not self._refactor(A_lower, shift):
            # Only reachable without inertia (quasi-static) or with an unprojected
            # Hessian: regularise like Levenberg-Marquardt.
            scale = scale or float(np.abs(A_lower.diagonal()).max()) or 1.0
            shift = max(1e-10 * scale, 10.0 * shift)
            if shift > scale:
                raise np.linalg.LinAlgError(f"not positive definite even shifted by {shift:.3g}")
        return shift

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._factor.solve(b)


def solve_once(A_lower: sp.csc_matrix, b: np.ndarray, allow_shift: bool = True) -> np.ndarray | None:
    """Solve with a matrix whose pattern is seen once: analyse, factor (shifted if not
    positive definite, or None when `allow_shift` is off), solve.

    Ordered by AMD alone: CHOLMOD's default also tries METIS, which on the 61K-DOF dress
    (contact couplings merged: a pattern new at nearly every Newton iteration) spends
    1.0 s to save 0.2 s of the 0.9 s factorization; AMD analyses in 0.13 s."""
    solver = CholeskySolver(A_lower, ordering="amd")
    if allow_shift:
        solver.factorize(A_lower)
    elif not solver.try_factorize(A_lower):
        return None
    return solver.solve(b)


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
