"""The control net: boundary rows from the side fits, the interior start, knot insertion.

Side order and orientation (garment.model.SIDES): v0 runs from corner 0 to corner 1 with u
increasing, u1 from corner 1 to 2 with v increasing, v1 from corner 2 to 3 with u
decreasing, u0 from corner 3 back to 0 with v decreasing. The boundary of a tensor-product
quadratic B-spline patch is the B-spline curve of its boundary control row, so a side fit
is exactly a boundary row.
"""

from __future__ import annotations

import numpy as np

from garment.model import Patch


def assemble_boundary(sides: list[np.ndarray]) -> np.ndarray:
    """(n, m, 2) net with the boundary rows from the four side curves (v0, u1, v1, u0,
    each in its loop direction); interior left as NaN."""
    v0, u1, v1, u0 = sides
    n, m = v0.shape[0], u1.shape[0]
    if v1.shape[0] != n or u0.shape[0] != m:
        raise ValueError("opposite sides need the same number of control points")
    X = np.full((n, m, 2), np.nan)
    X[:, 0] = v0
    X[n - 1, :] = u1
    X[:, m - 1] = v1[::-1]
    X[0, :] = u0[::-1]
    return X


def side_rows(X: np.ndarray) -> list[np.ndarray]:
    """The four boundary rows of a net in loop direction (inverse of assemble_boundary)."""
    return [X[:, 0], X[-1, :], X[::-1, -1], X[0, ::-1]]


def tangential_start(X: np.ndarray) -> np.ndarray:
    """Interior control points by the tangential projection of DESIGN.md section 4b.3.

    For interior (i, j): C1 interpolates linearly between the boundary points of column i
    (X[i, 0] and X[i, m-1]) at j's Greville fraction, C2 between those of row j (X[0, j]
    and X[n-1, j]) at i's; with the unit directions t1, t2 of those two segments,
    (t1 t1^T + t2 t2^T) C = t1 t1^T C1 + t2 t2^T C2: C keeps C1's coordinate along t1 and
    C2's along t2. Unlike plain averaging this does not invert spans on curved panels.
    """
    X = X.copy()
    n, m = X.shape[:2]
    s = Patch.greville(n) / (n - 2)
    t = Patch.greville(m) / (m - 2)
    i, j = np.meshgrid(np.arange(1, n - 1), np.arange(1, m - 1), indexing="ij")
    bot, top = X[i, 0], X[i, m - 1]
    left, right = X[0, j], X[n - 1, j]
    C1 = bot + t[j][..., None] * (top - bot)
    C2 = left + s[i][..., None] * (right - left)
    t1 = _unit(top - bot)
    t2 = _unit(right - left)
    A = t1[..., :, None] * t1[..., None, :] + t2[..., :, None] * t2[..., None, :]
    b = t1 * (t1 * C1).sum(-1, keepdims=True) + t2 * (t2 * C2).sum(-1, keepdims=True)
    # Nearly parallel directions make A singular: blend towards the plain average there.
    eps = 1e-3
    A = A + eps * np.eye(2)
    b = b + eps * 0.5 * (C1 + C2)
    X[1:-1, 1:-1] = np.linalg.solve(A, b[..., None])[..., 0]
    return X


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def refine_1d(P: np.ndarray) -> np.ndarray:
    """Knot insertion at every span midpoint of an open uniform quadratic B-spline with n
    control points (axis 0): 2n - 2 control points describing the same curve, parameter
    doubled (u_new = 2 u)."""
    n = P.shape[0]
    out = [P[0], 0.5 * (P[0] + P[1])]
    for i in range(1, n - 2):
        out.append(0.75 * P[i] + 0.25 * P[i + 1])
        out.append(0.25 * P[i] + 0.75 * P[i + 1])
    out += [0.5 * (P[n - 2] + P[n - 1]), P[n - 1]]
    return np.stack(out)


def refine(X: np.ndarray, axes=(0, 1)) -> np.ndarray:
    """Knot insertion at all span midpoints along the given axes of a net (n, m, d)."""
    for ax in axes:
        X = np.moveaxis(refine_1d(np.moveaxis(X, ax, 0)), 0, ax)
    return X
