"""The merged contact solve (sim/linsolve.py MergedSolver): F - diag(shift) + B for a fixed
lower pattern F and couplings B outside it, one symbolic analysis reused while the
couplings stay inside the pattern analysed."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from sim.linsolve import MergedSolver

N = 400


def _fixed(rng):
    """A banded SPD lower triangle (bandwidth 3), strongly diagonal."""
    A = sp.diags([rng.uniform(-1, 1, N - k) for k in range(4)], [0, -1, -2, -3], format="csc")
    A.setdiag(rng.uniform(20.0, 30.0, N))
    A.sort_indices()
    return A.tocsc()


def _couplings(rng, count):
    """Symmetric couplings, weak, between DOFs at least 10 apart (outside the band)."""
    i, j = rng.integers(0, N, (2, 2 * count))
    far = np.abs(i - j) >= 10
    i, j = i[far][:count], j[far][:count]
    B = sp.csr_matrix((rng.uniform(-0.5, 0.5, i.size), (np.maximum(i, j), np.minimum(i, j))), shape=(N, N))
    return (B + B.T).tocsr()


def _exact(F, shift, B):
    L = F - sp.diags(shift) + sp.tril(B)
    return (L + sp.tril(L, -1).T).toarray()


def _check(solver, F, shift, B, rng):
    b = rng.standard_normal(N)
    x = solver.solve(F, shift, B, b)
    return np.abs(_exact(F, shift, B) @ x - b).max()


def test_it_solves_the_merged_system_and_reuses_the_analysis_while_couplings_stay_inside():
    rng = np.random.default_rng(3)
    F = _fixed(rng)
    shift = rng.uniform(0.0, 1.0, N)
    B1 = _couplings(rng, 60)
    solver = MergedSolver()
    assert _check(solver, F, shift, B1, rng) < 1e-12
    assert (solver.analyses, solver.reuses) == (1, 0)
    # Fewer couplings, other values, another shift: the same analysis serves.
    kept = sp.triu(B1, 1).tocoo()
    sub = sp.csr_matrix((rng.uniform(-1, 1, 30), (kept.row[:30], kept.col[:30])), shape=(N, N))
    assert _check(solver, F, shift * 0.5, sub + sub.T, rng) < 1e-12
    assert (solver.analyses, solver.reuses) == (1, 1)
    # A new coupling: analysed again, joined with the ones before (within 10 % more
    # entries than in use) ...
    extra = sp.csr_matrix(([0.7], ([300], [200])), shape=(N, N))
    B2 = B1 + extra + extra.T
    assert _check(solver, F, shift, B2, rng) < 1e-12
    assert solver.analyses == 2
    assert _check(solver, F, shift, B1, rng) < 1e-12  # ... so the first set reuses it
    assert (solver.analyses, solver.reuses) == (2, 2)
    # Many couplings, then as many others: the join would be mostly stale, so the second
    # set is analysed alone.
    for count, B in enumerate((_couplings(rng, 3000), _couplings(rng, 3000)), start=3):
        assert _check(solver, F, shift, B, rng) < 1e-12
        assert solver.analyses == count
    assert solver._keys.size == sp.tril(B, -1).nnz


def test_a_coupling_on_the_diagonal_adds_to_it_and_an_indefinite_system_can_be_refused():
    rng = np.random.default_rng(4)
    F = _fixed(rng)
    B = _couplings(rng, 40) + sp.csr_matrix(([2.0], ([7], [7])), shape=(N, N))
    solver = MergedSolver()
    assert _check(solver, F, np.zeros(N), B, rng) < 1e-12
    b = np.ones(N)
    shift = np.zeros(N)
    shift[5] = F.diagonal()[5] + 1.0  # one negative pivot
    assert solver.solve(F, shift, B, b, allow_shift=False) is None
    x = solver.solve(F, shift, B, b)  # shifted until it factors
    assert np.all(np.isfinite(x)) and solver.analyses == 1
