"""Sparse Cholesky through CHOLMOD (scikit-sparse), symbolic analysis reused.

The fill-reducing ordering and supernodal structure depend only on the pattern, so they
are computed once per pattern; every Newton iteration refactors numerically in place.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from sksparse.cholmod import CholmodNotPositiveDefiniteError, analyze


class CholeskySolver:
    """Solves H x = b for the lower-triangular CSC matrices of one fixed pattern."""

    def __init__(self, A_lower: sp.csc_matrix):
        self._factor = analyze(A_lower, mode="supernodal")
        self.n_factorizations = 0

    def try_factorize(self, A_lower: sp.csc_matrix) -> bool:
        """Factor A if it is positive definite; False (and no usable factor) if not."""
        try:
            self._factor.cholesky_inplace(A_lower)
        except CholmodNotPositiveDefiniteError:
            return False
        self.n_factorizations += 1
        return True

    def factorize(self, A_lower: sp.csc_matrix) -> float:
        """Factor A (+ shift I if A is not positive definite); returns the shift used."""
        shift = 0.0
        scale = float(np.abs(A_lower.diagonal()).max()) or 1.0
        while True:
            try:
                self._factor.cholesky_inplace(A_lower, beta=shift)
                self.n_factorizations += 1
                return shift
            except CholmodNotPositiveDefiniteError:
                # Only reachable without inertia (quasi-static) or with an unprojected
                # Hessian: regularise like Levenberg-Marquardt.
                shift = max(1e-10 * scale, 10.0 * shift)
                if shift > scale:
                    raise

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._factor(b)


class MergedSolver:
    """Solves (A - diag(d) + E) x = b: A on a fixed lower-triangular pattern, E a few
    lower-triangular entries outside it that come and go (contact couplings merged back
    into the Hessian, sim/potential.py).

    One symbolic analysis serves every matrix whose entries lie in the pattern analysed:
    A's pattern, explicit zeros kept, plus every outside entry seen since. A new entry
    grows that pattern and analyses it again; once the entries seen outnumber `slack`
    times A's, the pattern restarts from A's plus the current ones. On the 61K-DOF dress
    a fresh analysis costs more than the numeric factorization (1.0 s against 0.7 s).
    """

    def __init__(self, A_lower: sp.csc_matrix, slack: float = 0.1):
        self.n = A_lower.shape[0]
        self._base_keys = _keys(A_lower)
        self._slack = slack
        self._keys = None  # sorted keys (col * n + row) of the pattern analysed
        self.n_analyses = 0

    def solve(self, A_lower: sp.csc_matrix, d: np.ndarray, E: sp.coo_matrix, b: np.ndarray,
              allow_shift: bool = True) -> np.ndarray | None:
        """x, factoring with a shift when the matrix is not positive definite (as
        CholeskySolver does), or None then when `allow_shift` is off."""
        E_keys = E.col.astype(np.int64) * self.n + E.row
        pos = self._positions(E_keys)
        if pos is None:
            self._analyse(E_keys)
            pos = self._positions(E_keys)
        data = np.zeros(self._keys.size)
        data[self._base_pos] = A_lower.data
        data[self._diag_pos] -= d
        np.add.at(data, pos, E.data)
        M = sp.csc_matrix((data, self._indices, self._indptr), shape=(self.n, self.n))
        scale = float(np.abs(data[self._diag_pos]).max()) or 1.0
        shift = 0.0
        while True:
            try:
                self._factor.cholesky_inplace(M, beta=shift)
                return self._factor(b)
            except CholmodNotPositiveDefiniteError:
                if not allow_shift:
                    return None
                shift = max(1e-10 * scale, 10.0 * shift)
                if shift > scale:
                    raise

    def _positions(self, keys: np.ndarray) -> np.ndarray | None:
        """Where `keys` sit in the analysed pattern, or None if one is missing."""
        if self._keys is None:
            return None
        pos = np.minimum(np.searchsorted(self._keys, keys), self._keys.size - 1)
        return pos if np.array_equal(self._keys[pos], keys) else None

    def _analyse(self, new_keys: np.ndarray) -> None:
        grown = np.union1d(self._keys if self._keys is not None else self._base_keys, new_keys)
        if grown.size > (1.0 + self._slack) * self._base_keys.size:
            grown = np.union1d(self._base_keys, new_keys)
        self._keys = grown
        cols, rows = np.divmod(grown, self.n)
        self._indices = rows.astype(np.int32)
        self._indptr = np.searchsorted(cols, np.arange(self.n + 1)).astype(np.int32)
        self._base_pos = np.searchsorted(grown, self._base_keys)
        self._diag_pos = np.searchsorted(grown, np.arange(self.n, dtype=np.int64) * (self.n + 1))
        pattern = sp.csc_matrix((np.ones(grown.size), self._indices, self._indptr), shape=(self.n, self.n))
        self._factor = analyze(pattern, mode="supernodal")
        self.n_analyses += 1


def _keys(A: sp.csc_matrix) -> np.ndarray:
    """col * n + row of every stored entry of a CSC matrix, explicit zeros included."""
    cols = np.repeat(np.arange(A.shape[1], dtype=np.int64), np.diff(A.indptr))
    return cols * A.shape[0] + A.indices


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
