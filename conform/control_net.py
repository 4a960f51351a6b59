"""The control net: boundary rows from the side fits, the interior start, knot insertion.

Side order and orientation (sim.patches.SIDES): v0 runs from corner 0 to corner 1 with u
increasing, u1 from corner 1 to 2 with v increasing, v1 from corner 2 to 3 with u
decreasing, u0 from corner 3 back to 0 with v decreasing. The boundary of a tensor-product
quadratic B-spline patch is the B-spline curve of its boundary control row, so a side fit
is exactly a boundary row.
"""

from __future__ import annotations

import numpy as np

from sim.patches import Patch
from sim.bspline import basis_matrix


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
    """Interior control points by the tangential projection of docs/design.md section 4b.3.

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


def laplace_start(X: np.ndarray, spans: tuple[float, float] | None = None) -> np.ndarray:
    """Interior control points solving the discrete Laplace equation of the control grid
    with the boundary rows fixed; spans (a, b), the mean span sizes along u and v, weight
    the u and v neighbours by 1 / a^2 and 1 / b^2 (an anisotropic grid stays harmonic)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    X = X.copy()
    n, m = X.shape[:2]
    wu, wv = (1.0, 1.0) if spans is None else (1.0 / spans[0] ** 2, 1.0 / spans[1] ** 2)
    ni, mi = n - 2, m - 2
    idx = np.arange(ni * mi).reshape(ni, mi)
    i, j = np.meshgrid(np.arange(ni), np.arange(mi), indexing="ij")
    rows, cols, vals = [idx.ravel()], [idx.ravel()], [np.full(ni * mi, 2 * wu + 2 * wv)]
    b = np.zeros((ni * mi, 2))
    for di, dj, w in ((1, 0, wu), (-1, 0, wu), (0, 1, wv), (0, -1, wv)):
        ii, jj = i + di, j + dj
        inside = (ii >= 0) & (ii < ni) & (jj >= 0) & (jj < mi)
        rows.append(idx[inside])
        cols.append(idx[ii[inside], jj[inside]])
        vals.append(np.full(int(inside.sum()), -w))
        # Neighbours on the boundary move to the right-hand side.
        out = ~inside
        b[idx[out]] += w * X[ii[out] + 1, jj[out] + 1]
    A = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(ni * mi,) * 2)
    X[1:-1, 1:-1] = splu(A).solve(b).reshape(ni, mi, 2)
    return X


def boundary_area(X: np.ndarray) -> float:
    """Area enclosed by the patch boundary (Green's theorem on the four side curves; exact:
    the integrand is polynomial on each span)."""
    t, w = np.polynomial.legendre.leggauss(3)
    total = 0.0
    for row in side_rows(X):
        k = row.shape[0]
        u = (np.arange(k - 2)[:, None] + 0.5 * (t[None, :] + 1.0)).ravel()
        ww = np.tile(0.5 * w, k - 2)
        p = basis_matrix(u, k) @ row
        dp = basis_matrix(u, k, 1) @ row
        total += 0.5 * float(np.sum(ww * (p[:, 0] * dp[:, 1] - p[:, 1] * dp[:, 0])))
    return total


def match_area(X: np.ndarray, area: float, iterations: int = 6) -> tuple[np.ndarray, float]:
    """Offset the boundary rows (corners excepted) along their outward normals by one
    common distance so the enclosed area equals `area`; returns the net and the offset (m).
    A least-squares side fit is close to area-neutral but not exactly; this removes the
    rest, so the patch keeps the panel's area (its mass) to round-off. The offset is found
    by secant steps, starting from area change / perimeter."""
    rows = side_rows(X)
    normals = []
    for r in rows:
        tang = np.gradient(r, axis=0)
        nrm = np.stack([tang[:, 1], -tang[:, 0]], axis=1)  # outward for a counter-clockwise loop
        normals.append(nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300))

    def moved(delta):
        Y = X.copy()
        new = []
        for r, nrm in zip(rows, normals):
            r = r.copy()
            r[1:-1] += delta * nrm[1:-1]
            new.append(r)
        Y[:, 0], Y[-1, :], Y[::-1, -1], Y[0, ::-1] = new
        return Y

    perimeter = sum(float(np.linalg.norm(np.diff(r, axis=0), axis=1).sum()) for r in rows)
    d0, a0 = 0.0, boundary_area(X)
    d1 = (area - a0) / perimeter
    for _ in range(iterations):
        if abs(area - a0) <= 1e-14 * abs(area) or d1 == d0:
            break
        a1 = boundary_area(moved(d1))
        slope = (a1 - a0) / (d1 - d0)
        d0, a0, d1 = d1, a1, d1 + (area - a1) / slope if slope != 0 else d1
    return moved(d0), d0
