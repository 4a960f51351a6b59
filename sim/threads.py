"""Thread settings for the 2-core target, applied before numpy or CHOLMOD load.

Measured on the 75^2 hanging cloth, seconds per Newton iteration: numba's OpenMP workers
spin after each kernel unless passive, and multi-threaded OpenBLAS (numpy's and CHOLMOD's)
loses more to hand-offs with numba than it gains: 0.26-0.28 s with 2 BLAS threads,
0.153-0.158 s with 1. The environment still overrides these defaults.
"""

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
