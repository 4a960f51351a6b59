"""The elastic drawstring (sim/energies/drawstring.py): derivatives against finite
differences, slack segments carry nothing, and the rest length moves over its window."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from sim.assembly import BlockPattern
from sim.energies.drawstring import DrawstringEnergy
from tests.support.fd import fd_gradient, fd_hessian, gradient, hessian, relerr

N_CP = 14


def band(rest_ratio: float, seed: int = 0):
    """A drawstring of 6 segments over random combinations of N_CP control points, its
    rest lengths rest_ratio x their lengths at C (segment 0 slack whatever the ratio)."""
    rng = np.random.default_rng(seed)
    G = sp.random(6, N_CP, density=0.3, random_state=seed, format="csr")
    G = (G - sp.random(6, N_CP, density=0.2, random_state=seed + 1, format="csr")).tocsr()
    C = rng.normal(size=(N_CP, 3))
    e = DrawstringEnergy(N_CP, stiffness=40.0)
    rest = rest_ratio * np.linalg.norm(G @ C, axis=1)
    rest[0] = 1.5 * np.linalg.norm(G[0] @ C)
    e.draw(G, rest, rest, (0.0, 1.0))
    return e, C


def test_drawstring_derivatives_match_finite_differences():
    e, C = band(0.7)
    assert relerr(gradient(e, C), fd_gradient(e, C)) < 1e-7
    H = e.hessian(C).toarray()
    assert relerr(H, fd_hessian(e, C)) < 1e-6
    assert np.linalg.eigvalsh(H).min() > -1e-9 * np.abs(H).max()  # PSD without projection


def test_the_assembled_hessian_is_the_free_block_and_off_pattern_couplings_stay_psd():
    e, C = band(0.8, seed=3)
    free = np.arange(N_CP)
    free[[2, 9]] = -1  # pinned
    free[free >= 0] = np.arange(N_CP - 2)
    keep = np.repeat(free >= 0, 3)
    full = BlockPattern.from_stencils(free, [np.arange(N_CP)[None]])
    e.bind(full)
    assert relerr(hessian(e, full, C), e.hessian(C).toarray()[np.ix_(keep, keep)]) < 1e-12
    sparse = BlockPattern.from_stencils(free, [])  # diagonal blocks only: everything moved
    e.bind(sparse)
    H = hessian(e, sparse, C)
    assert np.linalg.eigvalsh(H).min() > -1e-9 * np.abs(H).max()


def test_a_slack_band_carries_nothing():
    e, C = band(1.2)
    assert e.value(C) == 0.0 and not gradient(e, C).any() and e.hessian(C).nnz == 0
    assert DrawstringEnergy(N_CP).value(C) == 0.0  # not drawn: inactive


def test_the_tension_is_ea_times_the_strain():
    """One segment between two points 0.11 m apart, rest 0.1 m: tension 40 N x 10 %."""
    e = DrawstringEnergy(2, stiffness=40.0)
    e.draw(sp.csr_matrix([[-1.0, 1.0]]), [0.1], [0.1], (0.0, 1.0))
    C = np.array([[0.0, 0.0, 0.0], [0.11, 0.0, 0.0]])
    assert gradient(e, C)[1, 0] == pytest.approx(40.0 * 0.1, rel=1e-12)


def test_the_rest_length_moves_over_its_window():
    e = DrawstringEnergy(2)
    e.draw(sp.csr_matrix([[-1.0, 1.0]]), [0.3], [0.1], (1.0, 1.5))
    for t, want in ((0.5, 0.3), (1.0, 0.3), (1.25, 0.2), (1.5, 0.1), (9.0, 0.1)):
        e.set_time(t)
        assert e.rest[0] == pytest.approx(want, rel=1e-12)
