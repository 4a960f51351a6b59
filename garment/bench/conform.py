"""Quadrature error on conformed non-rectangular patches: the paper's distortion sweep.

Shapes (short side 1 m): aspect ratios 1:1 to 1:10 (A1-A10), parallelograms with a
smallest angle of 75 down to 30 degrees (S75-S30), and a unit square whose top edge bends
at its midpoint to an interior angle of 165 down to 105 degrees (B165-B105). Each is
conformed with `resolution` control points along its short side (proportionally more
along the long side, at least 5), corners at the shape's four corners, and measured with
the rule `quadrature` (the simulator's reduced rule by default):

- area_error: |rule area - shape area| / shape area, with the membrane rule. The
  reference is the input polygon: what a linear FEM mesh of the shape integrates exactly.
- mass_error: ||M - M_ref||_F / ||M_ref||_F for the consistent mass matrix
  M_ab = int N_a N_b dX (unit areal density) with the simulator's mass rule, 3 x 3 Gauss
  per span. N_a N_b det J has degree 4 + 3 per direction, so the rule is exact only where
  det J is constant (rectangles, parallelograms) and the error measures the distortion.
  (The lumped masses int N_a dX, degree 2 + 3, are exact on any patch.)
- energy_error: |E - E_ref| / E_ref for the membrane (StVK, unit Lame constants) energy
  of a smooth cloth-like deformation (2 % stretch and shear, a 5 cm bulge) applied to the
  control points,
  with the membrane rule.
The references for mass and energy integrate the same patch with 6 x 6 Gauss points per
knot span (converged to round-off for these smooth integrands). A fine linear FEM
reference (`linear_reference`: 16 x 16 linear triangle pairs per span) agrees with it to
its own discretisation error (B105 at 10 x 10: 3e-5 in the energy, 4e-5 in the lumped
masses), which is why it is not the default: it would hide errors of that size.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg.norm)

from conform.boundary import sample_polygon
from conform.pipeline import ConformOptions, conform_panel
from sim.bspline import basis_matrix
from sim.embedding import grid_faces
from sim.patches import Panel
from sim.quadrature import Rule, gauss, membrane_rule
from sim.rest import point_data

COLUMNS = ("shape", "resolution", "control_points", "quadrature", "area_error", "mass_error", "energy_error",
           "min_jacobian_ratio", "boundary_error_mm", "seconds")

ASPECTS = (1, 2, 4, 6, 8, 10)
SKEWS = (75, 60, 45, 30)
BENDS = (165, 150, 135, 120, 105)
FINE = 16  # linear sub-grid per knot span for the reference


def shapes() -> dict[str, tuple[np.ndarray, tuple[float, float]]]:
    """name -> (polygon (V, 2), counter-clockwise from the corner at the origin, (length
    along u, length along v)); the patch corners are the polygon vertices but the apex."""
    out = {}
    for a in ASPECTS:
        out[f"A{a}"] = (np.array([[0, 0], [a, 0], [a, 1], [0, 1]], float), (a, 1.0))
    for s in SKEWS:
        t = np.radians(s)
        out[f"S{s}"] = (np.array([[0, 0], [1, 0], [1 + np.cos(t), np.sin(t)], [np.cos(t), np.sin(t)]]), (1.0, 1.0))
    for b in BENDS:
        h = 0.5 / np.tan(np.radians(b) / 2)  # apex height over the top edge
        out[f"B{b}"] = (np.array([[0, 0], [1, 0], [1, 1], [0.5, 1 + h], [0, 1]]), (1.0, 1.0))
    return out


def outline_panel(name: str, polygon: np.ndarray, spacing: float) -> tuple[Panel, list]:
    """An outline panel sampled every `spacing` m; returns it and its corner positions."""
    rest, hints = sample_polygon(polygon, spacing)
    x, y = polygon[:, 0], polygon[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    panel = Panel(name=name, source="bench", rest=rest, corner_hints=hints, area=area)
    corners = [tuple(polygon[k]) for k in range(len(polygon)) if not (len(polygon) == 5 and k == 3)]
    return panel, corners


def deformation(X: np.ndarray) -> np.ndarray:
    """A smooth, cloth-like 3D deformation of rest points (..., 2), metres: 2 % stretch,
    2 % shear, an in-plane wave and a bulge of 5 cm over the 1 m short side."""
    x, y = X[..., 0], X[..., 1]
    return np.stack([1.02 * x + 0.02 * y, y + 0.01 * np.sin(2.0 * x),
                     0.05 * np.sin(np.pi * x / 2) * np.sin(np.pi * y)], axis=-1)


def _stvk(F: np.ndarray) -> np.ndarray:
    """StVK energy density (mu = lambda = 1) of deformation gradients F (Q, 3, 2)."""
    G = 0.5 * (np.einsum("qki,qkj->qij", F, F) - np.eye(2))
    return (G**2).sum(axis=(1, 2)) + 0.5 * np.trace(G, axis1=1, axis2=2) ** 2


def _integrate(X: np.ndarray, C: np.ndarray, pd) -> tuple[float, np.ndarray, float]:
    """Area, lumped masses (n*m,) and StVK energy over the points of pd."""
    n, m = X.shape[:2]
    ok = pd.idx >= 0
    masses = np.bincount(pd.idx[ok], (pd.N * pd.w[:, None])[ok], minlength=n * m)
    F = np.einsum("qad,qak->qkd", np.where(ok[..., None], pd.g, 0.0), C.reshape(-1, 3)[np.maximum(pd.idx, 0)])
    return float(pd.w.sum()), masses, float(pd.w @ _stvk(F))


def mass_matrix(X: np.ndarray, pd) -> "sp.csr_matrix":
    """Consistent mass matrix int N_a N_b dX (unit density) over the points of pd."""
    import scipy.sparse as sp

    n, m = X.shape[:2]
    ok = pd.idx >= 0
    N = np.where(ok, pd.N, 0.0) * np.sqrt(pd.w)[:, None]
    idx = np.maximum(pd.idx, 0)
    K = idx.shape[1]
    rows = np.repeat(idx, K, axis=1).ravel()
    cols = np.tile(idx, (1, K)).ravel()
    vals = (N[:, :, None] * N[:, None, :]).ravel()
    return sp.csr_matrix((vals, (rows, cols)), shape=(n * m, n * m))


def rule_quantities(X: np.ndarray, C: np.ndarray, quadrature: str):
    """Area and StVK energy with the membrane rule `quadrature`, mass matrix with 3 x 3 Gauss."""
    n, m = X.shape[:2]
    area, _, energy = _integrate(X, C, point_data(X, membrane_rule(quadrature, n, m)))
    return area, mass_matrix(X, point_data(X, gauss(n, m, 3))), energy


def linear_reference(X: np.ndarray, C: np.ndarray, fine: int = FINE) -> tuple[float, np.ndarray, float]:
    """Area, lumped masses and StVK energy from a fine linear FEM mesh of the patch (for
    checking gauss_reference)."""
    n, m = X.shape[:2]
    u = np.linspace(0.0, n - 2.0, fine * (n - 2) + 1)
    v = np.linspace(0.0, m - 2.0, fine * (m - 2) + 1)
    Bu, Bv = basis_matrix(u, n), basis_matrix(v, m)
    P = np.einsum("ai,bj,ijd->abd", Bu, Bv, X, optimize=True).reshape(-1, 2)
    W = np.einsum("ai,bj,ijd->abd", Bu, Bv, C, optimize=True).reshape(-1, 3)
    T = grid_faces(u.size, v.size)
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    e1, e2 = b - a, c - a
    area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    # Lumped masses: N_a at the triangle's edge midpoints (exact for quadratics) times area / 3.
    uv = np.stack(np.meshgrid(u, v, indexing="ij"), -1).reshape(-1, 2)
    masses = np.zeros(n * m)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        mid = 0.5 * (uv[T[:, i]] + uv[T[:, j]])
        masses += np.einsum("t,ti,tj->ij", area / 3.0, basis_matrix(mid[:, 0], n), basis_matrix(mid[:, 1], m), optimize=True).ravel()
    # Linear FEM deformation gradient per triangle: F = [w_b - w_a, w_c - w_a] [e1, e2]^-1.
    Dm = np.stack([e1, e2], axis=2)  # (T, 2, 2)
    Ds = np.stack([W[T[:, 1]] - W[T[:, 0]], W[T[:, 2]] - W[T[:, 0]]], axis=2)  # (T, 3, 2)
    F = Ds @ np.linalg.inv(Dm)
    return float(area.sum()), masses, float(np.abs(area) @ _stvk(F))


def gauss_reference(X: np.ndarray, C: np.ndarray) -> tuple[float, np.ndarray, float]:
    """Area, mass matrix and StVK energy with 6 x 6 Gauss points per knot span."""
    n, m = X.shape[:2]
    t, w = np.polynomial.legendre.leggauss(6)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    u = (np.arange(n - 2)[:, None] + t).ravel()
    v = (np.arange(m - 2)[:, None] + t).ravel()
    U, V = np.meshgrid(u, v, indexing="ij")
    Wt = np.outer(np.tile(w, n - 2), np.tile(w, m - 2))
    pd = point_data(X, Rule(U.ravel(), V.ravel(), Wt.ravel()))
    area, _, energy = _integrate(X, C, pd)
    return area, mass_matrix(X, pd), energy


def case(name: str, resolution: int, quadrature: str = "reduced") -> dict:
    polygon, (lu, lv) = shapes()[name]
    short = min(lu, lv)
    n = max(5, int(round((resolution - 2) * lu / short)) + 2)
    m = max(5, int(round((resolution - 2) * lv / short)) + 2)
    panel, corners = outline_panel(name, polygon, spacing=short / (resolution - 2) / 8)
    start = time.perf_counter()
    patch, rep = conform_panel(panel, ConformOptions(control_points=(n, m), corners=corners))
    seconds = time.perf_counter() - start
    X = patch.rest
    C = deformation(X)
    area, masses, energy = rule_quantities(X, C, quadrature)
    _, ref_masses, ref_energy = gauss_reference(X, C)
    return {
        "shape": name, "resolution": resolution, "control_points": f"{n}x{m}", "quadrature": quadrature,
        "area_error": abs(area - panel.area) / panel.area,
        "mass_error": float(sp.linalg.norm(masses - ref_masses) / sp.linalg.norm(ref_masses)),
        "energy_error": abs(energy - ref_energy) / ref_energy,
        "min_jacobian_ratio": rep["min_jacobian_ratio"],
        "boundary_error_mm": rep["boundary_error_mm"],
        "seconds": seconds,
    }


def run(resolutions, steps=None, quadrature="reduced") -> list[dict]:
    return [case(name, r, quadrature) for r in resolutions for name in shapes()]
