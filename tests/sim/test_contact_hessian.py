"""The parallel contact-Hessian mapping equals the scipy path W3^T H W3 + add_dof_matrix."""

from __future__ import annotations

import ipctk
import numpy as np
import pytest
import scipy.sparse as sp

from garment.scene import loads_scene
from sim.assembly import BlockPattern, add_dof_matrix
from sim.contact.hessian_map import ContactHessianMap, _sum_entries
from garment.build import build_simulator

from tests.support.fd import dofs, relerr
from tests.support.scenes import DROP


@pytest.fixture(scope="module")
def sim():
    return build_simulator(loads_scene(DROP.format(height=0.1605)))


def reference(W, pattern, H, n_cloth):
    """The current path: W3^T H_cloth W3 restricted to free DOFs, then add_dof_matrix."""
    n = 3 * n_cloth
    W3 = sp.kron(W, sp.identity(3), format="csr")
    HC = (W3.T @ H.tocsc()[:n, :n] @ W3).tocsr()
    free = dofs(np.flatnonzero(pattern.free >= 0))
    S = sp.csr_matrix((np.ones(free.size), (np.arange(free.size), free)), shape=(free.size, HC.shape[0]))
    data = np.zeros(pattern.nnz)
    moved = add_dof_matrix(pattern, S @ HC @ S.T, data)
    return data, moved


def pinned_pattern(sim, every=7):
    """The barrier's pattern with every `every`-th control point pinned."""
    free = np.arange(sim.model.n_cp)
    free[::every] = -1
    ok = free >= 0
    free[ok] = np.arange(ok.sum())
    return BlockPattern.from_stencils(free, sim.model.barrier.stencils())


def synthetic_collisions(sim, n=300, seed=0):
    """Random PSD 12x12 Hessians on 4-vertex stencils: a cloth triangle's vertices plus a
    random vertex (often far away: off-pattern) or an obstacle vertex (ignored)."""
    rng = np.random.default_rng(seed)
    mesh = sim.model.barrier.contact
    V = mesh.mesh.num_vertices
    faces = mesh.cloth_faces[rng.integers(0, len(mesh.cloth_faces), n)]
    other = np.where(rng.random(n) < 0.7, rng.integers(0, mesh.n_cloth, n), rng.integers(mesh.n_cloth, V, n))
    ids = np.c_[faces, other].astype(np.int64)
    ids[ids[:, 3] == ids[:, 0], 3] = -1  # padding slot
    A = rng.standard_normal((n, 12, 12))
    hess = A @ A.transpose(0, 2, 1)
    hess[ids[:, 3] < 0, 9:, :] = 0.0
    hess[ids[:, 3] < 0, :, 9:] = 0.0
    rows, cols, vals = [], [], []
    for k in range(n):
        dof = (3 * ids[k, :, None] + np.arange(3)).ravel()
        ok = np.repeat(ids[k] >= 0, 3)
        R, Cc = np.meshgrid(dof[ok], dof[ok], indexing="ij")
        rows.append(R.ravel())
        cols.append(Cc.ravel())
        vals.append(hess[k][np.ix_(ok, ok)].ravel())
    H = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * V, 3 * V))
    return H, hess, ids


def test_synthetic_far_pairs_and_pins_match_reference(sim):
    pattern = pinned_pattern(sim)
    W = sim.model.barrier.contact.W
    H, hess, ids = synthetic_collisions(sim)
    ref, ref_moved = reference(W, pattern, H, sim.model.barrier.contact.n_cloth)
    assert ref_moved > 0  # the case exercises off-pattern pairs
    cmap = ContactHessianMap(W, pattern)
    assert cmap.n_colors <= 16
    for mat in (H, H.tocsr()):
        data = np.zeros(pattern.nnz)
        moved = cmap.add(mat, data)
        assert relerr(data, ref) < 1e-12
        assert moved == ref_moved
    data = np.zeros(pattern.nnz)
    assert cmap.add_local(hess, ids, data) == ref_moved
    assert relerr(data, ref) < 1e-12
    # PSD in, PSD out (moved entries keep it so).
    eig = np.linalg.eigvalsh(pattern.full(data).toarray())
    assert eig.min() > -1e-10 * eig.max()
    # The moved couplings and the diagonal they went to restore the exact W^T H W.
    r, c, v = cmap.off_pattern
    assert np.all(r > c) and np.count_nonzero(v) == ref_moved
    B = sp.csr_matrix((v, (r, c)), shape=(pattern.n_dofs, pattern.n_dofs))
    exact = pattern.full(data) - sp.diags(cmap.shift) + B + B.T
    n = 3 * sim.model.barrier.contact.n_cloth
    W3 = sp.kron(W, sp.identity(3), format="csr")
    free = dofs(np.flatnonzero(pattern.free >= 0))
    want = (W3.T @ H.tocsc()[:n, :n] @ W3)[free][:, free]
    assert relerr(exact.toarray(), want.toarray()) < 1e-12


def test_adds_into_existing_data(sim):
    pattern = pinned_pattern(sim, every=5)
    W = sim.model.barrier.contact.W
    H, _, _ = synthetic_collisions(sim, n=50, seed=3)
    base = np.random.default_rng(1).standard_normal(pattern.nnz)
    ref, _ = reference(W, pattern, H, sim.model.barrier.contact.n_cloth)
    data = base.copy()
    ContactHessianMap(W, pattern).add(H, data)
    assert relerr(data, base + ref) < 1e-12


def test_ipctk_barrier_hessian_matches_reference(sim):
    """A real contact state (the sheet on the ball) on the simulator's own pattern."""
    e = sim.model.barrier
    x = e._update(sim.C)
    assert len(e.collisions) > 0
    H = e.potential.hessian(e.collisions, e.contact.mesh, x, ipctk.PSDProjectionMethod.CLAMP)
    pattern = sim.model.potential.pattern
    ref, ref_moved = reference(e.contact.W, pattern, H, e.contact.n_cloth)
    data = np.zeros(pattern.nnz)
    moved = ContactHessianMap(e.contact.W, pattern).add(H, data)
    assert moved == ref_moved == 0
    assert relerr(data, ref) < 1e-12


def test_sum_entries_sums_each_entry_once():
    rng = np.random.default_rng(4)
    r, c = rng.integers(0, 30, 2000), rng.integers(0, 30, 2000)
    v = rng.standard_normal(2000)
    indptr, cols, vals = _sum_entries(r, c, v, 40)
    rows = np.repeat(np.arange(40), np.diff(indptr))
    assert len(set(zip(rows, cols))) == cols.size  # no entry twice
    want = np.zeros((40, 40))
    np.add.at(want, (r, c), v)
    got = np.zeros((40, 40))
    got[rows, cols] = vals
    assert np.abs(got - want).max() < 1e-12 and indptr[-1] == np.count_nonzero(want)
