"""Conforming numerics (conform/): side fits, knot insertion, the interior start, the MIPS
energy's derivatives, the step bound, untangling, corners, and whole panels of known shape."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from conform import ConformOptions, conform_panel
from conform.boundary import extract_outline
from conform.control_net import boundary_area, match_area, refine, refine_1d, tangential_start
from conform.corners import TooFewCorners, candidates, pick_corners
from conform.curve_fit import evaluate, fit_side, fit_side_reweighted, sample_polyline
from conform.mips import MipsOptions, MipsProblem, _newton_terms, _point_terms, det, rule_points
from conform.mips import refine as mips_refine
from sim.patches import Panel, Patch
from sim.bspline import basis_matrix

from tests.support.fd import central, unit
from tests.support.panels import polygon_panel


# ------------------------------------------------------------------------ curves and nets


def test_knot_insertion_keeps_the_curve():
    rng = np.random.default_rng(0)
    for n in (3, 5, 9):
        P = rng.random((n, 2))
        Q = refine_1d(P)
        assert Q.shape == (2 * n - 2, 2)
        u = np.linspace(0, n - 2, 37)
        np.testing.assert_allclose(basis_matrix(u, n) @ P, basis_matrix(2 * u, Q.shape[0]) @ Q, atol=1e-14)
    X = rng.random((6, 7, 2))
    Y = refine(X)
    assert Y.shape == (10, 12, 2)
    u, v = np.linspace(0, 4, 9), np.linspace(0, 5, 11)
    a = np.einsum("ai,bj,ijd->abd", basis_matrix(u, 6), basis_matrix(v, 7), X)
    b = np.einsum("ai,bj,ijd->abd", basis_matrix(2 * u, 10), basis_matrix(2 * v, 12), Y)
    np.testing.assert_allclose(a, b, atol=1e-14)


def test_side_fit_reproduces_a_line_and_converges_on_an_arc():
    line = np.linspace([0.0, 0.0], [0.3, 0.1], 40)
    C = fit_side(sample_polyline(line, 0.002), 9)
    u = np.linspace(0, 7, 50)
    r, e = evaluate(C, u) - line[0], line[-1] - line[0]
    d = np.abs(r[:, 0] * e[1] - r[:, 1] * e[0]) / np.linalg.norm(e)
    assert d.max() < 1e-12
    np.testing.assert_allclose(C[[0, -1]], line[[0, -1]])  # ends pinned to the corners

    t = np.linspace(0, np.pi / 2, 400)
    arc = 0.2 * np.stack([np.cos(t), np.sin(t)], 1)
    errors = []
    for n in (6, 10, 18):
        C, _ = fit_side_reweighted(sample_polyline(arc, 0.001), n)
        p = evaluate(C, np.linspace(0, n - 2, 400))
        errors.append(np.abs(np.linalg.norm(p, axis=1) - 0.2).max())
    assert errors[0] > errors[1] > errors[2] and errors[2] < 2e-5
    # Quadratic splines approximate a circle to third order: halving the span ~ 1/8.
    assert errors[1] / errors[2] > 4.0


def test_tangential_start_is_exact_on_affine_nets():
    P = Patch.rectangle("r", (0.7, 0.4), (8, 6))
    A = np.array([[1.0, 0.3], [0.1, 0.9]])
    X = P.rest @ A.T  # a parallelogram net at the Greville points
    B = X.copy()
    B[1:-1, 1:-1] = np.nan
    np.testing.assert_allclose(tangential_start(B), X, atol=1e-12)


def test_match_area_offsets_the_boundary():
    P = Patch.rectangle("r", (0.5, 0.3), (7, 6))
    assert boundary_area(P.rest) == pytest.approx(0.15, rel=1e-12)
    X, offset = match_area(P.rest, 0.15 * 1.001)
    assert boundary_area(X) == pytest.approx(0.15 * 1.001, rel=1e-9)
    # About area change / perimeter; more, as the fixed corners do not move.
    assert 1.0 < offset / (0.15e-3 / 1.6) < 1.3
    np.testing.assert_allclose(X[[0, 0, -1, -1], [0, -1, 0, -1]], P.rest[[0, 0, -1, -1], [0, -1, 0, -1]])


# --------------------------------------------------------------------------------- MIPS


def test_point_energy_derivatives_match_finite_differences():
    rng = np.random.default_rng(1)
    Y = np.array([[1.0, 0.1, -0.2, 0.8], [0.7, 0.3, 0.2, 1.4], [1.2, -0.4, 0.5, 0.9]])
    # Per-point factors (1/a, 1/a, 1/b, 1/b), different at each point as on a graded net.
    scale = np.array([[1.3, 1.3, 0.8, 0.8], [0.9, 0.9, 1.1, 1.1], [2.0, 2.0, 0.5, 0.5]])
    for eps, aw in ((0.0, 0.0), (0.0, 10.0), (0.3, 1.0)):
        f, g, _ = _point_terms(Y, scale, eps, aw, 0.9)
        h = 1e-6

        def terms(Y):  # per point (f, g) without projection: component k of every point at once
            return _point_terms(Y, scale, eps, aw, 0.9, False)

        for k in range(4):
            fd = central(lambda Y: terms(Y)[0], Y, unit(Y, np.s_[:, k]), h)
            np.testing.assert_allclose(g[:, k], fd, rtol=1e-6)
        # The Hessian is the derivative of the gradient; the projected one is PSD.
        _, _, H = _point_terms(Y, scale, eps, aw, 0.9, project=False)
        for k in range(4):
            fd = central(lambda Y: terms(Y)[1], Y, unit(Y, np.s_[:, k]), h)
            np.testing.assert_allclose(H[:, :, k], fd, rtol=1e-5, atol=1e-6)
        _, _, Hp = _point_terms(Y, scale, eps, aw, 0.9)
        assert np.linalg.eigvalsh(Hp).min() > -1e-9 * np.abs(Hp).max()
    # The numba kernel agrees with the reference implementation.
    D = rng.random((3, 2, 1))
    E, gY, _ = _newton_terms(Y, np.ones(3), scale, 0.0, 10.0, 0.9, 2.0, D, np.zeros((3, 1, 1), np.int64), 1)
    f, g, _ = _point_terms(Y, scale, 0.0, 10.0, 0.9, False)
    assert E == pytest.approx(f.sum(), rel=1e-12)
    np.testing.assert_allclose(gY, g, rtol=1e-12)


def _problem(n=7, m=6, seed=2):
    rng = np.random.default_rng(seed)
    X = Patch.rectangle("r", (0.3, 0.2), (n, m)).rest
    X[1:-1, 1:-1] += 0.004 * rng.standard_normal((n - 2, m - 2, 2))
    fixed = np.zeros((n, m), bool)
    fixed[0, :] = fixed[-1, :] = fixed[:, 0] = fixed[:, -1] = True
    prob = MipsProblem(n, m, (0.3 / (n - 2), 0.2 / (m - 2)), None, np.repeat(fixed.ravel(), 2), MipsOptions())
    return prob, X.reshape(-1, 2), fixed


def test_mips_gradient_and_newton_step():
    prob, X2, _ = _problem()
    E, g, H = prob._energy(X2, 0.0, True)
    rng = np.random.default_rng(3)
    d = rng.standard_normal(X2.shape)
    h = 1e-7
    fd = central(prob.value, X2, d, h)
    assert (g * d).sum() == pytest.approx(fd, rel=1e-6)
    # The numba kernel's assembled Hessian equals a plain sparse assembly of the per-point
    # projected Hessians of the reference implementation.
    pts = prob.pts
    _, _, Hq = _point_terms(pts.jacobians(X2), prob.scale, 0.0, prob.options.area_weight, prob.d0)
    Hq = Hq * (pts.w / prob.W)[:, None, None]
    Dk = {0: pts.Du, 1: pts.Dv}
    N = X2.size
    H_ref = sp.csr_matrix((N, N))
    for a in range(2):
        for b in range(2):
            for dd in range(2):
                for ee in range(2):
                    block = (Dk[a].T @ sp.diags(Hq[:, 2 * a + dd, 2 * b + ee]) @ Dk[b]).tocoo()
                    H_ref = H_ref + sp.csr_matrix((block.data, (2 * block.row + dd, 2 * block.col + ee)), shape=(N, N))
    assert abs(H - H_ref).max() < 1e-9 * abs(H_ref).max()
    # Newton decreases the energy; the decrement is positive.
    E0, dec, D2 = prob.newton(X2)
    assert dec > 0 and prob.value(X2 + D2) < E0


def test_max_step_finds_the_first_fold():
    prob, X2, fixed = _problem()
    # Move one interior control point far across its neighbours: a fold at some alpha < 1.
    D2 = np.zeros_like(X2)
    k = 3 * 6 + 2
    D2[k] = [0.0, 0.15]
    alpha = prob.max_step(X2, D2)
    assert 0.0 < alpha < 1.0
    assert det(prob.pts.jacobians(X2 + 0.999 * alpha * D2)).min() > 0
    assert det(prob.pts.jacobians(X2 + 1.001 * alpha * D2)).min() < 0


def test_untangles_an_inverted_net_and_keeps_every_rule_point_positive():
    n, m = 8, 7
    X = Patch.rectangle("r", (0.3, 0.2), (n, m)).rest.copy()
    X[3, 3], X[4, 4] = X[4, 4].copy(), X[3, 3].copy()  # fold the middle
    X[2, 5] = X[5, 1]
    pts = rule_points(n, m)
    assert det(pts.jacobians(X.reshape(-1, 2))).min() < 0
    fixed = np.zeros((n, m), bool)
    fixed[0, :] = fixed[-1, :] = fixed[:, 0] = fixed[:, -1] = True
    res = mips_refine(X, (0.3 / 6, 0.2 / 5), None, fixed, MipsOptions())
    assert res.untangle_iterations > 0 and res.converged
    d = det(pts.jacobians(res.X.reshape(-1, 2)))
    assert d.min() > 0.5 * d.mean()  # back to a near-uniform grid
    np.testing.assert_allclose(res.X, Patch.rectangle("r", (0.3, 0.2), (n, m)).rest, atol=2e-3)


# ------------------------------------------------------------------------------ corners


def test_corners_of_a_house_skip_the_roof_apex():
    house = [[0, 0], [0.4, 0], [0.4, 0.3], [0.2, 0.38], [0, 0.3]]
    panel = polygon_panel("house", house, hints=False)
    outline = extract_outline(panel)
    c = pick_corners(outline)
    np.testing.assert_allclose(outline.points[c], [[0, 0], [0.4, 0], [0.4, 0.3], [0, 0.3]], atol=1e-9)


def test_corners_ignore_mesh_noise_and_user_overrides_win():
    # A noisy 0.3 x 0.2 rectangle outline.
    rng = np.random.default_rng(4)
    rect = polygon_panel("r", [[0, 0], [0.3, 0], [0.3, 0.2], [0, 0.2]], spacing=0.004, hints=False)
    rect.rest += 2e-4 * rng.standard_normal(rect.rest.shape) * (rng.random((len(rect.rest), 1)) > 0.5)
    outline = extract_outline(rect)
    c = pick_corners(outline)
    np.testing.assert_allclose(outline.points[c], [[0, 0], [0.3, 0], [0.3, 0.2], [0, 0.2]], atol=1e-3)
    # Overrides: positions (snapped to the nearest boundary vertex), in the order given.
    user = [(0.1, 0.0), (0.3, 0.1), (0.1, 0.2), (0.0, 0.1)]
    patch, rep = conform_panel(rect, ConformOptions(corners=user, knot_span=0.03))
    np.testing.assert_allclose(rep["provenance"]["corner_positions"], user, atol=3e-3)
    np.testing.assert_allclose(patch.rest[0, 0], [0.1, 0.0], atol=3e-3)


def test_round_outline_fallback_corners_keep_off_a_seam_end_and_a_dart_tip():
    # A round outline has no turn sharp enough for a corner, so evenly spaced points stand
    # in; one of them a loop point from a seam's end would be a corner that seam wraps
    # round (skirt_06: 0.23 spans, 2.1 mm off in the plane), one beside a dart tip that tip.
    t = np.linspace(0.0, 2.0 * np.pi, 200, endpoint=False)
    panel = Panel(name="disc", source="test", rest=0.3 * np.c_[np.cos(t), np.sin(t)])
    outline = extract_outline(panel)
    spaced = np.searchsorted(outline.s[:-1], np.linspace(0.0, outline.perimeter, 12, endpoint=False))
    hint, tip = spaced[3] + 1, spaced[6] - 1  # one loop point from two of them
    pool = candidates(outline, hints=[hint], avoid=[tip])
    assert hint in pool and tip not in pool
    assert spaced[3] not in pool and spaced[6] not in pool
    assert set(spaced) - {spaced[3], spaced[6]} <= set(pool)  # the others stay


def test_fallback_corners_never_leave_fewer_than_four_candidates():
    # Avoided points beside ten of the twelve spaced points would leave two clear ones; a
    # patch needs four, so the spaced points not themselves avoided stand in (a fuzzed
    # panel with one stray vertex made pick_corners index with an empty array).
    t = np.linspace(0.0, 2.0 * np.pi, 200, endpoint=False)
    outline = extract_outline(Panel(name="disc", source="test", rest=0.3 * np.c_[np.cos(t), np.sin(t)]))
    spaced = np.searchsorted(outline.s[:-1], np.linspace(0.0, outline.perimeter, 12, endpoint=False))
    avoid = spaced[:10] + 1
    pool = candidates(outline, avoid=avoid)
    assert pool.size >= 4 and not np.isin(pool, avoid).any()
    assert len(pick_corners(outline, avoid=avoid)) == 4
    square = extract_outline(Panel(name="sq", source="test", rest=np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])))
    with pytest.raises(TooFewCorners, match="needs 4"):
        pick_corners(square, avoid=[0])  # a clear error, not an IndexError


# ------------------------------------------------------------------------- whole panels


def test_rectangle_conforms_to_the_exact_affine_patch():
    panel = polygon_panel("rect", [[0, 0], [0.4, 0], [0.4, 0.2], [0, 0.2]])
    patch, rep = conform_panel(panel, ConformOptions(knot_span=0.02))
    assert patch.shape == (22, 12)
    np.testing.assert_allclose(patch.rest, Patch.rectangle("r", (0.4, 0.2), (22, 12)).rest, atol=1e-9)
    assert rep["boundary_error_mm"] < 1e-6
    assert rep["min_jacobian_ratio"] == pytest.approx(1.0, abs=1e-6)
    assert abs(rep["area_error_reduced_pct"]) < 1e-9
    np.testing.assert_allclose(patch.world[..., 2], 0.0)
    sides = rep["provenance"]["sides"]
    assert [sides[k]["outline_range"][0] for k in ("v0", "u1", "v1", "u0")] == list(panel.corner_hints)


def test_curved_panel_meets_the_targets():
    # A panel bounded by an arc on top and a concave bottom: both boundaries curved.
    t = np.linspace(0, 1, 60, endpoint=False)
    top = np.stack([0.4 - 0.4 * t, 0.25 + 0.06 * np.sin(np.pi * t)], 1)
    bottom = np.stack([0.4 * t, 0.04 * np.sin(np.pi * t)], 1)
    right = np.stack([np.full(20, 0.4), 0.25 * np.arange(20) / 20], 1)
    left = np.stack([np.zeros(20), 0.25 - 0.25 * np.arange(20) / 20], 1)
    poly = np.concatenate([bottom, right, top, left])
    panel = Panel("curved", "test", poly, corner_hints=np.array([0, 60, 80, 140]))
    patch, rep = conform_panel(panel, ConformOptions(knot_span=0.02))
    assert rep["inverted_points"] == 0 and rep["min_jacobian_ratio"] > 0.5
    assert rep["boundary_error_mm"] < 0.1 < rep["tolerance_mm"]
    assert abs(rep["area_error_gauss2_pct"]) < 1e-3  # the boundary keeps the panel's area
    assert abs(rep["area_error_reduced_pct"]) < 0.1


def test_knot_insertion_refinement_halves_the_spans():
    panel = polygon_panel("house", [[0, 0], [0.3, 0], [0.3, 0.2], [0.15, 0.26], [0, 0.2]], hints=False)
    coarse, rc = conform_panel(panel, ConformOptions(knot_span=0.03))
    fine, rf = conform_panel(panel, ConformOptions(knot_span=0.03, refine=2))
    n, m = coarse.shape
    assert fine.shape == (4 * n - 6, 4 * m - 6)  # twice: n -> 2n - 2 -> 4n - 6
    assert rf["inverted_points"] == 0
    # The roof apex (a bend inside a side) is rounded off less by shorter spans.
    assert rf["boundary_error_mm"] < 0.6 * rc["boundary_error_mm"]
