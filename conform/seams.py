"""Seams between panels -> seams between patch boundaries (parameter samples and intervals).

Every seam point on a panel's outline is projected onto the nearest side curve of the
patch (sim.patches.SIDES); its parameter there is the patch parameter u (sides v0, v1)
or v (sides u0, u1). A point away from the boundary (a stitch inside a panel) is located
by inverting the rest map. Consecutive samples on one side form a BoundaryInterval; a seam
that turns a corner splits into two intervals meeting at the corner.
"""

from __future__ import annotations

import numpy as np

from sim.patches import SIDES, Patch
from sim.seams.spec import BoundaryInterval, PanelSeam, PatchSeam, side_length
from sim.bspline import basis_matrix

from .control_net import side_rows
from .curve_fit import project


def seam_hints(panel_name: str, seams: list[PanelSeam]) -> tuple[np.ndarray, np.ndarray]:
    """Rest positions of one panel's seam ends (preferred corners) and of every point on
    its darts (never corners). A dart is a seam sewing the panel to itself whose two sides
    meet (at the dart's tip); other seams of a panel with itself (a sleeve closed into a
    tube, pleats) give neither."""
    ends, avoid = [], []
    for s in seams:
        if s.panel_a == s.panel_b:
            if s.panel_a == panel_name and len(s.points_a):
                gap = np.linalg.norm(np.asarray(s.points_a) - np.asarray(s.points_b), axis=1)
                size = np.ptp(np.concatenate([s.points_a, s.points_b]), axis=0).max()
                if gap.min() <= 1e-3 * max(size, 1e-9):
                    avoid += [s.points_a, s.points_b]
            continue
        for panel, pts in ((s.panel_a, s.points_a), (s.panel_b, s.points_b)):
            if panel == panel_name and len(pts):
                ends.append(np.asarray(pts)[[0, -1]])
    cat = lambda L: np.concatenate(L) if L else np.zeros((0, 2))  # noqa: E731
    return cat(ends), cat(avoid)


def short_seams(panel_name: str, seams: list[PanelSeam], length: float) -> list[np.ndarray]:
    """Rest points (K, 2) of each side of a seam on this panel shorter than `length`
    (a dart or a tuck gives its two legs)."""
    out = []
    for s in seams:
        for panel, pts in ((s.panel_a, s.points_a), (s.panel_b, s.points_b)):
            pts = np.asarray(pts, float).reshape(-1, 2)
            if panel == panel_name and len(pts) > 1 and side_length(pts) < length:
                out.append(pts)
    return out


def below_resolution(seam: PanelSeam, fit: dict[str, float]) -> bool:
    """Whether the seam is shorter on both panels than their boundary fit tolerance (fit,
    metres by patch name): it then joins what the fitted boundaries hold as one point, and
    the seams on either side of it end there already. Kept, its samples pull that point
    to spots the neighbours' ends pull elsewhere, up to its own length apart, and it stays
    about 1 mm open however hard it pulls: GarmentCode's fitted shirts join front and back
    torso at the waist's side with a 1.46 mm and a 0.75 mm edge (jumpsuit_04's stitch39
    ended at rest at 1.003 mm, 0.86 mm and 0.998 mm in three runs)."""
    return all(side_length(pts) < fit[name] for name, pts in ((seam.panel_a, seam.points_a), (seam.panel_b, seam.points_b)))


def side_uv(side: int, t: np.ndarray, n: int, m: int) -> np.ndarray:
    """(u, v) of loop-direction parameter t on side index 0..3 of an (n, m) patch."""
    t = np.asarray(t, float)
    U, V = n - 2.0, m - 2.0
    z = np.zeros_like(t)
    return [np.stack([t, z], 1), np.stack([z + U, t], 1), np.stack([U - t, z + V], 1),
            np.stack([z, V - t], 1)][side]


def side_parameter(side: int, uv: np.ndarray) -> np.ndarray:
    """The patch parameter along a side: u on v0/v1, v on u0/u1."""
    return uv[:, 0] if side in (0, 2) else uv[:, 1]


def locate_boundary(X: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For rest points (K, 2): side index (K,), (u, v) (K, 2) and distance (K,) to the
    nearest point of the patch boundary."""
    n, m = X.shape[:2]
    best_d = np.full(points.shape[0], np.inf)
    side = np.zeros(points.shape[0], np.int64)
    uv = np.zeros((points.shape[0], 2))
    for k, row in enumerate(side_rows(X)):
        t, d = project(row, points)
        better = d < best_d
        best_d[better], side[better] = d[better], k
        uv[better] = side_uv(k, t[better], n, m)
    return side, uv, best_d


def invert(X: np.ndarray, points: np.ndarray, iterations: int = 20) -> np.ndarray:
    """(u, v) with X(u, v) = points, by Newton from the nearest sample of a fine grid."""
    n, m = X.shape[:2]
    gu = np.linspace(0, n - 2, 8 * (n - 2) + 1)
    gv = np.linspace(0, m - 2, 8 * (m - 2) + 1)
    G = np.einsum("ai,bj,ijd->abd", basis_matrix(gu, n), basis_matrix(gv, m), X, optimize=True).reshape(-1, 2)
    k = np.argmin(((points[:, None, :] - G[None]) ** 2).sum(-1), axis=1)
    u, v = gu[k // gv.size].copy(), gv[k % gv.size].copy()
    for _ in range(iterations):
        Bu, Bv = basis_matrix(u, n), basis_matrix(v, m)
        dBu, dBv = basis_matrix(u, n, 1), basis_matrix(v, m, 1)
        P = np.einsum("ki,kj,ijd->kd", Bu, Bv, X, optimize=True)
        Xu = np.einsum("ki,kj,ijd->kd", dBu, Bv, X, optimize=True)
        Xv = np.einsum("ki,kj,ijd->kd", Bu, dBv, X, optimize=True)
        J = np.stack([Xu, Xv], axis=2)
        step = np.linalg.solve(J, (points - P)[..., None])[..., 0]
        u = np.clip(u + step[:, 0], 0, n - 2)
        v = np.clip(v + step[:, 1], 0, m - 2)
    return np.stack([u, v], axis=1)


def _intervals(side: np.ndarray, uv: np.ndarray, n: int, m: int) -> list[BoundaryInterval]:
    out = []
    start = 0
    for k in range(1, side.size + 1):
        if k == side.size or side[k] != side[start]:
            s = int(side[start])
            if s >= 0:
                t = side_parameter(s, uv[start:k])
                out.append(BoundaryInterval(SIDES[s], float(t[0]), float(t[-1])))
            start = k
    # Runs on consecutive sides meet at their shared corner: extend both to it.
    corner_t = {0: (0.0, n - 2.0), 1: (0.0, m - 2.0), 2: (n - 2.0, 0.0), 3: (m - 2.0, 0.0)}
    for a, b in zip(out, out[1:]):
        ia, ib = SIDES.index(a.side), SIDES.index(b.side)
        if ib == (ia + 1) % 4:  # running with the loop: a's end corner is b's start
            a.t1, b.t0 = corner_t[ia][1], corner_t[ib][0]
        elif ia == (ib + 1) % 4:  # against the loop
            a.t1, b.t0 = corner_t[ia][0], corner_t[ib][1]
    # A lone sample on a corner may land on the neighbouring side: drop empty intervals.
    kept = [iv for iv in out if abs(iv.t1 - iv.t0) > 1e-9]
    return kept if kept else out[:1]


def map_seam(seam: PanelSeam, patches: dict[str, Patch], tolerance: dict[str, float]) -> PatchSeam:
    """The seam's matched points as patch parameters. tolerance: per patch, the distance
    (m) beyond which a point counts as inside the panel rather than on its boundary."""
    parts = []
    for name, pts in ((seam.panel_a, seam.points_a), (seam.panel_b, seam.points_b)):
        X = patches[name].rest
        n, m = X.shape[:2]
        side, uv, d = locate_boundary(X, np.asarray(pts, float))
        inside = d > tolerance[name]
        if inside.any():
            uv[inside] = invert(X, np.asarray(pts, float)[inside])
            side[inside] = -1
        parts.append((uv, _intervals(side, uv, n, m)))
    (uv_a, int_a), (uv_b, int_b) = parts
    return PatchSeam(seam.name, seam.panel_a, seam.panel_b, uv_a, uv_b, int_a, int_b)
