"""Energies (sim/energies/*): gradients and Hessians against finite differences, assembly
into the block pattern (with pinned points), PSD projection, invariance under rigid
motions and closed-form values for homogeneous deformations."""

from __future__ import annotations

import numpy as np
import pytest

from sim.materials import Material
from sim.patches import Patch
from sim.assembly import deformation_gradients
from sim.energies import (BendingEnergy, ExternalForceEnergy, InertiaEnergy, MembraneFBW,
                          MembraneStVK)
from sim.energies.base import projection_code
from sim.energies.membrane_fbw import fbw_density
from sim.energies.membrane_stvk import stvk_density
from sim.quadrature import gauss, membrane_rule, span_centres
from sim.rest import point_data

from tests.support.fd import bound, central, dofs, fd_gradient, fd_hessian, gradient, hessian, relerr, unit

SHAPE = (6, 7)
SIZE = (0.6, 0.5)
N_CP = SHAPE[0] * SHAPE[1]
MAT = Material()


def rest_net(kind: str) -> np.ndarray:
    X = Patch.rectangle("r", SIZE, SHAPE).rest.copy()
    if kind == "warped":  # curved, injective rest net
        x, y = X[..., 0].copy(), X[..., 1].copy()
        X[..., 0] = x + 0.04 * np.sin(2.0 * y / SIZE[1]) * np.sin(np.pi * x / SIZE[0])
        X[..., 1] = y + 0.04 * np.sin(3.0 * x / SIZE[0])
    return X


def placed(X: np.ndarray) -> np.ndarray:
    """The rest net laid flat in world space (z = 0), as (n_cp, 3)."""
    return np.concatenate([X.reshape(-1, 2), np.zeros((X.shape[0] * X.shape[1], 1))], axis=1)


def random_rotation(rng) -> np.ndarray:
    Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q if np.linalg.det(Q) > 0 else -Q


def make_energy(name: str, X: np.ndarray, shear_factor: float = 1.0):
    if name.startswith("fbw") or name.startswith("stvk"):
        model, rule = name.split("-")
        pd = point_data(X, membrane_rule(rule, *SHAPE))
        if model == "fbw":
            params = (MAT.h * MAT.k_st, MAT.h * MAT.k_sh * shear_factor)
            cls = MembraneFBW
        else:
            mu, lam = MAT.lame
            params = (MAT.h * mu, MAT.h * lam)
            cls = MembraneStVK
        return cls(pd, np.tile(params, (pd.n_points, 1)), N_CP)
    if name == "bending":
        pd = point_data(X, span_centres(*SHAPE), second_order=True)
        # Cotton's D is tiny; scale it so FD noise does not dominate (the test is relative).
        return BendingEnergy(pd, np.full(pd.n_points, 1e3 * MAT.bending_stiffness), N_CP)
    rng = np.random.default_rng(7)
    if name == "inertia":
        pd = point_data(X, gauss(*SHAPE, 3))
        ok = pd.idx >= 0
        mass = np.bincount(pd.idx[ok], (pd.N * pd.w[:, None])[ok], minlength=N_CP) * MAT.areal_density
        e = InertiaEnergy(mass, 0.01)
        e.target = placed(X) + 0.03 * rng.standard_normal((N_CP, 3))
        return e
    if name == "external":
        return ExternalForceEnergy(rng.standard_normal((N_CP, 3)))
    raise KeyError(name)


def states(X, rng, kinds=("random", "compressed", "sheared")):
    """Deformed world states around the flat placement of X, rotated into 3D."""
    R = random_rotation(rng)
    W = placed(X)
    out = []
    for kind in kinds:
        C = W.copy()
        if kind == "compressed":
            C *= 0.7
        elif kind == "sheared":  # I6 of both signs: shear one half one way, the other half the other
            y = C[:, 1] - C[:, 1].mean()
            C[:, 0] += 0.4 * y * np.sign(C[:, 0] - C[:, 0].mean())
        noise = 0.05 if kind == "random" else 0.01  # keep the designed strain visible
        out.append(C @ R.T + noise * rng.standard_normal(C.shape) + rng.standard_normal(3))
    return out


ELASTIC = ("fbw-reduced", "fbw-gauss2", "stvk-reduced", "stvk-gauss2", "bending")


# ------------------------------------------------------------------ derivatives vs finite differences


@pytest.mark.parametrize("rest", ("rectangle", "warped"))
@pytest.mark.parametrize("name", ELASTIC + ("fbw_stiff_shear-reduced", "inertia", "external"))
def test_derivatives_match_finite_differences(name, rest):
    X = rest_net(rest)
    stiff = name.startswith("fbw_stiff_shear")
    e = make_energy(name.replace("fbw_stiff_shear", "fbw"), X, shear_factor=200.0 if stiff else 1.0)
    pattern = bound(e, N_CP)
    rng = np.random.default_rng(3)
    kinds = ("random", "compressed", "sheared") if rest == "rectangle" else ("random",)
    for C in states(X, rng, kinds):
        g = gradient(e, C)
        assert np.abs(g).max() > 0
        assert relerr(g, fd_gradient(e, C)) < 1e-5
        H = hessian(e, pattern, C)
        if name == "external":
            assert not H.any()
            continue
        assert relerr(H, fd_hessian(e, C)) < 1e-5
        assert np.abs(H - H.T).max() == 0.0


def test_sheared_state_has_both_signs_of_I6():
    X = rest_net("rectangle")
    pd = point_data(X, membrane_rule("reduced", *SHAPE))
    C = states(X, np.random.default_rng(3), ("sheared",))[0]
    F = np.zeros((pd.n_points, 3, 2))
    deformation_gradients(C, pd.idx, pd.g, F)
    I6 = np.einsum("qd,qd->q", F[:, :, 0], F[:, :, 1])
    assert (I6 > 0.05).sum() > 10 and (I6 < -0.05).sum() > 10
    # The compressed state really is compressed at most points.
    C = states(X, np.random.default_rng(3), ("compressed",))[0]
    deformation_gradients(C, pd.idx, pd.g, F)
    assert (np.linalg.norm(F, axis=1) < 1.0).mean() > 0.8


@pytest.mark.parametrize("name", ("fbw-reduced", "stvk-gauss2", "bending", "inertia"))
def test_pinned_assembly_is_restricted_hessian(name):
    """With pinned points, the assembled matrix is the full Hessian on the free DOFs."""
    X = rest_net("warped")
    e = make_energy(name, X, shear_factor=50.0)
    pinned = np.zeros(N_CP, bool)
    pinned[:SHAPE[1]] = True  # the side u0
    pinned[[17, 30, N_CP - 1]] = True
    free = -np.ones(N_CP, np.int64)
    free[~pinned] = np.arange((~pinned).sum())
    pattern = bound(e, free)
    assert pattern.n_free == (~pinned).sum()
    C = states(X, np.random.default_rng(5), ("random",))[0]
    H = hessian(e, pattern, C)
    free_dofs = dofs(np.flatnonzero(~pinned))
    Hfd = fd_hessian(e, C)[np.ix_(free_dofs, free_dofs)]
    assert H.shape == Hfd.shape
    assert relerr(H, Hfd) < 1e-5
    # Forces on pinned points are still reported (reaction forces).
    g = gradient(e, C)
    assert np.abs(g[pinned]).max() > 1e-3 * np.abs(g).max()
    assert relerr(g, fd_gradient(e, C)) < 1e-5


# ------------------------------------------------------------------ projection


@pytest.mark.parametrize("projection", ("clamp", "abs"))
@pytest.mark.parametrize("name", ("fbw-reduced", "fbw-gauss2", "stvk-reduced", "stvk-gauss2"))
def test_projected_hessian_is_psd(name, projection):
    X = rest_net("rectangle")
    e = make_energy(name, X, shear_factor=50.0)
    pattern = bound(e, N_CP)
    for C in states(X, np.random.default_rng(11), ("compressed", "sheared")):
        raw = np.linalg.eigvalsh(hessian(e, pattern, C, project=False))
        proj = np.linalg.eigvalsh(hessian(e, pattern, C, project=projection))
        scale = np.abs(raw).max()
        assert raw.min() < -1e-3 * scale  # the state really is indefinite ...
        assert proj.min() >= -1e-10 * scale  # ... and projection fixed it
        # Projection only removes negative curvature: it never lowers the largest mode
        # by much, and it keeps the matrix non-trivial.
        assert proj.max() > 0.5 * raw.max()


def eigen_fixed(H, projection):
    """H with its negative eigenvalues clamped to 0 or flipped (`projection`), numerically."""
    lam, V = np.linalg.eigh(H)
    return (V * (np.maximum(lam, 0.0) if projection == "clamp" else np.abs(lam))) @ V.T


def per_term_projected(F, kst, ksh, projection):
    """Sum of the eigen-fixed exact Hessians of the three FBW terms."""
    f1, f2 = F[:, 0], F[:, 1]
    H = np.zeros((6, 6))
    for off, f in ((0, f1), (3, f2)):
        l = np.linalg.norm(f)
        nn = np.outer(f, f) / l**2
        H[off:off + 3, off:off + 3] += eigen_fixed(2 * kst * (nn + (1 - 1 / l) * (np.eye(3) - nn)), projection)
    g = np.concatenate([f2, f1])
    S = np.block([[np.zeros((3, 3)), np.eye(3)], [np.eye(3), np.zeros((3, 3))]])
    H += eigen_fixed(2 * ksh * (np.outer(g, g) + (f1 @ f2) * S), projection)
    return H


def fbw_point_Fs(rng):
    Fs = [rng.standard_normal((3, 2)) * s for s in (0.3, 0.7, 1.0, 1.5) for _ in range(6)]
    a, b = rng.standard_normal(3), rng.standard_normal(3)
    b -= (a @ b) / (a @ a) * a
    Fs += [
        np.c_[a, a],  # f1 = f2: the -1 space part of g vanishes
        np.c_[a, -a],  # f1 = -f2: the +1 space part vanishes
        np.c_[a, b],  # I6 = 0
        np.c_[0.5 * a / np.linalg.norm(a), 2.0 * b / np.linalg.norm(b)],  # one compressed, one stretched
        np.c_[[1.0, 0, 0], [0.0, 1.0, 0]],  # rest
    ]
    return np.array(Fs)


@pytest.mark.parametrize("projection", ("clamp", "abs"))
def test_fbw_analytic_projection_equals_per_term_eigen_fix(projection):
    rng = np.random.default_rng(2)
    F = fbw_point_Fs(rng)
    Q = F.shape[0]
    params = np.tile([3.0, 0.7], (Q, 1))
    psi, P, H = np.zeros(Q), np.zeros((Q, 3, 2)), np.zeros((Q, 6, 6))
    fbw_density(np.ascontiguousarray(F), params, projection_code(projection), psi, P, H)
    for q in range(Q):
        ref = per_term_projected(F[q], 3.0, 0.7, projection)
        assert np.abs(H[q] - ref).max() < 1e-8 * max(1.0, np.abs(ref).max()), q
        assert np.linalg.eigvalsh(H[q]).min() > -1e-10 * np.abs(H[q]).max()
    # Unprojected, the kernel returns the exact Hessian (checked against the same algebra).
    fbw_density(np.ascontiguousarray(F), params, 0, psi, P, H)
    for q in range(Q):
        f1, f2 = F[q, :, 0], F[q, :, 1]
        expect = 3.0 * ((np.linalg.norm(f1) - 1) ** 2 + (np.linalg.norm(f2) - 1) ** 2) + 0.7 * (f1 @ f2) ** 2
        assert psi[q] == pytest.approx(expect, rel=1e-13, abs=1e-15)


@pytest.mark.parametrize("kernel", ("fbw", "stvk"))
def test_density_derivatives_match_finite_differences(kernel):
    """Per-point P = dPsi/dF and H = d2Psi/dF2 (layout [F e1; F e2]) against FD."""
    rng = np.random.default_rng(4)
    F = fbw_point_Fs(rng)[:-1]  # skip the exact rest state (nothing to compare at zero)
    Q = F.shape[0]
    density = fbw_density if kernel == "fbw" else stvk_density
    params = np.tile([3.0, 0.7], (Q, 1))

    def run(Fx):
        psi, P, H = np.zeros(Q), np.zeros((Q, 3, 2)), np.zeros((Q, 6, 6))
        density(np.ascontiguousarray(Fx), params, 0, psi, P, H)
        return psi, P, H

    psi, P, H = run(F)
    eps = 1e-6
    for c in range(2):
        for d in range(3):
            dF = unit(F, np.s_[:, d, c])  # F[:, d, c] of every point at once
            dP = central(lambda Fx: run(Fx)[0], F, dF, eps)
            assert np.abs(P[:, d, c] - dP).max() < 1e-6 * np.abs(P).max()
            dH = central(lambda Fx: run(Fx)[1], F, dF, eps).transpose(0, 2, 1).reshape(Q, 6)  # column-stacked
            assert np.abs(H[:, :, 3 * c + d] - dH).max() < 1e-6 * np.abs(H).max()


# ------------------------------------------------------------------ invariances


@pytest.mark.parametrize("rest", ("rectangle", "warped"))
@pytest.mark.parametrize("name", ELASTIC)
def test_rigid_motions_carry_no_energy(name, rest):
    X = rest_net(rest)
    e = make_energy(name, X)
    bound(e, N_CP)
    rng = np.random.default_rng(9)
    deformed = states(X, rng, ("random",))[0]
    E_ref = e.value(deformed)
    g_ref = np.abs(gradient(e, deformed)).max()
    assert E_ref > 0
    for _ in range(2):
        C = placed(X) @ random_rotation(rng).T + rng.standard_normal(3)
        assert abs(e.value(C)) < 1e-12 * E_ref
        assert np.abs(gradient(e, C)).max() < 1e-9 * g_ref
    # Translation and rotation invariance at a deformed state: no net force or torque.
    g = gradient(e, deformed)
    assert np.abs(g.sum(axis=0)).max() < 1e-10 * np.abs(g).sum()
    torque = np.cross(deformed, g).sum(axis=0)
    assert np.abs(torque).max() < 1e-10 * (np.abs(g).sum() * np.abs(deformed).max())


def test_bending_hessian_is_constant_and_psd():
    X = rest_net("warped")
    e = make_energy("bending", X)
    pattern = bound(e, N_CP)
    C1, C2 = states(X, np.random.default_rng(1), ("random", "compressed"))
    H1, H2 = hessian(e, pattern, C1), hessian(e, pattern, C2)
    assert np.array_equal(H1, H2)
    lam = np.linalg.eigvalsh(H1)
    assert lam.min() > -1e-10 * lam.max()
    # One Laplacian per span centre: rank 3 Q (the rows lap_q are independent), so the
    # null space (which holds the 9 affine maps) has dimension 3 (n_cp - Q).
    Q = e.points.n_points
    assert (lam < 1e-9 * lam.max()).sum() == 3 * (N_CP - Q)


# ------------------------------------------------------------------ closed-form values


@pytest.mark.parametrize("rule", ("reduced", "gauss2"))
def test_membrane_values_for_homogeneous_deformations(rule):
    X = rest_net("rectangle")
    W = placed(X)
    area = SIZE[0] * SIZE[1]
    fbw = make_energy(f"fbw-{rule}", X, shear_factor=3.0)
    stvk = make_energy(f"stvk-{rule}", X)
    kst, ksh = MAT.h * MAT.k_st, 3.0 * MAT.h * MAT.k_sh
    mu, lam = (MAT.h * c for c in MAT.lame)
    # Uniaxial stretch by s along x.
    s = 1.2
    C = W * [s, 1.0, 1.0]
    assert fbw.value(C) == pytest.approx(kst * (s - 1) ** 2 * area, rel=1e-12)
    G = (s * s - 1) / 2
    assert stvk.value(C) == pytest.approx((mu * G**2 + 0.5 * lam * G**2) * area, rel=1e-12)
    # Simple shear x += gamma y: f1 = e1, f2 = (gamma, 1, 0).
    gamma = 0.3
    C = W.copy()
    C[:, 0] += gamma * W[:, 1]
    expect = (kst * (np.sqrt(1 + gamma**2) - 1) ** 2 + ksh * gamma**2) * area
    assert fbw.value(C) == pytest.approx(expect, rel=1e-12)
    G = np.array([[0.0, gamma / 2], [gamma / 2, gamma**2 / 2]])
    expect = (mu * np.sum(G * G) + 0.5 * lam * np.trace(G) ** 2) * area
    assert stvk.value(C) == pytest.approx(expect, rel=1e-12)


def test_bending_value_for_parabolic_bump():
    """z = x^2 (exactly representable on the rectangle) has Laplacian 2: E = 2 D area."""
    X = rest_net("rectangle")
    n, m = SHAPE
    D = 0.37
    pd = point_data(X, span_centres(n, m), second_order=True)
    e = BendingEnergy(pd, np.full(pd.n_points, D), N_CP)
    sx = SIZE[0] / (n - 2)
    t = np.array([min(max(j - 2, 0), n - 2) for j in range(n + 3)], float)
    cz = sx**2 * t[1:n + 1] * t[2:n + 2]  # blossom of (sx u)^2
    C = placed(X)
    C[:, 2] = np.repeat(cz, m)
    assert e.value(C) == pytest.approx(2.0 * D * SIZE[0] * SIZE[1], rel=1e-12)
