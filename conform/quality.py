"""The quality report of a conformed patch (docs/design.md section 4b, "Report per patch").

- boundary fit error: the two-sided (Hausdorff) distance between the input outline and
  the patch boundary, mm, against the tolerance max(1 mm, 0.5 % of the panel diameter);
- Jacobian: det dX/du at every guard point (the points of every simulator rule: reduced,
  2 x 2 and 3 x 3 Gauss), as a ratio to its mean: min (> 0 means no inverted point) and max;
- corner angles: the patch's interior angles at its four corners, degrees;
- skew: the smallest angle between X_u and X_v over the guard points, degrees;
  aspect: the largest singular-value ratio of the scaled Jacobian;
- lift strain: the largest relative change of length between the rest and the lifted 3D
  patch, sampled four times per knot span (0 for a rigid placement);
- area: the rest area that the simulator's rules integrate (reduced rule, and 2 x 2 Gauss,
  which is exact for the patch: det is bicubic per span) against the input's area, %.
"""

from __future__ import annotations

from functools import partial

import numpy as np
from scipy.spatial import cKDTree

from sim.rest import point_data
from sim.bspline import basis_matrix
from sim.embedding import default_resolution, grid_faces, interpolation_matrix, points_at, sample_grid
from sim.seams.mesh import THIN, Perimeter, seamed_mesh

from .boundary import Outline, self_intersections, signed_areas
from .curve_fit import evaluate
from .control_net import side_rows
from .mips import det, rule_points, simulator_rules


def polyline_distance(points: np.ndarray, poly: np.ndarray, closed: bool, k: int = 6) -> np.ndarray:
    """Distance from each point (P, 2) to the polyline through poly (V, 2)."""
    V = poly.shape[0]
    _, near = cKDTree(poly).query(points, k=min(k, V))
    near = near.reshape(points.shape[0], -1)
    best = np.full(points.shape[0], np.inf)
    for j in range(near.shape[1]):
        for step in (-1, 0):  # the segments before and after the vertex
            a = near[:, j] + step
            if closed:
                a = a % V
            else:
                a = np.clip(a, 0, V - 2)
            b = (a + 1) % V
            A, B = poly[a], poly[b]
            AB = B - A
            t = np.clip(((points - A) * AB).sum(1) / np.maximum((AB**2).sum(1), 1e-300), 0.0, 1.0)
            d = np.linalg.norm(points - (A + t[:, None] * AB), axis=1)
            best = np.minimum(best, d)
    return best


def boundary_curve(X: np.ndarray, per_span: int = 24) -> np.ndarray:
    """The patch boundary as a closed polyline, counter-clockwise from corner (0, 0)."""
    parts = []
    for row in side_rows(X):
        nr = row.shape[0]
        u = np.linspace(0.0, nr - 2.0, per_span * (nr - 2) + 1)[:-1]
        parts.append(evaluate(row, u))
    return np.concatenate(parts)


def densify(poly: np.ndarray, per_segment: int = 4) -> np.ndarray:
    """Closed polyline points plus per_segment - 1 points inside every segment."""
    nxt = np.roll(poly, -1, axis=0)
    t = np.arange(per_segment) / per_segment
    return (poly[:, None, :] + t[None, :, None] * (nxt - poly)[:, None, :]).reshape(-1, 2)


def boundary_error(outline: Outline, X: np.ndarray) -> tuple[float, float]:
    """(Hausdorff distance, mean outline-to-patch distance) between outline and patch
    boundary, metres."""
    curve = boundary_curve(X)
    a = polyline_distance(densify(outline.points), curve, closed=True)
    b = polyline_distance(curve, outline.points, closed=True)
    return float(max(a.max(), b.max())), float(a.mean())


def corner_angles(X: np.ndarray) -> np.ndarray:
    """Interior angles (degrees) of the patch at corners (0,0), (n-2,0), (n-2,m-2), (0,m-2)."""
    Xu0 = X[1, :] - X[0, :]  # derivative direction along u at u = 0, per j
    Xu1 = X[-2, :] - X[-1, :]
    Xv0 = X[:, 1] - X[:, 0]
    Xv1 = X[:, -2] - X[:, -1]
    pairs = [(Xu0[0], Xv0[0]), (Xu1[0], Xv0[-1]), (Xu1[-1], Xv1[-1]), (Xu0[-1], Xv1[0])]
    out = []
    for a, b in pairs:
        c = a @ b / (np.linalg.norm(a) * np.linalg.norm(b))
        out.append(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))
    return np.asarray(out)


def report(outline: Outline, X: np.ndarray, tolerance: float) -> dict:
    """Quality numbers of the rest net X (n, m, 2) against its panel's outline."""
    n, m = X.shape[:2]
    X2 = X.reshape(-1, 2)
    guard = rule_points(n, m)
    Y = guard.jacobians(X2)
    d = det(Y)
    ratio = d / d.mean()
    # Scaled Jacobian for skew and aspect: mean span sizes along u and v.
    a = np.linalg.norm(np.diff(X, axis=0), axis=-1).sum(0).mean() / (n - 2)
    b = np.linalg.norm(np.diff(X, axis=1), axis=-1).sum(1).mean() / (m - 2)
    J = np.stack([Y[:, :2] / a, Y[:, 2:] / b], axis=2)  # columns X_u/a, X_v/b
    sv = np.linalg.svd(J, compute_uv=False)
    cosang = (Y[:, :2] * Y[:, 2:]).sum(1) / (np.linalg.norm(Y[:, :2], axis=1) * np.linalg.norm(Y[:, 2:], axis=1))
    skew = np.degrees(np.arccos(np.clip(np.abs(cosang), 0.0, 1.0)))
    err, mean_err = boundary_error(outline, X)
    rep = {
        "control_points": [n, m],
        "knot_span_mm": [1e3 * a, 1e3 * b],
        "boundary_error_mm": 1e3 * err,
        "boundary_error_mean_mm": 1e3 * mean_err,
        "tolerance_mm": 1e3 * tolerance,
        "panel_diameter_mm": 1e3 * outline.diameter,
        "inverted_points": int((d <= 0).sum()),
        "min_jacobian_ratio": float(ratio.min()),
        "max_jacobian_ratio": float(ratio.max()),
        "min_corner_angle_deg": float(corner_angles(X).min()),
        "corner_angles_deg": [float(x) for x in corner_angles(X)],
        "min_skew_angle_deg": float(skew.min()),
        "max_aspect_ratio": float((sv[:, 0] / np.maximum(sv[:, 1], 1e-300)).max()),
        "input_area_m2": outline.area,
    }
    if rep["inverted_points"] == 0:
        rules = simulator_rules(n, m)
        for name, rule in (("reduced", rules.get("reduced")), ("gauss2", rules["gauss2"])):
            if rule is None:
                continue
            area = float(point_data(X, rule).w.sum())
            rep[f"area_{name}_m2"] = area
            rep[f"area_error_{name}_pct"] = 100.0 * (area - outline.area) / outline.area
        rep["area_error_pct"] = rep.get("area_error_reduced_pct", rep["area_error_gauss2_pct"])
    return rep


def lift_strain(X: np.ndarray, C: np.ndarray, per_span: int = 4) -> float:
    """Largest |length in 3D / length at rest - 1| between neighbouring samples."""
    n, m = X.shape[:2]
    Bu = basis_matrix(np.linspace(0, n - 2, per_span * (n - 2) + 1), n)
    Bv = basis_matrix(np.linspace(0, m - 2, per_span * (m - 2) + 1), m)
    S = np.einsum("ai,bj,ijd->abd", Bu, Bv, X, optimize=True)
    W = np.einsum("ai,bj,ijd->abd", Bu, Bv, C, optimize=True)
    worst = 0.0
    for axis in (0, 1):
        ds = np.linalg.norm(np.diff(S, axis=axis), axis=-1)
        dw = np.linalg.norm(np.diff(W, axis=axis), axis=-1)
        worst = max(worst, float(np.abs(dw / ds - 1.0).max()))
    return worst


def folded(patch, per_span: int = 4, density: float = 2.0) -> bool:
    """Whether the patch's map from parameters to its flat rest shape folds over anywhere:
    on a fine grid (`per_span` points per knot span) or on the simulator's contact mesh
    (sim.embedding.default_resolution at `density`), a triangle turned over or the
    boundary crossing itself, or that mesh with seam vertices all round its boundary
    turning a triangle over. The Jacobian checks look at quadrature points only; a
    narrow strap can fold between them, and a barely one-to-one net can overlap itself
    on the coarser contact mesh (its chords cut across)."""
    n, m = patch.shape
    rest = patch.rest.reshape(-1, 2)
    contact = default_resolution(n, m, density)
    return (any(_grid_folds(rest, n, m, res) for res in ((per_span * (n - 2) + 1, per_span * (m - 2) + 1), contact))
            or _seamed_folds(patch.rest, contact))


def _seamed_folds(rest: np.ndarray, res: tuple[int, int]) -> bool:
    """The simulator's mesh of a sewn piece (sim/seams/mesh.py) puts seam vertices on the
    true boundary between the grid's: near a dart tip the grid's chords can pass outside
    them. Seam vertices every THIN grid steps all round stand for any seams."""
    n, m = rest.shape[:2]
    per = Perimeter(n - 2.0, m - 2.0, *res)
    place = partial(points_at, rest)
    uv, faces, _ = seamed_mesh(per.U, per.V, res, [np.arange(0.0, per.length, THIN)], place)
    return bool((signed_areas(place(uv), faces) <= 0).any())


def _grid_folds(rest: np.ndarray, n: int, m: int, res: tuple[int, int]) -> bool:
    X = interpolation_matrix(*sample_grid(n, m, res), n, m, 0, n * m) @ rest
    if (signed_areas(X, grid_faces(*res)) <= 0).any():
        return True
    # Turned over nowhere, it can still lie over itself (a narrow strap whose sides
    # cross): a map without turned-over triangles is one-to-one exactly when its
    # boundary does not cross itself.
    G = X.reshape(res[0], res[1], 2)
    loop = np.concatenate([G[:, 0], G[-1, 1:], G[-2::-1, -1], G[0, -2:0:-1]])
    return bool(self_intersections(loop))
