"""Thread settings for the 2-core target, applied before numpy or CHOLMOD load.

Measured on the 75^2 hanging cloth, seconds per Newton iteration: numba's OpenMP workers
spin after each kernel unless passive, and multi-threaded OpenBLAS (numpy's and CHOLMOD's)
loses more to hand-offs with numba than it gains: 0.26-0.28 s with 2 BLAS threads,
0.153-0.158 s with 1. The environment still overrides these defaults.

A script that imports numpy before us (or ipctk, which loads numpy) has started numpy's
OpenBLAS with one thread per core before the variable is read; those already loaded are
told the count directly (`limit_loaded_blas`). Left at 2 threads, a 17K-entry dot product
took 3-7 ms instead of 3 us once numba's and ipctk's thread pools were up and the other
core was busy: the hanging cloth at 75^2, 3.0 against 2.2 s per step.
"""

import ctypes
import os
import sys

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# numba takes TBB before OpenMP where both are installed (MKL's wheel brings TBB); its
# kernels were measured on OpenMP, whose pool MKL's PARDISO shares (sim/pardiso.py).
os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")

# Thread-count setters of the OpenBLAS builds we meet: numpy's wheels (scipy-openblas,
# 64-bit integers) and Debian's libopenblas (CHOLMOD's).
SETTERS = ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads", "openblas_set_num_threads")


def loaded_blas() -> list[str]:
    """Paths of the OpenBLAS libraries mapped into this process (Linux; [] elsewhere)."""
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "openblas" in line.lower() and "/" in line}
    except OSError:
        return []
    return sorted(paths)


def limit_loaded_blas(threads: int) -> int:
    """Set the thread count of every OpenBLAS already loaded; returns how many were set."""
    done = 0
    for path in loaded_blas():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        setter = next((getattr(lib, name) for name in SETTERS if hasattr(lib, name)), None)
        if setter is not None:
            setter(ctypes.c_int(threads))
            done += 1
    return done


if "numpy" in sys.modules and os.environ["OPENBLAS_NUM_THREADS"].isdigit():
    limit_loaded_blas(int(os.environ["OPENBLAS_NUM_THREADS"]))
