"""Discrete quadratic bending of Bergou et al. 2006 on the interior edges of a flat mesh.

M. Bergou, M. Wardetzky, D. Harmon, D. Zorin, E. Grinspun, "A Quadratic Bending Model
for Inextensible Surfaces", SGP 2006. For a flat rest state and isometric deformations
the hinge energy is exactly quadratic in the positions, E = 1/2 sum_e c_e |sum_i K_i x_i|^2,
with the cotangent weights

    K = (cot a1 + cot b1, cot a0 + cot b0, -cot a0 - cot a1, -cot b0 - cot b1)

for the edge x0-x1 with opposite vertices x2 (face A = x0 x1 x2) and x3 (face B), a_k /
b_k the rest angles at x_k in faces A / B. sum_i K_i x_i vanishes on every affine (flat
or rigidly moved) configuration and has length 2 |e| sin(theta / 2) for a dihedral angle
theta, so the Hessian c_e K K^T (x) I3 is constant and PSD.

Normalisation. Bergou's c_e = 3 / (A_1 + A_2) reproduces the discrete-shells hinge
energy, which on cylinders measures 3 x the smooth energy D/2 int (2H)^2 dA (tests:
grid and equilateral meshes, ratio 2.96-2.98 at 81 vertices a side, -> 3). The
B-spline cloth uses D/2 |Laplacian phi|^2 with D = E h^3 / (12 (1 - nu^2)), so for the
same bending model we take c_e = D / (A_1 + A_2): Bergou's form with D / 3. With it the
plate deflection converges to the Navier solution (tests/sim/test_linear_fem.py).

Written as the Laplacian bending of sim/energies/bending.py with one "point" per edge:
weight w_e = A_1 + A_2 (m^2) and coefficients lap_e = K / w_e (a discrete Laplacian,
1/m^2), so E = 1/2 sum_e w_e D |lap_e . x|^2 and the same code assembles the Hessian.
"""

from __future__ import annotations

import numpy as np

from ..energies import BendingEnergy
from ..rest import PointData
from .mesh import TriangleMesh


def _cot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Cotangent of the angle between 2D vectors u, v (E, 2)."""
    cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return np.einsum("ij,ij->i", u, v) / np.abs(cross)


def _area(p, q, r):
    u, v = q - p, r - p
    return 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def hinge_weights(mesh: TriangleMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interior edge stencils (E, 4), cotangent weights K (E, 4) and A_1 + A_2 (E,) m^2."""
    quad = mesh.interior_edges()
    x0, x1, x2, x3 = (mesh.rest[quad[:, k]] for k in range(4))
    e = x1 - x0
    a0, a1 = _cot(e, x2 - x0), _cot(-e, x2 - x1)
    b0, b1 = _cot(e, x3 - x0), _cot(-e, x3 - x1)
    K = np.c_[a1 + b1, a0 + b0, -(a0 + a1), -(b0 + b1)]
    return quad, K, _area(x0, x1, x2) + _area(x0, x1, x3)


def hinge_points(mesh: TriangleMesh) -> PointData:
    """Hinges as PointData: idx = hinge stencil, w = A_1 + A_2, lap = K / w."""
    quad, K, A = hinge_weights(mesh)
    E = quad.shape[0]
    return PointData(idx=quad, g=np.zeros((E, 4, 2)), lap=K / A[:, None], N=np.zeros((E, 4)), w=A,
                     det=np.ones(E))


def bergou_bending(mesh: TriangleMesh, stiffness: float, n_cp: int | None = None) -> BendingEnergy:
    """The constant-Hessian bending energy of `mesh` with bending stiffness D (N m)."""
    pts = hinge_points(mesh)
    return BendingEnergy(pts, np.full(pts.n_points, float(stiffness)), n_cp or mesh.n_vertices)
