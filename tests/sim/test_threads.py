"""Thread defaults hold however the user's script orders its imports."""

import ast
import subprocess
import sys

import pytest

from tests.support.paths import ROOT

# numpy imported first (as any script would), its OpenBLAS started with one thread per
# core; importing sim must bring it down to OPENBLAS_NUM_THREADS without the variable
# having been read in time.
SCRIPT = """
import ctypes, os
import numpy
import sim
getters = ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads", "openblas_get_num_threads")
counts = []
paths = {line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line.lower() and "/" in line}
for path in sorted(paths):
    lib = ctypes.CDLL(path)
    get = next((getattr(lib, g) for g in getters if hasattr(lib, g)), None)
    if get is not None:
        counts.append(get())
print(os.environ.get("OPENBLAS_NUM_THREADS"), counts)
"""


def test_numpy_loaded_first_gets_one_blas_thread():
    env = {"PATH": "/usr/bin:/bin"}  # no OPENBLAS_NUM_THREADS from outside
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, check=True,
                         cwd=ROOT).stdout.split(maxsplit=1)
    variable, counts = out[0], ast.literal_eval(out[1])
    if not counts:
        pytest.skip("numpy here does not use OpenBLAS")
    assert variable == "1"
    assert counts == [1] * len(counts)
