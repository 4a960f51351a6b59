"""Quadrature rules (sim/quadrature.py) and their physical weights (sim/rest.py):
exactness on rectangles, the reduced rule's layout (docs/design.md section 3), stencil sizes
and the rest area of a curved patch."""

from __future__ import annotations

import numpy as np
import pytest

from sim.patches import Patch
from sim.bspline import basis_matrix
from sim.quadrature import gauss, membrane_rule, reduced_membrane, span_centres
from sim.rest import point_data

RULES = {
    "reduced": reduced_membrane,
    "gauss2": lambda n, m: gauss(n, m, 2),
    "gauss3": lambda n, m: gauss(n, m, 3),
    "span_centres": span_centres,
}
G = np.sqrt(1.0 / 3.0) / 2.0  # 2-point Gauss offset on a unit interval: 0.2887
G3 = np.sqrt(0.6) / 2.0  # 3-point Gauss offset on a unit interval: 0.3873


def interpolate(pd, values):
    """values (n_cp, k) interpolated at the points of pd: sum_a N[q, a] values[idx[q, a]]."""
    N = np.where(pd.idx >= 0, pd.N, 0.0)
    return np.einsum("qa,qak->qk", N, values[np.maximum(pd.idx, 0)])


# ------------------------------------------------------------------ exactness on rectangles


@pytest.mark.parametrize("shape", ((5, 5), (7, 9), (12, 6)))
@pytest.mark.parametrize("rule_name", tuple(RULES))
def test_rectangle_moments_are_exact(shape, rule_name):
    n, m = shape
    W, H = 0.9, 0.55
    patch = Patch.rectangle("r", (W, H), shape)
    rule = RULES[rule_name](n, m)
    pd = point_data(patch.rest, rule)
    # Parametric weights cover the domain; physical weights = parametric x |det|.
    assert abs(rule.w.sum() - (n - 2) * (m - 2)) < 1e-12 * (n - 2) * (m - 2)
    assert np.all(rule.w > 0)
    assert np.abs(pd.w - rule.w * pd.det).max() < 1e-15
    assert np.abs(pd.det - (W / (n - 2)) * (H / (m - 2))).max() < 1e-14
    # Points lie in the domain.
    assert rule.u.min() >= 0 and rule.u.max() <= n - 2 and rule.v.min() >= 0 and rule.v.max() <= m - 2
    X = interpolate(pd, patch.rest.reshape(-1, 2))
    x, y = X[:, 0], X[:, 1]
    area = W * H
    assert abs(pd.w.sum() - area) < 1e-12 * area
    assert abs(pd.w @ x - W**2 / 2 * H) < 1e-12 * W * area
    assert abs(pd.w @ y - H**2 / 2 * W) < 1e-12 * H * area
    # Every rule here is a tensor product of 1D rules exact for linear functions on each
    # cell, so the bilinear moment is exact as well.
    assert abs(pd.w @ (x * y) - W**2 * H**2 / 4) < 1e-12 * W * H * area
    # The interpolated points agree with the affine map X = (W u / (n-2), H v / (m-2)).
    assert np.abs(x - W * rule.u / (n - 2)).max() < 1e-14
    assert np.abs(y - H * rule.v / (m - 2)).max() < 1e-14


def test_interpolation_matches_basis_matrix():
    """PointData.N/idx agree with the tensor product of 1D basis matrices."""
    n, m = 7, 9
    rule = reduced_membrane(n, m)
    pd = point_data(Patch.rectangle("r", (1.0, 1.0), (n, m)).rest, rule)
    dense = np.einsum("qi,qj->qij", basis_matrix(rule.u, n), basis_matrix(rule.v, m)).reshape(len(rule), -1)
    mine = np.zeros_like(dense)
    rows = np.repeat(np.arange(len(rule)), pd.idx.shape[1])
    ok = pd.idx.ravel() >= 0
    np.add.at(mine, (rows[ok], pd.idx.ravel()[ok]), pd.N.ravel()[ok])
    assert np.abs(mine - dense).max() < 1e-15


# ------------------------------------------------------------------ reduced rule layout


def points_in(rule, u0, u1, v0, v1):
    """Indices of points strictly inside the open box (u0, u1) x (v0, v1)."""
    return np.flatnonzero((rule.u > u0) & (rule.u < u1) & (rule.v > v0) & (rule.v < v1))


def find(rule, u, v):
    hit = np.flatnonzero((np.abs(rule.u - u) < 1e-12) & (np.abs(rule.v - v) < 1e-12))
    assert hit.size == 1, f"expected one point at ({u}, {v}), found {hit.size}"
    return hit[0]


def test_reduced_layout_7x7():
    """docs/design.md section 3 on the figure's domain [0, 5]^2."""
    rule = reduced_membrane(7, 7)
    # Interior cell centred on knot (2, 2): single point in u on the knot, 2 Gauss in v.
    for v in (2 - G, 2 + G):
        assert rule.w[find(rule, 2.0, v)] == pytest.approx(0.5, abs=1e-15)
    # Checkerboard: the neighbouring cell (3, 2) is 2 x 1.
    for u in (3 - G, 3 + G):
        assert rule.w[find(rule, u, 2.0)] == pytest.approx(0.5, abs=1e-15)
    # Half cell on the interior region's left edge: points on the knot line u = 1,
    # Gauss points of the cell [1.5, 2.5] in v, weight = clipped width 0.5 x 0.5.
    for v in (2 - G, 2 + G):
        assert rule.w[find(rule, 1.0, v)] == pytest.approx(0.25, abs=1e-15)
    # ... and on the bottom edge: points on v = 1.
    for u in (3 - G, 3 + G):
        assert rule.w[find(rule, u, 1.0)] == pytest.approx(0.25, abs=1e-15)
    # Corner quarter cells: one point on each corner knot, weight 0.25.
    for u, v in ((1, 1), (1, 4), (4, 1), (4, 4)):
        assert rule.w[find(rule, float(u), float(v))] == pytest.approx(0.25, abs=1e-15)
    # Corner spans of the ring: 3 x 3 Gauss.
    for s, t in ((0, 0), (4, 0), (0, 4), (4, 4)):
        q = points_in(rule, s, s + 1, t, t + 1)
        assert q.size == 9
        assert np.allclose(np.unique(np.round(rule.u[q] - s, 12)), [0.5 - G3, 0.5, 0.5 + G3])
        assert np.allclose(np.unique(np.round(rule.v[q] - t, 12)), [0.5 - G3, 0.5, 0.5 + G3])
        assert rule.w[q].sum() == pytest.approx(1.0, abs=1e-14)
    # Side spans: 2 Gauss points along the side, 3 across it.
    for s in (1, 2, 3):
        for t in (0, 4):  # bottom / top rows
            q = points_in(rule, s, s + 1, t, t + 1)
            assert q.size == 6
            assert np.unique(np.round(rule.u[q], 12)).size == 2
            assert np.unique(np.round(rule.v[q], 12)).size == 3
            assert rule.w[q].sum() == pytest.approx(1.0, abs=1e-14)
        for t in (0, 4):  # left / right columns (roles swapped)
            q = points_in(rule, t, t + 1, s, s + 1)
            assert q.size == 6
            assert np.unique(np.round(rule.u[q], 12)).size == 3
            assert np.unique(np.round(rule.v[q], 12)).size == 2
    # Totals: 4 x 9 + 12 x 6 ring points; 4 quarter cells x 1 + 8 half cells x 2 +
    # 4 inner cells x 2 interior points.
    ring = (rule.u < 1) | (rule.u > 4) | (rule.v < 1) | (rule.v > 4)
    assert ring.sum() == 108
    assert (~ring).sum() == 28
    assert rule.w[~ring].sum() == pytest.approx(9.0, abs=1e-13)
    # Every interior point sits on a knot line in at least one direction.
    on_u = rule.u == np.round(rule.u)
    on_v = rule.v == np.round(rule.v)
    assert np.all((on_u | on_v)[~ring])


@pytest.mark.parametrize("shape", ((5, 5), (6, 8), (9, 7)))
def test_reduced_interior_checkerboard(shape):
    """Interior cells away from the interior region's edges alternate 1x2 / 2x1."""
    n, m = shape
    rule = reduced_membrane(n, m)
    su, sv = n - 2, m - 2
    for k in range(2, su - 1):
        for l in range(2, sv - 1):
            q = points_in(rule, k - 0.5, k + 0.5, l - 0.5, l + 0.5)
            assert q.size == 2
            single_u = np.all(rule.u[q] == k)
            single_v = np.all(rule.v[q] == l)
            assert single_u != single_v
            assert single_u == ((k + l) % 2 == 0)
            assert rule.w[q].sum() == pytest.approx(1.0, abs=1e-14)


def test_reduced_rule_rejects_small_nets():
    with pytest.raises(ValueError):
        reduced_membrane(4, 7)


@pytest.mark.parametrize("shape", ((7, 7), (9, 6)))
def test_membrane_stencil_sizes(shape):
    """Interior (reduced) points touch 2 x 3 = 6 control points, ring points 3 x 3; the
    corner quarter-cell points sit on a knot in both directions and touch 2 x 2."""
    n, m = shape
    rule = reduced_membrane(n, m)
    pd = point_data(Patch.rectangle("r", (1.0, 0.8), shape).rest, rule)
    count = (pd.idx >= 0).sum(axis=1)
    ring = (rule.u < 1) | (rule.u > n - 3) | (rule.v < 1) | (rule.v > m - 3)
    corner_knot = (rule.u == np.round(rule.u)) & (rule.v == np.round(rule.v))
    assert np.all(count[ring] == 9)
    assert np.all(count[~ring & ~corner_knot] == 6)
    assert corner_knot.sum() == 4
    assert np.all(count[corner_knot] == 4)
    assert pd.idx.shape[1] == 9
    # Stencils hold distinct control points.
    for row in pd.idx:
        r = row[row >= 0]
        assert np.unique(r).size == r.size
    # The values of the dropped functions are exactly zero: the kept N sum to 1.
    assert np.abs(np.where(pd.idx >= 0, pd.N, 0).sum(axis=1) - 1).max() < 1e-14


# ------------------------------------------------------------------ curved patch


def annulus_sector(n, m, r0=1.0, r1=2.0, angle=np.pi / 2):
    """Control points at the Greville abscissae mapped through the polar map."""
    s = Patch.greville(n) / (n - 2)
    t = Patch.greville(m) / (m - 2)
    S, T = np.meshgrid(s, t, indexing="ij")
    r = r0 + (r1 - r0) * S
    a = angle * T
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=-1)


def boundary_area(X, samples=4000):
    """Shoelace area of the patch boundary curve, sampled densely (independent of quadrature)."""
    n, m = X.shape[:2]
    su = np.linspace(0, n - 2, samples)
    sv = np.linspace(0, m - 2, samples)
    Bu, Bv = basis_matrix(su, n), basis_matrix(sv, m)
    e0, e1 = basis_matrix(np.array([0.0]), n)[0], basis_matrix(np.array([n - 2.0]), n)[0]
    f0, f1 = basis_matrix(np.array([0.0]), m)[0], basis_matrix(np.array([m - 2.0]), m)[0]
    bottom = np.einsum("pi,j,ijd->pd", Bu, f0, X)
    right = np.einsum("i,pj,ijd->pd", e1, Bv, X)
    top = np.einsum("pi,j,ijd->pd", Bu[::-1], f1, X)
    left = np.einsum("i,pj,ijd->pd", e0, Bv[::-1], X)
    P = np.concatenate([bottom, right, top, left])
    x, y = P[:, 0], P[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_curved_patch_rest_area():
    n = m = 12
    X = annulus_sector(n, m)
    area = {name: point_data(X, membrane_rule(name, n, m)).w.sum() for name in ("reduced", "gauss2", "gauss3")}
    # The rest map is a polynomial of degree (2, 2) per span, so det dX/du has degree
    # (3, 3): 2- and 3-point Gauss rules both integrate it exactly ...
    assert abs(area["gauss2"] - area["gauss3"]) < 1e-12 * area["gauss3"]
    # ... and that is the true area of the B-spline surface (an independent boundary
    # integral agrees to the boundary sampling error).
    assert abs(boundary_area(X) - area["gauss3"]) < 1e-6 * area["gauss3"]
    # The reduced rule is not exact on a curved patch but within the design's budget.
    err = abs(area["reduced"] - area["gauss3"]) / area["gauss3"]
    assert err < 1e-3
    assert err > 0.0  # genuinely curved: the rules differ
    # Sanity: the spline surface approximates the exact sector.
    exact = np.pi / 4 * (2.0**2 - 1.0**2)
    assert abs(area["gauss3"] - exact) < 1e-2 * exact


def test_point_data_rejects_degenerate_rest():
    n, m = 6, 6
    X = Patch.rectangle("r", (1.0, 1.0), (n, m)).rest.copy()
    X[..., 1] = 0.0  # all points on a line: dX/du is singular
    with pytest.raises(ValueError):
        point_data(X, gauss(n, m, 2))


def test_point_data_rejects_folded_rest():
    n, m = 6, 6
    X = Patch.rectangle("r", (1.0, 1.0), (n, m)).rest.copy()
    X[2, 2] += [0.6, 0.0]  # drag an interior control point past its neighbours
    rule = gauss(n, m, 3)
    # The map really folds: the signed Jacobian changes sign at quadrature points.
    Bu, dBu = basis_matrix(rule.u, n), basis_matrix(rule.u, n, 1)
    Bv, dBv = basis_matrix(rule.v, m), basis_matrix(rule.v, m, 1)
    Xu = np.einsum("qi,qj,ijd->qd", dBu, Bv, X)
    Xv = np.einsum("qi,qj,ijd->qd", Bu, dBv, X)
    J = Xu[:, 0] * Xv[:, 1] - Xu[:, 1] * Xv[:, 0]
    assert (J < 0).any() and (J > 0).any()
    with pytest.raises(ValueError):
        point_data(X, rule)


def test_point_data_accepts_mirrored_rest():
    """A consistently mirrored net (J < 0 everywhere) is a valid parametrisation: same
    area, and gradients g = dN/dX still reproduce the identity map."""
    n, m = 6, 7
    X = Patch.rectangle("r", (1.0, 0.8), (n, m)).rest.copy()
    X[..., 0] *= -1.0
    pd = point_data(X, reduced_membrane(n, m))
    assert pd.w.sum() == pytest.approx(0.8, rel=1e-12)
    g = np.where((pd.idx >= 0)[..., None], pd.g, 0.0)
    F = np.einsum("qad,qae->qde", X.reshape(-1, 2)[np.maximum(pd.idx, 0)], g)
    assert np.abs(F - np.eye(2)).max() < 1e-12
