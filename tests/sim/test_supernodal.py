"""The ctypes CHOLMOD binding (sim/supernodal.py) and the solvers built on it."""

import numpy as np
import pytest
import scipy.sparse as sp

from sim import linsolve, supernodal


def grid_laplacian(m: int, shift: float = 0.1) -> sp.csc_matrix:
    """A 2D grid Laplacian plus shift I: SPD, with the fill pattern of a cloth."""
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
    I = sp.identity(m)
    return (sp.kron(T, I) + sp.kron(I, T) + shift * sp.identity(m * m)).tocsc()


def lower(A):
    return sp.tril(A).tocsc()


def test_binding_recognises_the_installed_cholmod():
    # The Makefile installs Debian's CHOLMOD 3: the mirrored layout must match it,
    # or every factorization silently falls back to scikit-sparse.
    assert supernodal.available()


@pytest.mark.parametrize("ordering", ["default", "amd", "metis", "natural"])
def test_solve_matches_dense(ordering):
    A = grid_laplacian(30)
    b = np.random.default_rng(1).standard_normal(A.shape[0])
    f = supernodal.RelaxedFactor(lower(A), ordering)
    assert f.factorize(lower(A))
    x = f.solve(b)
    assert np.linalg.norm(A @ x - b) <= 1e-12 * np.linalg.norm(b) * 1e3
    assert np.allclose(x, np.linalg.solve(A.toarray(), b), rtol=1e-10, atol=1e-12)


def test_refactor_same_pattern_new_values():
    A = grid_laplacian(20)
    f = supernodal.RelaxedFactor(lower(A))
    b = np.ones(A.shape[0])
    for scale in (1.0, 3.0):
        B = lower(A).copy()
        B.data *= scale
        assert f.factorize(B)
        assert np.allclose(A @ f.solve(b) * scale, b, atol=1e-10)


def test_not_positive_definite_and_shift():
    A = grid_laplacian(15, shift=-0.5)  # smallest eigenvalue about -0.4
    f = supernodal.RelaxedFactor(lower(A))
    assert not f.factorize(lower(A))
    assert f.factorize(lower(A), shift=1.0)
    b = np.arange(A.shape[0], dtype=float)
    x = f.solve(b)
    assert np.allclose((A + sp.identity(A.shape[0])) @ x, b, atol=1e-9)


def test_relaxation_merges_supernodes():
    A = lower(grid_laplacian(60))
    relaxed = supernodal.RelaxedFactor(A, "amd")
    head = supernodal._CommonHead.from_buffer(supernodal._LIB[1])
    try:
        supernodal._set_relaxation(head, (4, 16, 48), (0.8, 0.1, 0.05))  # CHOLMOD's defaults
        plain = supernodal.RelaxedFactor(A, "amd")
    finally:
        supernodal._set_relaxation(head, supernodal.NRELAX, supernodal.ZRELAX)
    assert relaxed.supernodes < 0.8 * plain.supernodes
    assert plain.stored < relaxed.stored < 3 * plain.stored  # explicit zeros, bounded by zrelax


def test_cholesky_solver_paths_agree():
    A = grid_laplacian(25)
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    fallback = linsolve._ScikitFactor(lower(A), "amd")
    assert fallback.factorize(lower(A), 0.0)
    x = linsolve.solve_once(lower(A), b)
    assert np.allclose(x, fallback.solve(b), rtol=1e-10, atol=1e-12)


def test_solve_once_without_shift_reports_indefinite():
    A = grid_laplacian(10, shift=-0.5)
    assert linsolve.solve_once(lower(A), np.ones(A.shape[0]), allow_shift=False) is None
    shifted = linsolve.CholeskySolver(lower(A))
    assert shifted.factorize(lower(A)) > 0.0
