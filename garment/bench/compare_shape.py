"""Shape measures between a B-spline and a linear FEM final state (compare benchmark).

All sample the cloth at material points (s, t) in [0, 1]^2 of the flat rest sheet, so the
two discretisations are compared at the same pieces of cloth:

- `hausdorff_mm`: symmetric Hausdorff distance between the two point clouds (B-spline
  surface at the linear mesh's vertices' material points vs the linear vertices): the
  shapes, whatever slides tangentially; resolution-limited to about the vertex spacing.
- `material_rms_mm` / `material_max_mm`: distance between the same material point on the
  two surfaces.
- `folds`: prominent (>= 2 mm) extrema of the out-of-plane coordinate along a line of
  material points (the vertical centre line of a hanging sheet crosses each wrinkle
  layer once).
- `max_dihedral_deg`: the largest dihedral angle between adjacent triangles of the
  surface mesh (the B-spline's render mesh, the linear mesh itself): a crease measure.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import LinearNDInterpolator
from scipy.signal import find_peaks
from scipy.spatial import cKDTree

from sim.embedding import interpolation_matrix
from sim.linear.mesh import TriangleMesh

FOLD_PROMINENCE = 2e-3  # m


def bspline_at(sim, st: np.ndarray) -> np.ndarray:
    """(P, 3) points of the first cloth of a B-spline Simulator at material points st
    (P, 2); rectangle patches have an affine rest map, so u = s (n - 2)."""
    piece = sim.model.pieces[0]
    n, m = piece.patch.shape
    W = interpolation_matrix(st[:, 0] * (n - 2), st[:, 1] * (m - 2), n, m, 0, sim.model.n_cp)
    return W @ sim.C


def linear_at(lin, st: np.ndarray) -> np.ndarray:
    """(P, 3) points of the first cloth of a LinearSimulator at material points st."""
    mesh = lin.model.pieces[0].mesh
    return LinearNDInterpolator(mesh.normalized, lin.C[lin.model.pieces[0].slice])(st)


def max_dihedral_deg(positions: np.ndarray, faces: np.ndarray, rest: np.ndarray) -> float:
    """Largest angle between the normals of two faces sharing an edge, degrees."""
    mesh = TriangleMesh(np.asarray(rest, float), np.asarray(faces, np.int64), (1.0, 1.0))
    quad = mesh.interior_edges()
    x0, x1, x2, x3 = (positions[quad[:, k]] for k in range(4))
    nA = np.cross(x1 - x0, x2 - x0)
    nB = np.cross(x3 - x0, x1 - x0)
    cos = np.einsum("ij,ij->i", nA, nB) / (np.linalg.norm(nA, axis=1) * np.linalg.norm(nB, axis=1))
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max())


def folds(points: np.ndarray, normal: np.ndarray) -> int:
    """Prominent extrema of points (P, 3) . normal along a sampled line."""
    y = points @ normal
    return int(len(find_peaks(y, prominence=FOLD_PROMINENCE)[0]) + len(find_peaks(-y, prominence=FOLD_PROMINENCE)[0]))


def compare(bs, lin, normal: np.ndarray, line: str = "centre") -> dict:
    """Shape measures between B-spline `bs` and linear `lin` final states (one cloth each)."""
    st = lin.model.pieces[0].mesh.normalized
    Pb, Pl = bspline_at(bs, st), lin.C[lin.model.pieces[0].slice]
    d_bl = cKDTree(Pl).query(Pb)[0]
    d_lb = cKDTree(Pb).query(Pl)[0]
    same = np.linalg.norm(Pb - Pl, axis=1)
    t = np.linspace(0.0, 1.0, 401)
    # Stay a hair inside the sheet: the interpolator returns NaN on the hull boundary.
    t = 1e-6 + (1.0 - 2e-6) * t
    samples = np.c_[np.full_like(t, 0.5), t] if line == "centre" else np.c_[t, t]
    b_top, l_top = bs.model.pieces[0].topology, lin.model.pieces[0].topology
    return {
        "hausdorff_mm": 1e3 * float(max(d_bl.max(), d_lb.max())),
        "material_rms_mm": 1e3 * float(np.sqrt(np.mean(same**2))),
        "material_max_mm": 1e3 * float(same.max()),
        "folds_bspline": folds(bspline_at(bs, samples), normal),
        "folds_linear": folds(linear_at(lin, samples), normal),
        "max_dihedral_deg_bspline": max_dihedral_deg(bs.positions(b_top.name), b_top.faces, b_top.rest),
        "max_dihedral_deg_linear": max_dihedral_deg(lin.C[lin.model.pieces[0].slice], l_top.faces, l_top.rest),
    }
