"""Panels and patches for the conforming and garment tests: grid meshes, polygon
outlines, panel OBJ files (garment/io/panels.py) with seams, malformed panels, and
measurements of conformed patches."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from conform.boundary import sample_polygon
from conform.curve_fit import evaluate
from sim.patches import Panel
from sim.bspline import basis_matrix


# ------------------------------------------------------------------ meshes and outlines


def grid(nx, ny, size=(0.2, 0.1), origin=(0.0, 0.0)):
    """Vertices (V, 2) and CCW triangles of an nx x ny vertex grid (vertex i * ny + j)."""
    x, y = np.meshgrid(np.linspace(0, size[0], nx), np.linspace(0, size[1], ny), indexing="ij")
    V = np.stack([x.ravel(), y.ravel()], 1) + origin
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    F = np.concatenate([np.stack([a, a + ny, a + ny + 1], 1), np.stack([a, a + ny + 1, a + 1], 1)])
    return V, F


def polygon_panel(name, poly, spacing=0.005, hints=True):
    """An outline panel sampled along the polygon, its vertices as corner hints."""
    rest, idx = sample_polygon(poly, spacing)
    return Panel(name=name, source="test", rest=rest, corner_hints=idx if hints else None)


# ------------------------------------------------------------------ panel OBJ files


def face_lines(name, F):
    """An OBJ group of triangles F (1-based ids, the same for v and vt)."""
    return [f"g {name}"] + [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in F]


def write_obj(path, panels, seams=()):
    """panels: [(name, V2 (k, 2), F (f, 3) local)] -> OBJ with v (lifted to z = 0.5 y,
    a sheared placement), vt = rest, one group per panel; seams: [[(i, j, k, w), ...]]."""
    lines, offset = [], 0
    faces = []
    for name, V, F in panels:
        for x, y in V:
            lines.append(f"v {x:.9g} {y:.9g} {0.5 * y:.9g}")
            lines.append(f"vt {x:.9g} {y:.9g}")
        faces.append((name, F + offset + 1))
        offset += len(V)
    for name, F in faces:
        lines += face_lines(name, F)
    for stitches in seams:
        lines.append(f"seam {len(stitches)}")
        lines += [f"stitch {i} {j} {k} {w}" for i, j, k, w in stitches]
    path.write_text("\n".join(lines) + "\n")
    return path


def bad_panels():
    """{name: (V, F, fragment of the error message)}: panels conforming must refuse."""
    V, F = grid(6, 5)
    out = {}
    # A hole: drop the two triangles of one interior cell.
    cell = 2 * 4 + 2
    keep = np.setdiff1d(np.arange(len(F)), [cell, cell + len(F) // 2])
    out["hole"] = (V, F[keep], "hole")
    # Two separate pieces.
    V2, F2 = grid(3, 3, (0.05, 0.05), (0.5, 0.0))
    out["two_pieces"] = (np.concatenate([V, V2]), np.concatenate([F, F2 + len(V)]), "2 boundary loops")
    # A non-manifold edge: a third triangle on an interior edge.
    extra = np.concatenate([V, [[0.05, 0.2]]])
    out["nonmanifold"] = (extra, np.concatenate([F, [[F[7, 0], F[7, 1], len(V)]]]), "non-manifold edge")
    # A degenerate (zero-area) triangle.
    Vd = np.concatenate([V, [[0.1, -0.02], [0.14, -0.02], [0.18, -0.02]]])
    out["degenerate"] = (Vd, np.concatenate([F, [[len(V), len(V) + 1, len(V) + 2]]]), "degenerate")
    # Folded layout: one triangle flipped.
    Ff = F.copy()
    Ff[3] = Ff[3, ::-1]
    out["folded"] = (V, Ff, "folds over")
    # A band spiralling past a full turn: every triangle counter-clockwise, outline crossing.
    t = np.linspace(0, 2.4 * np.pi, 40)
    r0, r1 = 0.1 + 0.003 * t, 0.14 + 0.003 * t  # 2 cm further out per turn, 4 cm wide
    Vs = np.concatenate([np.stack([r0 * np.cos(t), r0 * np.sin(t)], 1), np.stack([r1 * np.cos(t), r1 * np.sin(t)], 1)])
    k = np.arange(39)
    Fs = np.concatenate([np.stack([k, k + 1, k + 41], 1), np.stack([k, k + 41, k + 40], 1)])
    out["spiral"] = (Vs, Fs, "crosses itself")
    # A single triangle: three boundary vertices.
    out["triangle"] = (np.array([[0, 0], [0.1, 0], [0, 0.1]], float), np.array([[0, 1, 2]]), "only 3 boundary vertices")
    return out


BIB_SPACING = 0.02


def bib(path: Path, width: float, height: float, plane: float, top: float) -> Path:
    """A panel OBJ: two width x height panels at y = +-plane whose top edges (z = top) are
    sewn together outside a central neck opening."""
    nx, nz = round(width / BIB_SPACING) + 1, round(height / BIB_SPACING) + 1
    flat, tris = grid(nx, nz, (width, height))
    n, lines = len(flat), []
    for y in (plane, -plane):
        lines += [f"v {x - width / 2:.6f} {y:.6f} {top - height + z:.6f}" for x, z in flat]
    lines += [f"vt {x:.6f} {z:.6f}" for _ in range(2) for x, z in flat]
    for k, name in enumerate(("front", "back")):
        lines += face_lines(name, tris + 1 + k * n)
    top_ids = np.arange(nx) * nz + nz - 1
    x = flat[top_ids, 0] - width / 2
    for side in (x <= -0.05, x >= 0.05):
        lines.append(f"seam {side.sum()}")
        lines += [f"stitch {a} {a + n} {a + n} 0" for a in top_ids[side]]
    path.write_text("\n".join(lines) + "\n")
    return path


PLEAT_DX, PLEAT_DZ = 0.005, 0.02  # grid spacing along and across the pleated edge


def pleated(path: Path, face: str = "last", dart: bool = False) -> Path:
    """skirt: 30 x 12 cm, its top edge pleated at x = 10-16 cm (roots 10 and 16, tips 12
    and 14 cm; each tuck sews 15 mm from its roots); band: 26 x 4 cm 1 cm above, sewn to
    the skirt's top edge but for the pleat's under layers: the face is its last layer
    (14-16 cm) or its first (10-12 cm, the fold mirrored). dart: a last seam from the two
    tips 2 cm down into the skirt, closing the middle layer below them."""
    DX, DZ = PLEAT_DX, PLEAT_DZ

    def sheet(width, height):
        nx, nz = round(width / DX) + 1, round(height / DZ) + 1
        return (*grid(nx, nz, (width, height)), nz)

    skirt, skirt_tris, nz = sheet(0.30, 0.12)
    band, band_tris, nzb = sheet(0.26, 0.04)
    lines = [f"v {x:.6f} 0 {z:.6f}" for x, z in skirt]
    lines += [f"v {x + 0.02:.6f} 0.01 {z + 0.13:.6f}" for x, z in band]
    lines += [f"vt {x:.6f} {z:.6f}" for x, z in skirt] + [f"vt {x:.6f} {z + 0.2:.6f}" for x, z in band]
    n = len(skirt)
    for name, tris, off in (("skirt", skirt_tris, 0), ("band", band_tris, n)):
        lines += face_lines(name, tris + 1 + off)

    def top(x):  # skirt vertex on the top edge at x
        return round(x / DX) * nz + nz - 1

    def bottom(x):  # band vertex on its bottom edge at x
        return n + round(x / DX) * nzb

    def seam(pairs):
        lines.append(f"seam {len(pairs)}")
        lines.extend(f"stitch {a} {b} {b} 0" for a, b in pairs)

    k = np.arange(4) * DX
    seam([(top(0.14 - d), top(0.10 + d)) for d in k])  # tuck: layer 2 onto layer 1
    seam([(top(0.16 - d), top(0.12 + d)) for d in k])  # tuck: layer 3 onto layer 2
    cut = 0.10 if face == "last" else 0.12  # the band takes layer 3 or layer 1
    seam([(bottom(x), top(x)) for x in np.arange(0.0, cut + 1e-9, DX)])
    seam([(bottom(x), top(x + 0.04)) for x in np.arange(cut, 0.26 + 1e-9, DX)])
    if dart:
        seam([(top(0.12), top(0.14)), (top(0.125) - 1, top(0.135) - 1)])
    path.write_text("\n".join(lines) + "\n")
    return path


# ------------------------------------------------------------------ conformed patches


def rest_points(X: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The rest map of control net X (n, m, 2) at parameters uv (k, 2)."""
    n, m = X.shape[:2]
    return np.einsum("ki,kj,ijd->kd", basis_matrix(uv[:, 0], n), basis_matrix(uv[:, 1], m), X)


def interval_length(X: np.ndarray, iv) -> float:
    """Rest length (m) of the patch boundary over a boundary interval."""
    row = {"v0": X[:, 0], "u1": X[-1, :], "v1": X[:, -1], "u0": X[0, :]}[iv.side]
    t = np.linspace(min(iv.t0, iv.t1), max(iv.t0, iv.t1), 400)
    return float(np.linalg.norm(np.diff(evaluate(row, t), axis=0), axis=1).sum())
