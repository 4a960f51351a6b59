"""MKL PARDISO's sparse Cholesky called directly (ctypes), where MKL is installed.

On the cloth's Hessians PARDISO factors about three times faster than CHOLMOD here: the
seeded hanging sheet at 75^2 (16,869 rows, 4.48M values in L either way), 2 threads,
26 ms a refactorization against CHOLMOD's 97 ms with relaxed supernodes (sim/supernodal.py);
a solve 3.4 ms against 7.8. Both store the same factor; PARDISO's dense kernels on the
small fronts of a 2D mesh's factor run faster.

The matrix is real symmetric positive definite (mtype 2): a pivot that is not positive
stops the factorization with error -4, which is how a Hessian that is not positive
definite is found (sim/linsolve.CholeskySolver.try_factorize). Only what
sim/linsolve.py needs is bound: analyse, factor (with a shift), solve, free.

MKL comes from PyPI's `mkl` wheel (x86_64 Linux), which puts libmkl_rt in the
environment's lib folder, off the loader's path; elsewhere `available()` is False and
CHOLMOD does the work. MKL's threads are GNU OpenMP's, the pool numba's kernels already
use (sim/threads.py), so the two never compete for the cores.
"""

from __future__ import annotations

import ctypes
import glob
import os
import sys

import numpy as np
import scipy.sparse as sp

_SPD = 2  # mtype: real symmetric positive definite
_ANALYSE, _FACTOR, _SOLVE, _RELEASE = 11, 22, 33, -1
_NOT_POSITIVE = -4  # "zero pivot": a pivot <= 0 in the Cholesky factorization
_GNU_THREADS = 3  # MKL_THREADING_GNU (mkl_service.h)
# iparm[1], the fill-reducing ordering: minimum degree unless METIS is asked for. The
# hanging sheet at 75^2: 26 ms a factorization after minimum degree, 33 ms after METIS.
_ORDERINGS = {"metis": 2}


def _candidates() -> list[str]:
    here = [os.path.join(prefix, "lib") for prefix in dict.fromkeys((sys.prefix, sys.base_prefix))]
    found = [path for folder in here for path in sorted(glob.glob(os.path.join(folder, "libmkl_rt.so*")))]
    return found + ["libmkl_rt.so.2", "libmkl_rt.so"]


def _load():
    if os.environ.get("GARMENT_SOLVER", "").lower() == "cholmod":
        return None
    for name in _candidates():
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        if not hasattr(lib, "pardiso"):
            continue
        lib.MKL_Set_Threading_Layer(ctypes.c_int(_GNU_THREADS))
        lib.MKL_Set_Num_Threads_Local.restype = ctypes.c_int
        return lib
    return None


_LIB = _load()


def available() -> bool:
    return _LIB is not None


def _ptr(a: np.ndarray) -> ctypes.c_void_p:
    return a.ctypes.data_as(ctypes.c_void_p)


def _sorted(A: sp.csc_matrix) -> sp.csc_matrix:
    """A with its row indices sorted within each column, as PARDISO reads them."""
    return A if A.has_sorted_indices else A.sorted_indices()


_NO_VECTOR = np.zeros(1)  # b and x of the phases that solve nothing
_NO_VECTOR_PTR = _ptr(_NO_VECTOR)


class PardisoFactor:
    """A Cholesky factor of one lower-triangular CSC pattern: analysed once, refactored
    in place (`factorize`) for every matrix of that pattern.

    PARDISO reads the upper triangle in CSR, which is the lower triangle in CSC read as
    is; it needs every diagonal entry stored, first in its row."""

    def __init__(self, A_lower: sp.csc_matrix, ordering: str = "default", threads: int = 1):
        A = _sorted(A_lower)
        n = A.shape[0]
        self._ia = (A.indptr + 1).astype(np.int32)  # one-based: PARDISO's default
        self._ja = (A.indices + 1).astype(np.int32)
        self._diagonal = A.indptr[:-1]
        if not np.array_equal(A.indices[self._diagonal], np.arange(n)):
            raise ValueError("PARDISO needs every diagonal entry stored")
        self._a = np.array(A.data, dtype=np.float64)
        self._n = n
        self._threads = threads
        self._pt = np.zeros(64, dtype=np.int64)  # PARDISO's handle
        self._iparm = np.zeros(64, dtype=np.int32)
        self._iparm[0] = 1  # not the defaults: the values below
        self._iparm[1] = _ORDERINGS.get(ordering, 0)
        self._iparm[9] = 8  # pivot perturbation 1e-8 (indefinite matrices only)
        self._perm = np.zeros(n, dtype=np.int32)
        # Pointers taken once: the arrays are only ever written in place, and at
        # interpreter exit (a factor freed by __del__) numpy's .ctypes can no longer import.
        self._ptrs = tuple(_ptr(a) for a in (self._pt, self._a, self._ia, self._ja, self._perm, self._iparm))
        self._live = False
        if n == 0:  # nothing free to solve for (every point pinned)
            return
        error = self._call(_ANALYSE)
        if error != 0:
            raise MemoryError(f"PARDISO could not analyse a {n}-row matrix (error {error})")
        self._live = True

    def _call(self, phase: int, b: np.ndarray | None = None, x: np.ndarray | None = None, nrhs: int = 1) -> int:
        i32 = lambda v: ctypes.byref(ctypes.c_int32(v))
        error = ctypes.c_int32(0)
        pt, a, ia, ja, perm, iparm = self._ptrs
        b_ptr = _NO_VECTOR_PTR if b is None else _ptr(b)
        x_ptr = _NO_VECTOR_PTR if x is None else _ptr(x)
        # No lock: each factor has its own handle (a global one deadlocked when the
        # garbage collector freed another factor inside a call).
        before = _LIB.MKL_Set_Num_Threads_Local(ctypes.c_int(self._threads))
        try:
            _LIB.pardiso(pt, i32(1), i32(1), i32(_SPD), i32(phase), i32(self._n), a, ia, ja, perm,
                         i32(nrhs), iparm, i32(0), b_ptr, x_ptr, ctypes.byref(error))
        finally:
            _LIB.MKL_Set_Num_Threads_Local(ctypes.c_int(before))
        return error.value

    def factorize(self, A_lower: sp.csc_matrix, shift: float = 0.0) -> bool:
        """Factor A + shift I (A of the analysed pattern); False if it is not positive
        definite."""
        if self._n == 0:
            return True
        self._a[:] = _sorted(A_lower).data
        if shift:
            self._a[self._diagonal] += shift
        error = self._call(_FACTOR)
        if error == _NOT_POSITIVE:
            return False
        if error != 0:
            raise MemoryError(f"PARDISO could not factor a {self._n}-row matrix (error {error})")
        return True

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asfortranarray(b, dtype=np.float64)
        x = np.empty_like(b)
        if self._n == 0:
            return x
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        error = self._call(_SOLVE, b, x, nrhs)
        if error != 0:
            raise RuntimeError(f"PARDISO could not solve (error {error})")
        return x

    def __del__(self):
        if getattr(self, "_live", False) and _LIB is not None:
            self._call(_RELEASE)
            self._live = False
