"""Quadratic B-spline basis (sim/bspline.py) and the second-order point data built on it
(sim/rest.py): partition of unity, derivatives, the knot-average convention for N'',
linear precision and the Laplacian of affine / quadratic maps (docs/design.md section 2)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.patches import Patch
from sim.bspline import basis_matrix, knots
from sim.quadrature import reduced_membrane, span_centres
from sim.rest import point_data

from tests.support.fd import central, second_central

SIZES = (3, 4, 5, 9)


def dense_with_knots(n: int, per_span: int = 37) -> np.ndarray:
    """A dense sample of [0, n-2] that contains every knot exactly."""
    u = np.linspace(0.0, n - 2.0, per_span * (n - 2) + 1)
    u = np.concatenate([u, np.arange(n - 1, dtype=float)])
    return np.unique(u)


def off_knot_points(n: int, rng) -> np.ndarray:
    """Random points at least 0.05 away from every knot."""
    spans = rng.integers(0, n - 2, 40)
    return spans + rng.uniform(0.05, 0.95, 40)


def blossom_u2(n: int) -> np.ndarray:
    """Control values of f(u) = u^2: the blossom t_{i+1} t_{i+2} of N_i (support [t_i, t_{i+3}])."""
    t = knots(n)
    return t[1:n + 1] * t[2:n + 2]


# ------------------------------------------------------------------ 1D basis


def test_knot_vector_and_greville():
    assert np.array_equal(knots(5), [0, 0, 0, 1, 2, 3, 3, 3])
    assert np.array_equal(knots(3), [0, 0, 0, 1, 1, 1])
    t = knots(9)
    greville = 0.5 * (t[1:10] + t[2:11])
    assert np.array_equal(greville, Patch.greville(9))


@pytest.mark.parametrize("n", SIZES)
def test_partition_of_unity_and_derivative_sums(n):
    u = dense_with_knots(n)
    N0, N1, N2 = (basis_matrix(u, n, d) for d in range(3))
    assert np.abs(N0.sum(axis=1) - 1.0).max() < 1e-14
    assert N0.min() >= 0.0
    assert np.abs(N1.sum(axis=1)).max() < 1e-13
    assert np.abs(N2.sum(axis=1)).max() < 1e-13
    # Exactly at every interior knot as well (the knot-average convention).
    k = np.arange(1, n - 2, dtype=float)
    if k.size:
        assert np.abs(basis_matrix(k, n, 2).sum(axis=1)).max() < 1e-14
        assert np.abs(basis_matrix(k, n, 1).sum(axis=1)).max() < 1e-14


@pytest.mark.parametrize("n", SIZES)
def test_support_and_continuity(n):
    """N_i vanishes outside [t_i, t_{i+3}]; N and N' are continuous across knots."""
    u = dense_with_knots(n)
    N0 = basis_matrix(u, n, 0)
    t = knots(n)
    for i in range(n):
        outside = (u < t[i]) | (u > t[i + 3])
        assert np.all(N0[outside, i] == 0.0)
    k = np.arange(1, n - 2, dtype=float)
    if k.size:
        for d in (0, 1):
            left = basis_matrix(k - 1e-10, n, d)
            right = basis_matrix(k + 1e-10, n, d)
            mid = basis_matrix(k, n, d)
            assert np.abs(left - mid).max() < 1e-8
            assert np.abs(right - mid).max() < 1e-8


@pytest.mark.parametrize("n", SIZES)
def test_derivatives_match_finite_differences(n):
    rng = np.random.default_rng(n)
    u = off_knot_points(n, rng)
    h = 1e-5
    N1 = basis_matrix(u, n, 1)
    N2 = basis_matrix(u, n, 2)
    du = np.ones_like(u)  # row k of basis_matrix depends on u[k] only

    def basis(d):
        return lambda u: basis_matrix(u, n, d)

    fd1 = central(basis(0), u, du, h)
    fd2 = central(basis(1), u, du, h)
    assert np.abs(N1 - fd1).max() / np.abs(N1).max() < 1e-6
    assert np.abs(N2 - fd2).max() / np.abs(N2).max() < 1e-4
    # And the second derivative against a second difference of the values.
    fd2b = second_central(basis(0), u, du, h)
    assert np.abs(N2 - fd2b).max() / np.abs(N2).max() < 1e-4


@pytest.mark.parametrize("n", (4, 5, 9))
def test_second_derivative_at_knot_is_average_of_limits(n):
    k = np.arange(1, n - 2, dtype=float)
    left = basis_matrix(k - 1e-9, n, 2)
    right = basis_matrix(k + 1e-9, n, 2)
    at = basis_matrix(k, n, 2)
    # N'' really jumps at interior knots, so the convention matters ...
    assert np.abs(left - right).max() > 0.5
    # ... and the value on the knot is the mean of the one-sided limits.
    assert np.abs(at - 0.5 * (left + right)).max() < 1e-12


def test_known_values():
    """Closed forms on n = 5 (knots 0 0 0 1 2 3 3 3)."""
    u = np.array([0.0, 0.5, 1.0, 1.5, 3.0])
    N = basis_matrix(u, 5, 0)
    expected = np.array([
        [1.0, 0.0, 0.0, 0.0, 0.0],
        [0.25, 0.625, 0.125, 0.0, 0.0],
        [0.0, 0.5, 0.5, 0.0, 0.0],
        [0.0, 0.125, 0.75, 0.125, 0.0],
        [0.0, 0.0, 0.0, 0.0, 1.0],
    ])
    assert np.abs(N - expected).max() < 1e-15
    # Uniform interior function N_2 on [0, 3]: N'' = 1, -2, 1 on its three spans.
    d2 = basis_matrix(np.array([1.5]), 5, 2)
    assert np.abs(d2 - [[0.0, 1.0, -2.0, 1.0, 0.0]]).max() < 1e-14


@pytest.mark.parametrize("n", SIZES)
def test_linear_precision(n):
    u = dense_with_knots(n)
    assert np.abs(basis_matrix(u, n, 0) @ Patch.greville(n) - u).max() < 1e-13
    assert np.abs(basis_matrix(u, n, 1) @ Patch.greville(n) - 1.0).max() < 1e-13
    assert np.abs(basis_matrix(u, n, 2) @ Patch.greville(n)).max() < 1e-13


@pytest.mark.parametrize("n", SIZES)
def test_quadratic_precision(n):
    """u^2 is in the spline space; N'' reproduces 2 everywhere, knots included."""
    u = dense_with_knots(n)
    c = blossom_u2(n)
    assert np.abs(basis_matrix(u, n, 0) @ c - u**2).max() < 1e-12
    assert np.abs(basis_matrix(u, n, 1) @ c - 2 * u).max() < 1e-12
    assert np.abs(basis_matrix(u, n, 2) @ c - 2.0).max() < 1e-12


# ------------------------------------------------------------------ Laplacian point data


def rectangle_rest(n, m, size=(0.7, 0.45)):
    return Patch.rectangle("r", size, (n, m)).rest


def warped_rest(n, m, size=(0.7, 0.45), amp=0.05):
    """A curved (non-affine) but injective rest net: smooth warp of a rectangle."""
    X = rectangle_rest(n, m, size).copy()
    x, y = X[..., 0].copy(), X[..., 1].copy()
    X[..., 0] = x + amp * np.sin(2.0 * y / size[1]) * np.sin(np.pi * x / size[0])
    X[..., 1] = y + amp * np.sin(3.0 * x / size[0])
    return X


def laplacian_of(pd, values):
    """sum_a lap[q, a] values[idx[q, a]] for values (n_cp, k)."""
    ok = pd.idx >= 0
    lap = np.where(ok, pd.lap, 0.0)
    return np.einsum("qa,qak->qk", lap, values[np.maximum(pd.idx, 0)])


def rules_with_knot_points(n, m):
    """Span centres (the bending rule) and the reduced rule, whose points sit on knots."""
    return {"span_centres": span_centres(n, m), "reduced": reduced_membrane(n, m)}


@pytest.mark.parametrize("rest", ("rectangle", "warped"))
@pytest.mark.parametrize("rule_name", ("span_centres", "reduced"))
def test_laplacian_of_affine_map_vanishes(rest, rule_name):
    n, m = 7, 6
    X = rectangle_rest(n, m) if rest == "rectangle" else warped_rest(n, m)
    rule = rules_with_knot_points(n, m)[rule_name]
    pd = point_data(X, rule, second_order=True)
    rng = np.random.default_rng(1)
    A = rng.standard_normal((3, 2))
    b = rng.standard_normal(3)
    C = X.reshape(-1, 2) @ A.T + b
    lap = laplacian_of(pd, C)
    # Scale: the size of individual terms, |lap| * |C|.
    scale = np.abs(np.where(pd.idx >= 0, pd.lap, 0.0)).sum(axis=1).max() * np.abs(C).max()
    assert scale > 1.0
    assert np.abs(lap).max() < 1e-9 * scale
    # The constant function has zero Laplacian even without the affine part.
    assert np.abs(laplacian_of(pd, np.ones((n * m, 1)))).max() < 1e-9 * scale


@pytest.mark.parametrize("rule_name", ("span_centres", "reduced"))
def test_laplacian_of_quadratic_on_rectangle(rule_name):
    """phi = x^2 + y^2 (exactly representable on an affine rest map) has Laplacian 4."""
    n, m = 7, 6
    W, H = 0.7, 0.45
    X = rectangle_rest(n, m, (W, H))
    sx, sy = W / (n - 2), H / (m - 2)  # x = sx u, y = sy v
    cx = sx**2 * blossom_u2(n)
    cy = sy**2 * blossom_u2(m)
    phi = (cx[:, None] + cy[None, :]).ravel()
    pd = point_data(X, rules_with_knot_points(n, m)[rule_name], second_order=True)
    lap = laplacian_of(pd, phi[:, None])[:, 0]
    assert np.abs(lap - 4.0).max() < 1e-9
    # phi = x y (also representable: control values x_i y_j) is harmonic.
    xy = np.outer(sx * Patch.greville(n), sy * Patch.greville(m)).ravel()
    assert np.abs(laplacian_of(pd, xy[:, None])).max() < 1e-9
    # phi = x^2 - y^2 is harmonic too.
    h = (cx[:, None] - cy[None, :]).ravel()
    assert np.abs(laplacian_of(pd, h[:, None])).max() < 1e-9


def test_bending_stencils():
    """Span-centre points touch 9 control points; points on a knot line (reduced rule)
    with second_order keep the functions that act only through the averaged N''."""
    n, m = 7, 6
    X = rectangle_rest(n, m)
    pd = point_data(X, span_centres(n, m), second_order=True)
    assert np.all((pd.idx >= 0).sum(axis=1) == 9)
    rule = reduced_membrane(n, m)
    pr = point_data(X, rule, second_order=True)
    on_u = (rule.u == np.round(rule.u)) & (rule.u > 0) & (rule.u < n - 2)
    on_v = (rule.v == np.round(rule.v)) & (rule.v > 0) & (rule.v < m - 2)
    count = (pr.idx >= 0).sum(axis=1)
    # 4 x 3 on a single knot line; on a knot (corner quarter cells) 4 x 4 minus the four
    # pairs of outer functions, which have N = N' = 0 in both directions (12 again).
    assert np.all(count[on_u & ~on_v] == 12)
    assert np.all(count[on_v & ~on_u] == 12)
    assert np.any(on_u & on_v)
    assert np.all(count[on_u & on_v] == 12)
    assert np.all(count[~on_u & ~on_v] == 9)
