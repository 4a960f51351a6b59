"""The boundary loop of a panel, with the checks that make a panel conformable.

A panel is conformable when its rest layout is a topological disk: one connected piece,
manifold, no degenerate or flipped triangles, one boundary loop that does not cross itself
and has at least four vertices. Anything else raises PanelError naming the panel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.errors import InputError
from sim.patches import Panel


# Point pairs handled at once by the all-pairs loops below: about 100 MB of temporaries.
_PAIR_BLOCK = 2_000_000
_ALL_PAIRS = 1000  # hull points up to which the diameter compares all pairs


class PanelError(InputError):
    """A panel that cannot be conformed; the message names the file and the panel."""

    def __init__(self, panel: Panel, what: str):
        self.panel = panel.name
        super().__init__(f"{panel.source}: panel {panel.name}: {what}")


@dataclass
class Outline:
    """The counter-clockwise boundary loop of a panel.

    vertices: (B,) panel vertex index of each loop point; points: (B, 2) their rest
    positions, metres; s: (B + 1,) arc length at each point, closing back to the first;
    area: reference area of the panel (m^2); diameter: largest distance between two outline
    points (m).
    """

    vertices: np.ndarray
    points: np.ndarray
    s: np.ndarray
    area: float
    diameter: float

    @property
    def perimeter(self) -> float:
        return float(self.s[-1])

    def __len__(self) -> int:
        return self.points.shape[0]

    def at(self, s: np.ndarray) -> np.ndarray:
        """Points at arc lengths s (any real; wraps around the loop)."""
        s = np.mod(np.asarray(s, float), self.perimeter)
        closed = np.vstack([self.points, self.points[:1]])
        return np.stack([np.interp(s, self.s, closed[:, d]) for d in range(2)], axis=1)

    def segment(self, a: int, b: int) -> np.ndarray:
        """Loop points from position a to b inclusive, going forward (wrapping)."""
        B = len(self)
        idx = np.arange(a, a + (b - a) % B + 1) % B
        return self.points[idx]


def signed_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))


def polygon_area(points: np.ndarray) -> float:
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def sample_polygon(polygon, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along a closed polygon (K, 2), about `spacing` apart, and the index of each
    polygon vertex among them (an outline panel's corner hints)."""
    polygon = np.asarray(polygon, float)
    pts, corners = [], []
    for k in range(len(polygon)):
        a, b = polygon[k], polygon[(k + 1) % len(polygon)]
        count = max(int(np.ceil(np.linalg.norm(b - a) / spacing)), 1)
        corners.append(sum(len(p) for p in pts))
        pts.append(a + (np.arange(count) / count)[:, None] * (b - a))
    return np.concatenate(pts), np.asarray(corners)


def extract_outline(panel: Panel) -> Outline:
    """Check the panel and return its boundary loop (PanelError if not a disk)."""
    if panel.faces is None:
        return _outline_of_polygon(panel)
    return _outline_of_mesh(panel)


def _ids(panel: Panel, idx) -> str:
    ids = np.asarray(panel.vertex_ids)[np.atleast_1d(idx)]
    return ", ".join(str(int(i)) for i in ids[:6]) + (" ..." if len(ids) > 6 else "")


def _outline_of_mesh(panel: Panel) -> Outline:
    X, F = panel.rest, panel.faces
    if F.shape[0] == 0:
        raise PanelError(panel, "no triangles")
    if not np.all(np.isfinite(X)):
        raise PanelError(panel, "rest layout has non-finite coordinates")
    repeated = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    A = signed_areas(X, F)
    scale = float(np.median(np.abs(A))) if np.any(A != 0) else 0.0
    degenerate = repeated | (np.abs(A) <= 1e-6 * scale) | (scale == 0.0)
    if np.any(degenerate):
        k = int(np.nonzero(degenerate)[0][0])
        raise PanelError(panel, f"{int(degenerate.sum())} degenerate (zero-area) triangle(s), "
                                f"e.g. vertices {_ids(panel, F[k])}")
    if np.any(A < 0) and np.any(A > 0):
        flipped = A < 0 if (A < 0).sum() <= (A > 0).sum() else A > 0
        k = int(np.nonzero(flipped)[0][0])
        raise PanelError(panel, f"the rest layout folds over: {int(flipped.sum())} of {F.shape[0]} triangles "
                                f"are flipped, e.g. vertices {_ids(panel, F[k])}")
    if np.all(A < 0):  # a mirrored layout: orient the triangles counter-clockwise
        F = F[:, ::-1]
        A = -A

    # Edges: every undirected edge in at most two triangles, used once in each direction.
    directed = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    und = np.sort(directed, axis=1)
    key = und[:, 0] * (X.shape[0] + 1) + und[:, 1]
    uniq, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    if np.any(counts > 2):
        k = int(np.nonzero(counts[inverse] > 2)[0][0])
        raise PanelError(panel, f"{int((counts > 2).sum())} non-manifold edge(s) (in 3 or more triangles), "
                                f"e.g. the edge between vertices {_ids(panel, und[k])}")
    dkey = directed[:, 0] * (X.shape[0] + 1) + directed[:, 1]
    if np.unique(dkey).shape[0] != dkey.shape[0]:
        raise PanelError(panel, "triangles are not consistently oriented")
    boundary = directed[counts[inverse] == 1]
    if boundary.shape[0] == 0:
        raise PanelError(panel, "no boundary: the mesh is closed")

    # Boundary loops: each boundary vertex has exactly one outgoing boundary edge.
    out_deg = np.bincount(boundary[:, 0], minlength=X.shape[0])
    if np.any(out_deg > 1):
        v = np.nonzero(out_deg > 1)[0]
        raise PanelError(panel, f"non-manifold vertex (the boundary touches itself) at vertex {_ids(panel, v)}")
    nxt = np.full(X.shape[0], -1)
    nxt[boundary[:, 0]] = boundary[:, 1]
    loops, seen = [], np.zeros(X.shape[0], bool)
    for start in boundary[:, 0]:
        if seen[start]:
            continue
        loop = [start]
        seen[start] = True
        v = nxt[start]
        while v != start:
            if v < 0 or seen[v]:
                raise PanelError(panel, "the boundary edges do not form closed loops")
            loop.append(v)
            seen[v] = True
            v = nxt[v]
        loops.append(np.asarray(loop))
    if len(loops) > 1:
        pieces = _count_pieces(F, X.shape[0])
        sizes = ", ".join(str(len(lp)) for lp in loops)
        if pieces > 1:
            raise PanelError(panel, f"{len(loops)} boundary loops ({sizes} vertices) in {pieces} separate pieces; "
                                    "a panel must be one piece")
        areas = [polygon_area(X[lp]) for lp in loops]
        outer = int(np.argmax(areas))
        inner = [lp for k, lp in enumerate(loops) if k != outer]
        c = X[inner[0]].mean(axis=0)
        raise PanelError(panel, f"{len(inner)} hole(s) (inner boundary loops of "
                                f"{', '.join(str(len(lp)) for lp in inner)} vertices, the first around "
                                f"({c[0]:.4g}, {c[1]:.4g}) m); a panel must be a disk")
    loop = loops[0]
    if len(loop) < 4:
        raise PanelError(panel, f"only {len(loop)} boundary vertices; a patch needs at least 4 (one per corner)")
    area = float(A.sum())
    outline = _make(panel, loop, X[loop], area)
    loop_area = polygon_area(outline.points)
    _check_simple(panel, outline)
    if abs(loop_area - area) > 1e-6 * area:
        raise PanelError(panel, f"the rest layout overlaps itself (triangle area {area:.6g} m^2, "
                                f"outline area {loop_area:.6g} m^2)")
    return outline


def _count_pieces(F: np.ndarray, nv: int) -> int:
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    A = sp.csr_matrix((np.ones(F.size), (np.repeat(np.arange(F.shape[0]), 3), F.ravel())),
                      shape=(F.shape[0], nv))
    return int(connected_components(A @ A.T, directed=False)[0])


def _outline_of_polygon(panel: Panel) -> Outline:
    P = panel.rest
    if P.shape[0] < 4:
        raise PanelError(panel, f"only {P.shape[0]} outline points; a patch needs at least 4")
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    if np.any(seg <= 1e-12 * max(float(np.ptp(P, axis=0).max()), 1e-300)):
        raise PanelError(panel, "the outline repeats a point (zero-length edge)")
    area = polygon_area(P)
    outline = _make(panel, np.arange(P.shape[0]), P, panel.area if panel.area is not None else area)
    _check_simple(panel, outline)
    if area <= 0:
        raise PanelError(panel, "the outline runs clockwise or encloses no area")
    return outline


def diameter(points: np.ndarray) -> float:
    """Largest distance between two of the points (over their convex hull)."""
    from scipy.spatial import ConvexHull

    try:
        h = points[ConvexHull(points).vertices]
    except Exception:  # collinear points
        h = points[[np.argmin(points[:, 0]), np.argmax(points[:, 0]), np.argmin(points[:, 1]),
                    np.argmax(points[:, 1])]]
    if len(h) <= _ALL_PAIRS:
        d = h[:, None, :] - h[None, :, :]
        return float(np.sqrt((d**2).sum(-1).max()))
    # A finely sampled round outline has every point on its hull: all pairs of the
    # 99883 points of a circle skirt took 149 GiB. Rotating calipers: O(hull) instead.
    return _caliper_diameter(h)


def _caliper_diameter(h: np.ndarray) -> float:
    """Diameter of the convex polygon h (H, 2), counter-clockwise (scipy's hull order):
    the farthest pair is an antipodal pair, found by walking the far vertex j with the
    edge i -> i + 1."""
    x, y = h[:, 0].tolist(), h[:, 1].tolist()
    H = len(x)

    def height(i: int, k: int) -> float:  # twice the area of (i, i + 1, k)
        i1 = (i + 1) % H
        return (x[i1] - x[i]) * (y[k] - y[i]) - (y[i1] - y[i]) * (x[k] - x[i])

    best, j = 0.0, 1
    for i in range(H):
        while height(i, (j + 1) % H) > height(i, j):
            j = (j + 1) % H
        for a in (i, (i + 1) % H):
            best = max(best, (x[a] - x[j]) ** 2 + (y[a] - y[j]) ** 2)
    return float(np.sqrt(best))


def _make(panel: Panel, loop, pts, area) -> Outline:
    seg = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    diam = diameter(pts)
    return Outline(vertices=np.asarray(loop), points=np.ascontiguousarray(pts), s=s,
                   area=float(panel.area if panel.area is not None else area), diameter=diam)


def _check_simple(panel: Panel, outline: Outline) -> None:
    hits = self_intersections(outline.points)
    if hits:
        i, j = hits[0]
        p = outline.points[i]
        raise PanelError(panel, f"the outline crosses itself ({len(hits)} crossing(s), the first near "
                                f"({p[0]:.4g}, {p[1]:.4g}) m between boundary vertices "
                                f"{_ids(panel, outline.vertices[i])} and {_ids(panel, outline.vertices[j])})")


def self_intersections(P: np.ndarray) -> list[tuple[int, int]]:
    """Pairs (i, j), i < j, of non-adjacent segments P_i P_i+1 of the closed polygon P that
    intersect (touching counts). Candidates are the pairs whose boxes overlap, found by a
    sweep along x (segments sorted by their boxes' low x), not by testing all B^2 pairs:
    dress_04's 36 outlines took 3.4 s that way."""
    B = P.shape[0]
    a, b = P, np.roll(P, -1, axis=0)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    size = float(np.ptp(P, axis=0).max()) if B else 0.0
    tol = 1e-12 * size
    order = np.argsort(lo[:, 0], kind="stable")
    # Sorted segment k overlaps in x every later one up to `last[k]` (exclusive).
    last = np.searchsorted(lo[order, 0], hi[order, 0] + tol, side="right")
    count = np.maximum(last - np.arange(B) - 1, 0)
    out = []
    for rows in _blocks(count, _PAIR_BLOCK):
        n = count[rows]
        k = np.repeat(rows, n)
        kk = k + 1 + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
        ii, jj = np.minimum(order[k], order[kk]), np.maximum(order[k], order[kk])
        cand = ((jj - ii) % B != 1) & ((ii - jj) % B != 1)
        cand &= (lo[ii, 1] <= hi[jj, 1] + tol) & (lo[jj, 1] <= hi[ii, 1] + tol)
        ii, jj = ii[cand], jj[cand]
        p1, p2, q1, q2 = a[ii], b[ii], a[jj], b[jj]

        def orient(u, v, w):
            return (v[:, 0] - u[:, 0]) * (w[:, 1] - u[:, 1]) - (v[:, 1] - u[:, 1]) * (w[:, 0] - u[:, 0])

        d1, d2 = orient(q1, q2, p1), orient(q1, q2, p2)
        d3, d4 = orient(p1, p2, q1), orient(p1, p2, q2)
        cross = (d1 * d2 <= tol * size) & (d3 * d4 <= tol * size)
        out += [(int(x), int(y)) for x, y in zip(ii[cross], jj[cross])]
    return sorted(out)


def _blocks(count: np.ndarray, most: int):
    """Runs of consecutive indices of `count` whose counts sum to about `most` at most
    (one index alone may exceed it): the candidate arrays are built a block at a time."""
    start, total = 0, 0
    for k, c in enumerate(count.tolist()):
        if total and total + c > most:
            yield np.arange(start, k)
            start, total = k, 0
        total += c
    if start < len(count):
        yield np.arange(start, len(count))
