"""CHOLMOD's supernodal Cholesky called directly (ctypes), with relaxed supernodes.

scikit-sparse fixes CHOLMOD's supernode amalgamation at its defaults (nrelax 4/16/48,
zrelax 0.8/0.1/0.05); on the cloth's Hessians that leaves many small fronts, and dense
BLAS on small fronts is slow. Merging more columns into a supernode stores some explicit
zeros and runs faster. Dumped 61K merged dress systems, 2 BLAS threads, nrelax 8/64/192
and zrelax 0.8/0.2/0.1: AMD analysis + factorization + solve 0.92 -> 0.79 s, a
refactorization 0.58 -> 0.49 s; L stores 35.0M values instead of 30.1M, in 1,082
supernodes instead of 2,470 (16/128/256 with zrelax 0.3/0.2 was no faster).

Only what sim/linsolve.py needs is bound: start, analyse, factor (with a shift), solve,
free. The layout of cholmod_common is mirrored up to the fields set here, for
CHOLMOD 3 only, and checked against its documented defaults after cholmod_start: any
mismatch (another version, another build) leaves `available()` False and callers use
scikit-sparse.
"""

from __future__ import annotations

import ctypes
import threading
from ctypes import POINTER, byref, c_double, c_int, c_size_t, c_void_p

import numpy as np
import scipy.sparse as sp

NRELAX = (8, 64, 192)
ZRELAX = (0.8, 0.2, 0.1)

_AMD, _SUPERNODAL, _INT, _REAL, _DOUBLE, _SOLVE_A = 2, 2, 0, 1, 0, 0
_COMMON_BYTES = 1 << 16  # cholmod_common is about 3 KB in CHOLMOD 3; room to spare


class _Method(ctypes.Structure):
    _fields_ = [("lnz", c_double), ("fl", c_double), ("prune_dense", c_double),
                ("prune_dense2", c_double), ("nd_oksep", c_double), ("other_1", c_double * 4),
                ("nd_small", c_size_t), ("other_2", c_size_t * 4), ("aggressive", c_int),
                ("order_for_lu", c_int), ("nd_compress", c_int), ("nd_camd", c_int),
                ("nd_components", c_int), ("ordering", c_int), ("other_3", c_size_t * 4)]


class _CommonHead(ctypes.Structure):
    """The first fields of cholmod_common (CHOLMOD 3.0, cholmod_core.h)."""

    _fields_ = [("dbound", c_double), ("grow0", c_double), ("grow1", c_double),
                ("grow2", c_size_t), ("maxrank", c_size_t), ("supernodal_switch", c_double),
                ("supernodal", c_int), ("final_asis", c_int), ("final_super", c_int),
                ("final_ll", c_int), ("final_pack", c_int), ("final_monotonic", c_int),
                ("final_resymbol", c_int), ("zrelax", c_double * 3), ("nrelax", c_size_t * 3),
                ("prefer_zomplex", c_int), ("prefer_upper", c_int),
                ("quick_return_if_not_posdef", c_int), ("prefer_binary", c_int),
                ("print", c_int), ("precise", c_int), ("try_catch", c_int),
                ("error_handler", c_void_p), ("nmethods", c_int), ("current", c_int),
                ("selected", c_int), ("method", _Method * 10), ("postorder", c_int)]


class _Sparse(ctypes.Structure):
    _fields_ = [("nrow", c_size_t), ("ncol", c_size_t), ("nzmax", c_size_t), ("p", c_void_p),
                ("i", c_void_p), ("nz", c_void_p), ("x", c_void_p), ("z", c_void_p),
                ("stype", c_int), ("itype", c_int), ("xtype", c_int), ("dtype", c_int),
                ("sorted", c_int), ("packed", c_int)]


class _Dense(ctypes.Structure):
    _fields_ = [("nrow", c_size_t), ("ncol", c_size_t), ("nzmax", c_size_t), ("d", c_size_t),
                ("x", c_void_p), ("z", c_void_p), ("xtype", c_int), ("dtype", c_int)]


class _FactorHead(ctypes.Structure):
    _fields_ = [("n", c_size_t), ("minor", c_size_t),  # minor < n: not positive definite
                ("Perm", c_void_p), ("ColCount", c_void_p), ("IPerm", c_void_p),
                ("nzmax", c_size_t), ("p", c_void_p), ("i", c_void_p), ("x", c_void_p),
                ("z", c_void_p), ("nz", c_void_p), ("next", c_void_p), ("prev", c_void_p),
                ("nsuper", c_size_t), ("ssize", c_size_t), ("xsize", c_size_t)]


def _set_relaxation(head: _CommonHead, nrelax, zrelax) -> None:
    head.nrelax[:], head.zrelax[:] = nrelax, zrelax


def _load():
    """(library, common) ready for relaxed supernodal AMD analyses, or None."""
    try:
        lib = ctypes.CDLL("libcholmod.so.3")
    except OSError:
        return None
    version = (c_int * 3)()
    lib.cholmod_version.restype = c_int
    lib.cholmod_version(version)
    if version[0] != 3:
        return None
    buffer = ctypes.create_string_buffer(_COMMON_BYTES)
    lib.cholmod_start.argtypes = [c_void_p]
    lib.cholmod_start(buffer)
    head = _CommonHead.from_buffer(buffer)
    defaults = (head.grow0 == 1.2 and head.grow2 == 5 and head.maxrank == 8
                and head.supernodal_switch == 40.0 and tuple(head.nrelax) == (4, 16, 48)
                and tuple(head.zrelax) == (0.8, 0.1, 0.05) and head.print == 3
                and head.nmethods == 0 and head.postorder == 1)
    if not defaults:
        return None
    head.supernodal, head.print = _SUPERNODAL, 0
    _set_relaxation(head, NRELAX, ZRELAX)
    lib.cholmod_analyze.restype = c_void_p
    lib.cholmod_analyze.argtypes = [POINTER(_Sparse), c_void_p]
    lib.cholmod_factorize_p.restype = c_int
    lib.cholmod_factorize_p.argtypes = [POINTER(_Sparse), POINTER(c_double), c_void_p, c_size_t,
                                        c_void_p, c_void_p]
    lib.cholmod_solve.restype = c_void_p
    lib.cholmod_solve.argtypes = [c_int, c_void_p, POINTER(_Dense), c_void_p]
    lib.cholmod_free_factor.argtypes = [POINTER(c_void_p), c_void_p]
    lib.cholmod_free_dense.argtypes = [POINTER(c_void_p), c_void_p]
    return lib, buffer


_LIB = _load()


def available() -> bool:
    return _LIB is not None


_ORDERINGS = {"natural": 0, "amd": 2, "metis": 3, "nesdis": 4}
_LOCK = threading.RLock()  # one cholmod_common for the process; ctypes drops the GIL
# Re-entrant: the garbage collector may free another factor (`__del__`) from inside a
# locked section, on the same thread (a plain lock deadlocked so in PARDISO's binding).


class RelaxedFactor:
    """A symbolic analysis of one lower-triangular CSC pattern, refactored in place.

    ordering: "default" (CHOLMOD's: AMD, then METIS if AMD fills badly) or one of
    _ORDERINGS."""

    def __init__(self, A_lower: sp.csc_matrix, ordering: str = "default"):
        if _LIB is None:
            raise RuntimeError("CHOLMOD 3 not found for the relaxed supernodal solver")
        if ordering != "default" and ordering not in _ORDERINGS:
            raise ValueError(f"unknown CHOLMOD ordering {ordering!r}")
        self._lib, self._common = _LIB
        self.n = A_lower.shape[0]
        self._bind(A_lower)
        head = _CommonHead.from_buffer(self._common)
        with _LOCK:
            head.nmethods = 0 if ordering == "default" else 1
            head.method[0].ordering = _ORDERINGS.get(ordering, _AMD)
            self._L = c_void_p(self._lib.cholmod_analyze(byref(self._A), self._common))
        if not self._L.value:
            raise MemoryError(f"CHOLMOD could not analyse a {self.n}-row matrix")

    @property
    def supernodes(self) -> int:
        return int(_FactorHead.from_address(self._L.value).nsuper)

    @property
    def stored(self) -> int:
        """Entries stored in L, explicit zeros of the amalgamation included."""
        return int(_FactorHead.from_address(self._L.value).xsize)

    def _bind(self, A_lower: sp.csc_matrix) -> None:
        A = A_lower if A_lower.has_sorted_indices else A_lower.sorted_indices()
        # Kept referenced: CHOLMOD reads these buffers through the struct.
        self._arrays = (np.ascontiguousarray(A.indptr, np.int32),
                        np.ascontiguousarray(A.indices, np.int32),
                        np.ascontiguousarray(A.data, np.float64))
        p, i, x = self._arrays
        self._A = _Sparse(self.n, self.n, x.size, p.ctypes.data, i.ctypes.data, None,
                          x.ctypes.data, None, -1, _INT, _REAL, _DOUBLE, 1, 1)

    def factorize(self, A_lower: sp.csc_matrix, shift: float = 0.0) -> bool:
        """Factor A + shift I (A: the analysed pattern); False if not positive definite."""
        self._bind(A_lower)
        beta = (c_double * 2)(shift, 0.0)
        with _LOCK:
            ok = self._lib.cholmod_factorize_p(byref(self._A), beta, None, 0, self._L, self._common)
        if not ok:
            raise MemoryError(f"CHOLMOD could not factor a {self.n}-row matrix")
        return _FactorHead.from_address(self._L.value).minor == self.n

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.ascontiguousarray(b, np.float64)
        B = _Dense(self.n, 1, self.n, self.n, b.ctypes.data, None, _REAL, _DOUBLE)
        with _LOCK:
            X = c_void_p(self._lib.cholmod_solve(_SOLVE_A, self._L, byref(B), self._common))
        if not X.value:
            raise MemoryError(f"CHOLMOD could not solve with a {self.n}-row factor")
        dense = _Dense.from_address(X.value)
        x = np.ctypeslib.as_array(ctypes.cast(dense.x, POINTER(c_double)), (self.n,)).copy()
        with _LOCK:
            self._lib.cholmod_free_dense(byref(X), self._common)
        return x

    def __del__(self):
        if getattr(self, "_L", None) is not None and self._L.value:
            with _LOCK:
                self._lib.cholmod_free_factor(byref(self._L), self._common)
