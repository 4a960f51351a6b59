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


def test_only_the_nonzeros_are_factored_and_their_analysis_kept_while_they_stay_inside():
    # A pattern wider than its nonzeros (a contact stencil for every triangle, few
    # touching): the solver factors the nonzero part, keeps that analysis while later
    # nonzeros fall inside it, analyses anew when one falls outside, and at a step's
    # start (restart) whenever the nonzeros differ, so the result depends on the step's
    # matrices alone.
    m = 12
    A = grid_laplacian(m)
    wide = (A + sp.diags([1.0, 1.0], [-m - 1, m + 1], shape=A.shape)).tocsc()  # extra couplings
    pattern = lower(wide)
    pattern.sort_indices()
    rows, cols = pattern.indices, np.repeat(np.arange(A.shape[0]), np.diff(pattern.indptr))
    on_extra = rows - cols == m + 1  # the pattern entries of the couplings
    rng = np.random.default_rng(3)
    b = rng.standard_normal(A.shape[0])

    def matrix(coupled: np.ndarray) -> sp.csc_matrix:
        """The pattern with values of A, plus -0.2 on the couplings in `coupled` (zeros elsewhere)."""
        M = pattern.copy()
        M.data[:] = lower(A).toarray()[rows, cols]
        M.data[on_extra] = np.where(coupled, -0.2, 0.0)
        return M

    def full(M):
        return (M + M.T - sp.diags(M.diagonal())).toarray()

    n_extra = int(on_extra.sum())
    solver = linsolve.CholeskySolver(pattern)
    none = np.zeros(n_extra, bool)
    M = matrix(none)
    assert solver.factorize(M) == 0.0
    assert np.allclose(solver.solve(b), np.linalg.solve(full(M), b), rtol=1e-10, atol=1e-12)
    assert solver.n_analyses == 1 and solver._A.nnz == np.count_nonzero(lower(A).toarray())
    few = none.copy()
    few[:3] = True  # three couplings appear: outside the analysis, analysed anew (slack kept)
    M = matrix(few)
    solver.factorize(M)
    assert solver.n_analyses == 2
    assert np.allclose(solver.solve(b), np.linalg.solve(full(M), b), rtol=1e-10, atol=1e-12)
    fewer = none.copy()
    fewer[1] = True  # inside what was analysed: refactored only
    M = matrix(fewer)
    solver.factorize(M)
    assert solver.n_analyses == 2
    assert np.allclose(solver.solve(b), np.linalg.solve(full(M), b), rtol=1e-10, atol=1e-12)
    solver.restart()  # a new step: the nonzeros differ from the analysis, so analysed anew
    solver.factorize(M)
    assert solver.n_analyses == 3 and solver._A.nnz == np.count_nonzero(lower(A).toarray()) + 1
    solver.restart()  # the same nonzeros: the analysis is kept
    solver.factorize(M)
    assert solver.n_analyses == 3
    # Without contact (nonzeros=False) the whole pattern is factored and analysed once,
    # whatever its zeros, step starts included.
    whole = linsolve.CholeskySolver(pattern, nonzeros=False)
    for coupled in (none, few, fewer):
        M = matrix(coupled)
        whole.restart()
        whole.factorize(M)
        assert np.allclose(whole.solve(b), np.linalg.solve(full(M), b), rtol=1e-10, atol=1e-12)
    assert whole.n_analyses == 1 and whole.n_factorizations == 3


@pytest.mark.parametrize("nonzeros", [True, False])
def test_a_matrix_of_another_pattern_is_analysed_as_its_own(nonzeros):
    """scipy drops an entry that cancels to zero in a sum, so a Hessian built as a sum
    (conform/mips.py: MIPS plus boundary terms) can come one entry short of the pattern
    the solver was made with: solved as a new pattern, not a broadcast error."""
    A = lower(grid_laplacian(12))
    b = np.random.default_rng(4).standard_normal(A.shape[0])
    solver = linsolve.CholeskySolver(A, nonzeros=nonzeros)
    solver.factorize(A)
    short = A.tolil()
    short[13, 1] = 0.0  # an off-diagonal entry gone from the pattern
    short = short.tocsc()
    short.eliminate_zeros()
    assert short.nnz == A.nnz - 1
    solver.factorize(short)
    dense = (short + short.T - sp.diags(short.diagonal())).toarray()
    assert np.allclose(solver.solve(b), np.linalg.solve(dense, b), rtol=1e-10, atol=1e-12)
    assert solver.n_analyses == 2


def test_a_factor_freed_by_the_collector_inside_a_locked_call_does_not_deadlock():
    # The garbage collector runs __del__ wherever Python allocates, including between
    # the C calls of a locked section: freeing a factor there must not wait for itself.
    import gc
    import threading

    f = supernodal.RelaxedFactor(lower(grid_laplacian(10)))
    cycle = [f]
    cycle.append(cycle)
    del f, cycle
    done = threading.Event()

    def locked_collect():
        with supernodal._LOCK:
            gc.collect()
        done.set()

    threading.Thread(target=locked_collect, daemon=True).start()
    assert done.wait(10.0)
