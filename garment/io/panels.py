"""Read garment panels as triangle meshes: OBJ with a flat layout, or any mesh trimesh or
meshio reads.

OBJ (the convention of Codim-IPC's garment inputs, e.g. ../shared/assets/panels_dress_knife):
- `vt u v`: the flat rest layout of each vertex, metres.
- `v x y z`: the same vertex placed in 3D (optional: without `vt`, `v` must be flat).
- `g name` (or `o name`): starts a panel; its faces follow. Without groups every connected
  component is a panel (`panel0`, `panel1`, ...).
- `f a/at b/bt c/ct`: triangles (polygons are fanned); panel vertices are the distinct
  `vt` (or `v`) indices of the group's faces.
- `seam N` followed by N lines `stitch i j k w` (0-based `v` indices): vertex i is sewn to
  the point (1 - w) x_j + w x_k.

Other formats (PLY, OFF, STL, ...): the vertices must lie in one plane; the rest layout is
that plane's 2D coordinates and the 3D placement the vertices as given.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sim.errors import InputError
from sim.files import input_file
from sim.patches import Panel
from sim.seams.spec import PanelSeam

from ..units import LARGEST_M, other_unit
from .meshfile import read_mesh


def read_panels(path) -> tuple[list[Panel], list[PanelSeam]]:
    """Panels and seams of a mesh file; raises InputError naming the file."""
    path = input_file(path)
    panels, seams = _read_obj(path) if path.suffix.lower() == ".obj" else (_read_other(path), [])
    for p in panels:
        check_panel_size(p)
    return panels, seams


def check_panel_size(panel: Panel) -> None:
    """A panel (layout or placement) wider than a person could wear was not written in
    metres; conforming it at a knot span meant in metres would take minutes."""
    for what, points in (("layout", panel.rest), ("3D placement", panel.world)):
        extent = float(np.ptp(points, axis=0).max()) if points is not None and len(points) else 0.0
        if extent > LARGEST_M:
            guess = other_unit(extent, "m", None, LARGEST_M)
            hint = f"looks like {guess[0]}: convert it to metres (x {guess[1]:g})" if guess else "use metres"
            raise InputError(f"{panel.source}: panel {panel.name}: the {what} is {extent:.3g} m across; "
                             f"panel files are in metres ({hint})")


# --------------------------------------------------------------------------------- OBJ


def _index(token: str, count: int, path: Path, lineno: int) -> int:
    i = int(token)
    if i == 0:
        raise InputError(f"{path}:{lineno}: OBJ indices start at 1")
    if abs(i) > 2**40:
        raise InputError(f"{path}:{lineno}: index {token[:24]} is out of range")
    return i - 1 if i > 0 else count + i


def _numbers(tokens: list[str], count: int, path: Path, lineno: int) -> tuple[float, ...]:
    """The first `count` tokens as finite numbers (ValueError: too few or not numbers)."""
    if len(tokens) < count:
        raise ValueError
    values = tuple(float(t) for t in tokens[:count])
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{path}:{lineno}: non-finite number (NaN or inf) in {_excerpt(' '.join(tokens[:count]))}")
    return values


def _excerpt(line: str, limit: int = 80) -> str:
    """A line of the file for a message: quoted, escaped, at most `limit` characters."""
    line = line.strip()
    return repr(line if len(line) <= limit else line[:limit] + "...")


def _read_obj(path: Path) -> tuple[list[Panel], list[PanelSeam]]:
    v, vt = [], []
    groups: list[tuple[str, list]] = []  # (name, [(v index, vt index or -1) per face corner])
    stitches: list[tuple[int, list]] = []  # (line number, [(i, j, k, w)])
    current = None
    with open(path, "r", errors="backslashreplace") as f:
        for lineno, line in enumerate(f, 1):
            t = line.split()
            if not t or t[0].startswith("#"):
                continue
            try:
                key = t[0]
                if key == "v":
                    v.append(_numbers(t[1:], 3, path, lineno))
                elif key == "vt":
                    vt.append(_numbers(t[1:], 2, path, lineno))
                elif key in ("g", "o"):
                    current = (" ".join(t[1:]) or f"panel{len(groups)}", [])
                    groups.append(current)
                elif key == "f":
                    if current is None:
                        current = ("", [])
                        groups.append(current)
                    corners = []
                    for c in t[1:]:
                        parts = c.split("/")
                        vi = _index(parts[0], len(v), path, lineno)
                        ti = _index(parts[1], len(vt), path, lineno) if len(parts) > 1 and parts[1] else -1
                        corners.append((vi, ti))
                    if len(corners) < 3:
                        raise InputError(f"{path}:{lineno}: a face needs at least 3 vertices")
                    for a in range(1, len(corners) - 1):  # fan polygons into triangles
                        current[1].append((corners[0], corners[a], corners[a + 1]))
                elif key == "seam":
                    stitches.append((lineno, []))
                elif key == "stitch":
                    if not stitches:
                        raise InputError(f"{path}:{lineno}: 'stitch' before any 'seam' line")
                    w = _numbers(t[4:], 1, path, lineno)[0]
                    if not 0.0 <= w <= 1.0:
                        raise InputError(f"{path}:{lineno}: stitch weight {w:g} is not in [0, 1]")
                    stitches[-1][1].append((int(t[1]), int(t[2]), int(t[3]), w))
            except InputError:
                raise
            except (ValueError, IndexError, OverflowError):
                raise InputError(f"{path}:{lineno}: cannot read {_excerpt(line)}") from None
    V = np.asarray(v, float).reshape(-1, 3)
    VT = np.asarray(vt, float).reshape(-1, 2)
    groups = [g for g in groups if g[1]]
    if not groups:
        raise InputError(f"{path}: no faces")

    panels = []
    if len(groups) == 1 and groups[0][0] == "":
        # No groups: one panel per connected component.
        corners = np.asarray(groups[0][1])  # (F, 3, 2)
        for k, comp in enumerate(_components(corners[..., 1 if VT.size else 0])):
            panels.append(_obj_panel(f"panel{k}", corners[comp], V, VT, path))
    else:
        for name, faces in groups:
            panels.append(_obj_panel(name, np.asarray(faces), V, VT, path))
    names = [p.name for p in panels]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise InputError(f"{path}: panel names repeat: {', '.join(dup)}")
    return panels, _obj_seams(stitches, panels, V.shape[0], path)


def _components(faces: np.ndarray) -> list[np.ndarray]:
    """Face index arrays of the connected components (sharing vertices) of faces (F, 3)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    F = faces.shape[0]
    nv = int(faces.max()) + 1
    A = sp.csr_matrix((np.ones(3 * F), (np.repeat(np.arange(F), 3), faces.ravel())), shape=(F, nv))
    _, label = connected_components(A @ A.T, directed=False)
    return [np.nonzero(label == c)[0] for c in range(label.max() + 1)]


def _obj_panel(name: str, corners: np.ndarray, V, VT, path: Path) -> Panel:
    """corners (F, 3, 2): (v, vt) per face corner."""
    use_vt = VT.shape[0] > 0 and np.all(corners[..., 1] >= 0)
    key = corners[..., 1] if use_vt else corners[..., 0]
    bad = (key < 0) | (key >= (VT.shape[0] if use_vt else V.shape[0])) | (corners[..., 0] < 0) | (
        corners[..., 0] >= V.shape[0])
    if np.any(bad):
        raise InputError(f"{path}: panel {name}: a face refers to a vertex that does not exist")
    ids, faces = np.unique(key.ravel(), return_inverse=True)
    faces = faces.reshape(-1, 3)
    vidx = np.empty(ids.shape[0], np.int64)
    vidx[faces.ravel()] = corners[..., 0].ravel()  # the v of each panel vertex (last wins)
    if use_vt:
        rest, world = VT[ids], V[vidx]
    else:
        rest, world = _flatten(V[vidx], f"{path}: panel {name}")
    return Panel(name=name, source=str(path), rest=rest, faces=faces, world=world, vertex_ids=vidx)


def _obj_seams(stitches, panels: list[Panel], nv: int, path: Path) -> list[PanelSeam]:
    """`seam`/`stitch` blocks -> matched rest points, split where the panel pair changes."""
    owner = np.full(nv, -1)
    local = np.full(nv, -1)
    for p, panel in enumerate(panels):
        free = owner[panel.vertex_ids] < 0
        owner[panel.vertex_ids[free]] = p
        local[panel.vertex_ids[free]] = np.nonzero(free)[0]
    seams = []
    for s, (lineno, rows) in enumerate(stitches):
        if not rows:
            continue
        rows = np.asarray(rows, float)
        ijk = rows[:, :3].astype(np.int64)
        if np.any((ijk < 0) | (ijk >= nv)) or np.any(owner[ijk] < 0):
            raise InputError(f"{path}:{lineno}: seam {s}: a stitch refers to a vertex outside every panel")
        w = rows[:, 3]
        pa, pb, pk = owner[ijk[:, 0]], owner[ijk[:, 1]], owner[ijk[:, 2]]
        if np.any(pb != pk):
            raise InputError(f"{path}:{lineno}: seam {s}: a stitch edge joins vertices of two panels")
        breaks = np.nonzero((pa[1:] != pa[:-1]) | (pb[1:] != pb[:-1]))[0] + 1
        for part, rng in enumerate(np.split(np.arange(rows.shape[0]), breaks)):
            A, B = panels[pa[rng[0]]], panels[pb[rng[0]]]
            la, lj, lk = local[ijk[rng, 0]], local[ijk[rng, 1]], local[ijk[rng, 2]]
            wb = w[rng][:, None]
            vb = np.where(wb[:, 0] == 0.0, lj, np.where(wb[:, 0] == 1.0, lk, -1))
            seams.append(PanelSeam(
                name=f"seam{s}" + (f"_{part}" if len(breaks) else ""), panel_a=A.name, panel_b=B.name,
                points_a=A.rest[la], points_b=(1.0 - wb) * B.rest[lj] + wb * B.rest[lk],
                vertices_a=la, vertices_b=vb))
    return seams


# ------------------------------------------------------------------------- other formats


def _read_other(path: Path) -> list[Panel]:
    vertices, faces = read_mesh(path)
    panels = []
    for k, comp in enumerate(_components(faces)):
        ids, local = np.unique(faces[comp].ravel(), return_inverse=True)
        name = f"panel{k}"
        rest, world = _flatten(vertices[ids], f"{path}: panel {name}")
        panels.append(Panel(name=name, source=str(path), rest=rest, faces=local.reshape(-1, 3),
                            world=world, vertex_ids=ids))
    return panels


def _flatten(points: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    """2D coordinates of points (P, 3) that lie in one plane, and the points themselves."""
    if points.shape[0] < 3:
        raise InputError(f"{where}: only {points.shape[0]} vertices; a panel needs at least 3")
    c = points.mean(axis=0)
    _, s, vh = np.linalg.svd(points - c, full_matrices=False)
    diam = float(np.ptp(points, axis=0).max()) or 1.0
    off_plane = np.abs((points - c) @ vh[2]).max()
    if off_plane > 1e-6 * diam:
        raise InputError(f"{where}: the vertices are not flat (up to {off_plane:.3g} off their plane) "
                         "and the file gives no flat layout (OBJ 'vt')")
    if points.shape[0] >= 3 and np.ptp(points[:, 2]) <= 1e-12 * diam:
        return points[:, :2].copy(), points  # already in the xy plane: keep its coordinates
    return (points - c) @ vh[:2].T, points
