"""The ctypes MKL PARDISO binding (sim/pardiso.py) against dense solves and CHOLMOD."""

import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import norm as sparse_norm

from sim import linsolve, pardiso, supernodal

from .test_supernodal import grid_laplacian, lower

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="MKL is not installed (x86_64 Linux only)")


def smallest_eigenvalue(m: int) -> float:
    """Of grid_laplacian(m, 0): twice the 1D Laplacian's."""
    return 2.0 * (2.0 - 2.0 * np.cos(np.pi / (m + 1)))


def test_mkl_is_installed_where_its_wheel_exists():
    # pyproject.toml asks for MKL on x86_64 Linux: without it every factorization
    # silently falls back to CHOLMOD, about 3x slower on the cloth's Hessians.
    if platform.machine() == "x86_64" and platform.system() == "Linux":
        assert pardiso.available()


@pytest.mark.parametrize("ordering,threads", [("default", 1), ("amd", 2), ("metis", 2)])
def test_solve_matches_dense(ordering, threads):
    A = grid_laplacian(30)
    b = np.random.default_rng(1).standard_normal(A.shape[0])
    f = pardiso.PardisoFactor(lower(A), ordering, threads)
    assert f.factorize(lower(A))
    x = f.solve(b)
    assert np.allclose(x, np.linalg.solve(A.toarray(), b), rtol=1e-10, atol=1e-12)
    # several right-hand sides at once, each as alone
    B = np.random.default_rng(2).standard_normal((A.shape[0], 3))
    X = f.solve(B)
    assert X.shape == B.shape
    assert np.allclose(X[:, 2], f.solve(B[:, 2].copy()), rtol=1e-12, atol=1e-14)


def test_the_same_factor_as_cholmod():
    A = lower(grid_laplacian(40))
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    f = pardiso.PardisoFactor(A, "amd", 2)
    g = supernodal.RelaxedFactor(A, "amd")
    assert f.factorize(A) and g.factorize(A)
    assert np.allclose(f.solve(b), g.solve(b), rtol=1e-10, atol=1e-13)


def test_refactor_same_pattern_new_values():
    A = grid_laplacian(20)
    f = pardiso.PardisoFactor(lower(A))
    b = np.ones(A.shape[0])
    for scale in (1.0, 3.0, 0.5):
        B = lower(A).copy()
        B.data *= scale
        assert f.factorize(B)
        assert np.allclose(A @ f.solve(b) * scale, b, atol=1e-10)


@pytest.mark.parametrize("margin", [1e-2, 1e-6])
def test_not_positive_definite_is_reported_and_a_shift_factors(margin):
    # Projected Newton relies on this: a Hessian that is not positive definite must
    # fail, even when its smallest eigenvalue is only just below zero.
    m = 15
    lam = smallest_eigenvalue(m)
    A = grid_laplacian(m, shift=-lam * (1.0 + margin))
    f = pardiso.PardisoFactor(lower(A), "default", 2)
    assert not f.factorize(lower(A))
    assert f.factorize(lower(A), shift=2.0 * margin * lam)
    just_positive = lower(grid_laplacian(m, shift=-lam * (1.0 - margin)))
    assert pardiso.PardisoFactor(just_positive).factorize(just_positive)
    b = np.arange(A.shape[0], dtype=float)
    x = f.solve(b)
    shifted = A + 2.0 * margin * lam * sp.identity(A.shape[0])
    assert np.linalg.norm(shifted @ x - b) <= 1e-12 * sparse_norm(shifted) * np.linalg.norm(x)


def test_a_missing_diagonal_is_refused():
    A = lower(grid_laplacian(5)).tolil()
    A[3, 3] = 0.0
    A = A.tocsc()
    A.eliminate_zeros()
    with pytest.raises(ValueError, match="diagonal"):
        pardiso.PardisoFactor(A)


def test_cholesky_solver_uses_pardiso_and_factors_only_the_nonzeros():
    A = lower(grid_laplacian(30))
    s = linsolve.CholeskySolver(A)
    s.factorize(A)
    assert isinstance(s._factor, pardiso.PardisoFactor)
    B = A.copy()
    B.data[(B.indices != np.repeat(np.arange(B.shape[1]), np.diff(B.indptr))) & (np.arange(B.nnz) % 3 == 0)] = 0.0
    s.restart()  # a new step: analysed anew for its nonzeros
    s.factorize(B)
    full = (B + sp.tril(B, -1).T).toarray()
    b = np.ones(A.shape[0])
    assert np.allclose(full @ s.solve(b), b, atol=1e-10)
    assert s.n_analyses == 2


def test_an_empty_system():
    f = pardiso.PardisoFactor(sp.csc_matrix((0, 0)))
    assert f.factorize(sp.csc_matrix((0, 0)))
    assert f.solve(np.zeros(0)).shape == (0,)


def test_a_factor_alive_at_exit_is_freed_quietly():
    # A factor held in a reference cycle at exit is released by __del__ in the last
    # collection, after numpy can no longer import what `.ctypes` needs: it printed
    # "Exception ignored in ... __del__" at the end of every benchmark script.
    code = ("import numpy as np, scipy.sparse as sp\n"
            "from sim import pardiso\n"
            "A = sp.csc_matrix(sp.tril(sp.diags([4.0] * 5) + sp.eye(5, k=-1)))\n"
            "class Holder: pass\n"
            "h = Holder(); h.me = h; h.factor = pardiso.PardisoFactor(A)\n"
            "assert h.factor.factorize(A)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "Exception ignored" not in done.stderr, done.stderr
