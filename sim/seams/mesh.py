"""Piece meshes that meet along seams, and the vertex groups a closed seam merges.

A sewn piece's contact (and export) mesh is its uv grid (sim/embedding.py) inside, and
along its boundary a ring of triangles zipped to the seams' matched points: each sewn
stretch of boundary carries the seam's samples (thinned to about the grid spacing and
subdivided where sparser), the same count on both sides, so the matched vertices of the
two panels are pairs. Once the seams are closed the simulator merges every pair into one
contact vertex (sim/seams/contact.py): the panels then share one vertex line, as a
stitched seam does, so stitched neighbours never create a barrier (ipctk never pairs
primitives that share a vertex) while every other pair near the seam keeps its barrier.

Boundary positions are measured by g, the perimeter in grid steps: the grid's boundary
vertices sit at integer g, counter-clockwise from u = v = 0 (v = 0, then u = U, v = V,
u = 0), so a seam may run along any part of the boundary, corners included. Seams that
run into a patch (darts whose legs the boundary fit left inside the panel) carry their
matched points as interior vertices; such a piece is triangulated by Delaunay (in grid
steps) over its grid, boundary loop and those points.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay

from ..embedding import grid_faces, points_at
from .spec import side_length

THIN = 0.5  # keep seam samples at least this many grid steps apart (on both sides)
CLEAR = 0.35  # drop grid boundary vertices closer than this (grid steps) to a seam vertex
SNAP = 0.2  # seam points closer than this (grid steps) share one vertex


class Perimeter:
    """The boundary of the parameter rectangle [0, U] x [0, V] of an a x b vertex grid."""

    def __init__(self, U: float, V: float, a: int, b: int):
        self.U, self.V, self.a, self.b = U, V, a, b
        self.corners = np.array([0.0, a - 1.0, a + b - 2.0, 2.0 * a + b - 3.0])
        self.length = 2.0 * (a + b - 2)

    def on_boundary(self, uv: np.ndarray) -> bool:
        u, v = uv[:, 0], uv[:, 1]
        tol = 1e-9 * max(self.U, self.V)
        return bool(np.all((np.abs(u) <= tol) | (np.abs(u - self.U) <= tol)
                           | (np.abs(v) <= tol) | (np.abs(v - self.V) <= tol)))

    def g(self, uv: np.ndarray) -> np.ndarray:
        """Perimeter coordinate of boundary points uv (N, 2)."""
        U, V, a, b = self.U, self.V, self.a, self.b
        u, v = uv[:, 0], uv[:, 1]
        du, dv = (a - 1) / U, (b - 1) / V
        tol = 1e-9 * max(U, V)
        g = np.full(len(uv), np.nan)
        on = [np.abs(v) <= tol, np.abs(u - U) <= tol, np.abs(v - V) <= tol, np.abs(u) <= tol]
        # Last assignment wins: a corner takes its later side's value, except u = v = 0 (0).
        g = np.where(on[3], self.corners[3] + (V - v) * dv, g)
        g = np.where(on[2], self.corners[2] + (U - u) * du, g)
        g = np.where(on[1], self.corners[1] + v * dv, g)
        g = np.where(on[0], u * du, g)
        if np.isnan(g).any():
            raise ValueError("seam sample off the patch boundary")
        return g

    def uv(self, g: np.ndarray) -> np.ndarray:
        """Boundary points (N, 2) at perimeter coordinates g (any real: taken mod length)."""
        U, V, a, b = self.U, self.V, self.a, self.b
        g = np.mod(g, self.length)
        c = self.corners
        side = np.searchsorted(c, g, side="right") - 1
        t = g - c[side]
        u = np.choose(side, [t * U / (a - 1), np.full_like(t, U), U - t * U / (a - 1), np.zeros_like(t)])
        v = np.choose(side, [np.zeros_like(t), t * V / (b - 1), np.full_like(t, V), V - t * V / (b - 1)])
        return np.c_[u, v]


def matched_points(ga: np.ndarray, gb: np.ndarray, per_a: Perimeter, per_b: Perimeter):
    """Seam samples (perimeter coordinates of both sides, matched) with the patch corners
    they pass added, thinned to THIN grid steps and subdivided to at most one grid step
    per interval, on both sides alike. Returns both sides' coordinates, unwrapped."""
    ga, gb = _unwrap(ga, per_a.length), _unwrap(gb, per_b.length)
    # Corners inside an interval (on either side) become samples, with the other side
    # interpolated, so the boundary keeps its corners.
    pa, pb, fixed = [ga[0]], [gb[0]], [True]
    for k in range(len(ga) - 1):
        cuts = []
        for g, per in ((ga, per_a), (gb, per_b)):
            lo, hi = sorted((g[k], g[k + 1]))
            for c in per.corners[None, :] + per.length * np.arange(-1, 2)[:, None]:
                for corner in c[(c > lo + 1e-9) & (c < hi - 1e-9)]:
                    cuts.append((corner - g[k]) / (g[k + 1] - g[k]))
        for t in sorted(cuts):
            pa.append(ga[k] + t * (ga[k + 1] - ga[k]))
            pb.append(gb[k] + t * (gb[k + 1] - gb[k]))
            fixed.append(True)
        pa.append(ga[k + 1])
        pb.append(gb[k + 1])
        fixed.append(k + 1 == len(ga) - 1)
    ga, gb = np.asarray(pa), np.asarray(pb)
    keep = [0]
    for k in range(1, len(ga)):
        far = min(abs(ga[k] - ga[keep[-1]]), abs(gb[k] - gb[keep[-1]])) >= THIN
        if fixed[k]:
            if not far and not fixed[keep[-1]]:
                keep[-1] = k  # a corner or the seam's end stays, its too-close predecessor goes
            else:
                keep.append(k)
        elif far:
            keep.append(k)
    ga, gb = ga[keep], gb[keep]
    out_a, out_b = [ga[:1]], [gb[:1]]
    for k in range(len(ga) - 1):
        q = max(int(np.ceil(max(abs(ga[k + 1] - ga[k]), abs(gb[k + 1] - gb[k])) - 1e-9)), 1)
        t = np.arange(1, q + 1) / q
        out_a.append(ga[k] + t * (ga[k + 1] - ga[k]))
        out_b.append(gb[k] + t * (gb[k + 1] - gb[k]))
    return np.concatenate(out_a), np.concatenate(out_b)


def matched_uv_points(uv_a: np.ndarray, uv_b: np.ndarray, step_a: np.ndarray, step_b: np.ndarray):
    """Matched samples (S, 2) of a seam that runs into its patches, in uv, thinned to THIN
    and subdivided to at most one grid step (step_*: uv size of a grid step) per interval
    on both sides alike, as matched_points does along the boundary."""
    da = np.linalg.norm(np.diff(uv_a, axis=0) / step_a, axis=1)
    db = np.linalg.norm(np.diff(uv_b, axis=0) / step_b, axis=1)
    ta, tb = np.r_[0.0, np.cumsum(da)], np.r_[0.0, np.cumsum(db)]
    keep = [0]
    for k in range(1, len(uv_a)):
        if min(ta[k] - ta[keep[-1]], tb[k] - tb[keep[-1]]) >= THIN:
            keep.append(k)
        elif k == len(uv_a) - 1:
            keep[-1:] = [k] if len(keep) > 1 else [0, k]  # the seam's end stays
    out_a, out_b = [uv_a[:1]], [uv_b[:1]]
    for i, j in zip(keep[:-1], keep[1:]):
        q = max(int(np.ceil(max(ta[j] - ta[i], tb[j] - tb[i]) - 1e-9)), 1)
        t = (np.arange(1, q + 1) / q)[:, None]
        out_a.append(uv_a[i] + t * (uv_a[j] - uv_a[i]))
        out_b.append(uv_b[i] + t * (uv_b[j] - uv_b[i]))
    return np.concatenate(out_a), np.concatenate(out_b)


def _unwrap(g: np.ndarray, period: float) -> np.ndarray:
    """Make consecutive perimeter coordinates continuous across g = 0."""
    d = np.diff(g)
    d -= period * np.round(d / period)
    return np.concatenate([g[:1], g[0] + np.cumsum(d)])


def seamed_mesh(U: float, V: float, resolution: tuple[int, int], sides: list[np.ndarray], place=None):
    """Mesh of one piece whose seams' points are vertices: per seam side, in seam order,
    either perimeter coordinates (S,) along the boundary (unwrapped) or uv points (S, 2)
    of a seam that runs into the patch. place(uv) -> (N, 2): the piece's flat rest shape
    at uv (None: uv itself), where the ring's triangles must not turn over.

    Returns uv (Nv, 2), faces (Nf, 3) counter-clockwise in uv like grid_faces, and per
    seam side the vertex index of each of its points."""
    a, b = resolution
    if a < 4 or b < 4:
        raise ValueError(f"a seamed piece needs a contact mesh of at least 4 x 4 vertices, not {a} x {b}")
    per = Perimeter(U, V, a, b)
    L = per.length
    # Outer loop (seam vertices, then the grid's boundary vertices clear of every seam)
    # and interior seam points, each found by position.
    # A point within SNAP grid steps of one already placed (where one seam ends and the
    # next begins) is that vertex: a shorter edge than d_hat would make a barrier between
    # a vertex and its own neighbour's edge, which no motion can relieve.
    outer_g, inner_uv = [], []
    step = _step(per)

    def vertex(g: float) -> int:
        g = float(np.mod(g, L))
        if outer_g:
            d = np.abs((np.asarray(outer_g) - g + L / 2) % L - L / 2)
            if d.min() < SNAP:
                return int(d.argmin())
        outer_g.append(g)
        return len(outer_g) - 1

    def point(uv: np.ndarray) -> int:
        if per.on_boundary(uv[None]):
            return vertex(per.g(uv[None])[0])
        if inner_uv:
            d = np.linalg.norm((np.asarray(inner_uv) - uv) / step, axis=1)
            if d.min() < SNAP:
                return -1 - int(d.argmin())
        inner_uv.append(uv)
        return -len(inner_uv)

    seam_vertices = [np.array([vertex(g) for g in side] if side.ndim == 1 else [point(p) for p in side], np.int64)
                     for side in sides]
    regular = np.arange(int(L), dtype=float)
    covered = np.zeros(len(regular), bool)
    for side in sides:
        if side.ndim == 1:
            for g0, g1 in zip(side[:-1], side[1:]):
                lo, hi = min(g0, g1), max(g0, g1)
                # Strictly inside a seam interval (unwrapped, so compare modulo L).
                for shift in (-L, 0.0, L):
                    covered |= (regular + shift > lo + 1e-9) & (regular + shift < hi - 1e-9)
    near = np.abs((regular[:, None] - np.array(outer_g)[None, :] + L / 2) % L - L / 2).min(axis=1, initial=np.inf)
    covered |= near < CLEAR
    for g in regular[~covered]:
        vertex(g)
    outer_g, inner_uv = np.array(outer_g), np.array(inner_uv, float).reshape(-1, 2)

    grid_uv, faces = _delaunay(per, outer_g, inner_uv) if len(inner_uv) else _zipped_ring(per, outer_g, place)
    n_grid = len(grid_uv)
    uv = np.concatenate([grid_uv, per.uv(outer_g), inner_uv])
    ids = [np.where(v >= 0, n_grid + v, n_grid + len(outer_g) - 1 - v) for v in seam_vertices]
    return uv, faces, ids


def _inner_grid(per: Perimeter) -> np.ndarray:
    """uv of the grid's vertices off the boundary, (i, j) for 1 <= i <= a-2, 1 <= j <= b-2."""
    a, b = per.a, per.b
    us, vs = np.linspace(0.0, per.U, a), np.linspace(0.0, per.V, b)
    I, J = np.meshgrid(np.arange(1, a - 1), np.arange(1, b - 1), indexing="ij")
    return np.c_[us[I.ravel()], vs[J.ravel()]]


def _zipped_ring(per: Perimeter, outer_g: np.ndarray, place=None):
    """The inner grid as it is, zipped to the outer loop by a ring of triangles: the inner
    grid's boundary loop placed at the perimeter coordinates of the outer vertices it faces.
    Where that order would turn a triangle over in the rest shape (place; a patch whose
    boundary wraps round a dart tip crowds its rows there), the zip advances on the other
    loop instead. Returns the inner grid's uv and all faces (outer loop numbered after the
    grid)."""
    a, b, L = per.a, per.b, per.length
    nj = b - 2
    idx = lambda i, j: (i - 1) * nj + (j - 1)  # noqa: E731
    c = per.corners
    loop = [(idx(1, 1), 0.0)]
    loop += [(idx(i, 1), float(i)) for i in range(2, a - 2)]
    loop += [(idx(a - 2, 1), c[1])] + [(idx(a - 2, j), c[1] + j) for j in range(2, b - 2)]
    loop += [(idx(a - 2, b - 2), c[2])] + [(idx(i, b - 2), c[2] + (a - 1 - i)) for i in range(a - 3, 1, -1)]
    loop += [(idx(1, b - 2), c[3])] + [(idx(1, j), c[3] + (b - 1 - j)) for j in range(b - 3, 1, -1)]
    inner_idx = np.array([v for v, _ in loop])
    inner_g = np.array([g for _, g in loop])

    n_inner = (a - 2) * nj
    order = np.argsort(outer_g, kind="stable")
    O = np.r_[order, order[:1]] + n_inner
    sO = np.r_[outer_g[order], outer_g[order[0]] + L]
    In = np.r_[inner_idx, inner_idx[:1]]
    sI = np.r_[inner_g, L]
    grid = _inner_grid(per)
    X = np.concatenate([grid, per.uv(outer_g)])
    if place is not None:
        X = place(X)

    def turns_over(t) -> bool:
        p, q, r = X[t[0]], X[t[1]], X[t[2]]
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]) <= 0.0

    ring = []
    i = j = 0
    while i < len(O) - 1 or j < len(In) - 1:
        outer = j == len(In) - 1 or (i < len(O) - 1 and sO[i + 1] <= sI[j + 1])
        if i < len(O) - 1 and j < len(In) - 1:
            along, across = (O[i], O[i + 1], In[j]), (O[i], In[j + 1], In[j])
            if turns_over(along if outer else across) and not turns_over(across if outer else along):
                outer = not outer
        if outer:
            ring.append((O[i], O[i + 1], In[j]))
            i += 1
        else:
            ring.append((O[i], In[j + 1], In[j]))
            j += 1
    faces = np.concatenate([grid_faces(a - 2, nj), np.asarray(ring, np.int64)]).astype(np.int32)
    return grid, faces


def _delaunay(per: Perimeter, outer_g: np.ndarray, inner_uv: np.ndarray):
    """Delaunay triangulation, in grid steps, of the inner grid (less its vertices within
    CLEAR of an interior seam point), the outer loop and the interior seam points.
    Returns the kept grid vertices' uv and all faces (grid, outer loop, interior points)."""
    grid, step = _inner_grid(per), _step(per)
    d = np.linalg.norm((grid[:, None, :] - inner_uv[None, :, :]) / step, axis=2).min(axis=1)
    grid = grid[d >= CLEAR]
    pts = np.concatenate([grid, per.uv(outer_g), inner_uv]) / step
    F = Delaunay(pts).simplices
    p0, p1, p2 = pts[F[:, 0]], pts[F[:, 1]], pts[F[:, 2]]
    area = 0.5 * ((p1[:, 0] - p0[:, 0]) * (p2[:, 1] - p0[:, 1]) - (p1[:, 1] - p0[:, 1]) * (p2[:, 0] - p0[:, 0]))
    F = np.where((area < 0.0)[:, None], F[:, [0, 2, 1]], F)[np.abs(area) > 1e-9]  # collinear boundary slivers go
    return grid, np.ascontiguousarray(F, dtype=np.int32)


def seam_meshes(shapes: dict, resolutions: dict, seams, rests: dict | None = None) -> tuple[dict, list]:
    """Meshes of the sewn pieces and the matched vertex pairs of every seam.

    shapes / resolutions: control-net shape (n, m) and contact-mesh grid (a, b) by piece
    name; seams: sim.seams.SeamSpec; rests: rest control nets (n, m, 2) by name, so no
    triangle turns over in the rest shape. Returns {name: (uv, faces)} for the pieces with
    a seam, and per seam (piece_a, vertices_a, piece_b, vertices_b), matched in order
    (less the pairs whose merge would pull an edge shut: _without_collapses)."""
    perimeters = {name: Perimeter(n - 2.0, m - 2.0, *resolutions[name]) for name, (n, m) in shapes.items()}
    sides: dict[str, list] = {}
    for s in seams:
        pa, pb = perimeters[s.piece_a], perimeters[s.piece_b]
        uv_a, uv_b = np.asarray(s.uv_a, float), np.asarray(s.uv_b, float)
        if pa.on_boundary(uv_a) and pb.on_boundary(uv_b):
            ga, gb = matched_points(pa.g(uv_a), pb.g(uv_b), pa, pb)
        else:
            ga, gb = matched_uv_points(uv_a, uv_b, _step(pa), _step(pb))
        sides.setdefault(s.piece_a, []).append(ga)
        sides.setdefault(s.piece_b, []).append(gb)
    meshes, vertices = {}, {}
    for name, gs in sides.items():
        per = perimeters[name]
        place = None if rests is None else partial(points_at, rests[name])
        uv, faces, seam_vertices = seamed_mesh(per.U, per.V, (per.a, per.b), gs, place)
        meshes[name] = (uv, faces)
        vertices[name] = iter(seam_vertices)
    # Seam sides were appended in seam order, a before b: hand them back the same way.
    pairs = [(s.piece_a, next(vertices[s.piece_a]), s.piece_b, next(vertices[s.piece_b])) for s in seams]
    closed = [] if rests is None else [k for k, s in enumerate(seams) if _closed_at_rest(s, rests)]
    return meshes, _without_collapses(meshes, pairs, closed)


def _closed_at_rest(seam, rests: dict) -> bool:
    """Whether the seam joins two pieces whose sides lie together in the rest frame (each
    sample within half the shorter side's length of its partner): a cut through one
    panel, whose pieces abut in the start layout too. (A dart's legs, one piece, meet
    only at its tip.)"""
    if seam.piece_a == seam.piece_b:
        return False
    a = points_at(rests[seam.piece_a], np.asarray(seam.uv_a, float))
    b = points_at(rests[seam.piece_b], np.asarray(seam.uv_b, float))
    return bool(np.linalg.norm(a - b, axis=1).max() < 0.5 * min(side_length(a), side_length(b)))


def _without_collapses(meshes: dict, pairs: list, closed=()) -> list:
    """The matched pairs, less each whose merge would join two vertices of one piece that
    share a mesh edge without being matched to each other. A point of one side matched
    to a stretch of the other would pull that edge to zero length and hold its seam open:
    a seam shorter than SNAP on one side (dress_00's shoulder, 0.15 grid steps on the
    front and 0.45 on the back), or a gathered seam cut to a grid step on its long side,
    whose short side's points crowd below SNAP (jumpsuit_777_02's back waist, 8.2 steps
    of torso on 2.4 of trouser: a pair held 5.1 mm open). The seam's samples still pull
    the stretch shut; its vertices merge one to one. The seams `closed` (indices: closed
    at rest, as a cut is) keep every pair and merge before the others: their pieces abut
    from the start, and a vertex left unmerged sits on the other piece's edge and starts
    them crossed (jumpsuit_777_02's 6 mm cut at the front waist between a 31 x 10 piece
    and a 5 x 5 one, 7 points on 4 vertices of the larger: 3 pairs dropped, 7 edges
    crossing)."""
    edges = {}
    for name, (_, faces) in meshes.items():
        E = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        edges[name] = set(map(tuple, E.tolist()))
    members: dict = {}  # merge class (a list of (piece, vertex)) of each matched vertex

    def collapses(A: list, B: list) -> bool:
        return any(p == q and u != w and (min(u, w), max(u, w)) in edges[p] for p, u in A for q, w in B)

    out = [None] * len(pairs)
    closed = set(closed)
    for i in sorted(closed) + [i for i in range(len(pairs)) if i not in closed]:
        name_a, va, name_b, vb = pairs[i]
        keep = np.ones(len(va), bool)
        for k, (u, w) in enumerate(zip(va.tolist(), vb.tolist())):
            A = members.get((name_a, u), [(name_a, u)])
            B = members.get((name_b, w), [(name_b, w)])
            if A is B:
                continue
            direct = name_a == name_b and (min(u, w), max(u, w)) in edges[name_a]  # a dart's own pair
            if i not in closed and collapses(A, B) and not (direct and len(A) == len(B) == 1):
                keep[k] = False
                continue
            A.extend(B)
            for key in A:
                members[key] = A
        out[i] = (name_a, va[keep], name_b, vb[keep])
    return out


def _step(per: Perimeter) -> np.ndarray:
    """uv size of one grid step."""
    return np.array([per.U / (per.a - 1), per.V / (per.b - 1)])


# --------------------------------------------------------------------------- merging

def merged_labels(n: int, pairs: np.ndarray) -> np.ndarray:
    """Class label (0..K-1) of each of n vertices, pairs (P, 2) joined (union-find, so
    junctions of several seams become one class)."""
    g = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(g, directed=False)[1]


def mean_rows(labels: np.ndarray) -> sp.csr_matrix:
    """(K, n) averaging of the rows in each class."""
    count = np.bincount(labels)
    return sp.csr_matrix((1.0 / count[labels], (labels, np.arange(len(labels)))), shape=(len(count), len(labels)))


def merged_faces(F: np.ndarray) -> np.ndarray:
    """Faces after merging: those with a repeated vertex (collapsed at a dart tip) and
    repeats of one triangle (both sides of a closed dart) dropped."""
    ok = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])
    F = F[ok]
    _, first = np.unique(np.sort(F, axis=1), axis=0, return_index=True)
    return np.ascontiguousarray(F[np.sort(first)], dtype=np.int32)
