"""Flat triangle meshes of a rectangle for the linear FEM baseline.

- `grid_mesh`: a regular vertex grid split with alternating diagonals, the paper's fair
  layout for membrane tests (uniform diagonals lock more).
- `equilateral_mesh`: rows of near-equilateral triangles, every other row shifted by half
  a spacing and closed by half triangles on the sides; the layout on which linear
  bending is most accurate (paper section 6.2, plate benchmark).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..embedding import grid_faces


@dataclass
class TriangleMesh:
    """rest: (V, 2) material-space vertices in metres; faces: (T, 3) counter-clockwise;
    size: (width, height) of the rectangle [0, w] x [0, h] the mesh covers."""

    rest: np.ndarray
    faces: np.ndarray
    size: tuple[float, float]

    @property
    def n_vertices(self) -> int:
        return self.rest.shape[0]

    @property
    def normalized(self) -> np.ndarray:
        """(V, 2) rest coordinates divided by the size: the (s, t) in [0, 1]^2 pins use."""
        return self.rest / np.asarray(self.size, float)

    def areas(self) -> np.ndarray:
        """(T,) signed rest triangle areas, m^2 (positive for counter-clockwise faces)."""
        a, b, c = (self.rest[self.faces[:, k]] for k in range(3))
        e1, e2 = b - a, c - a
        return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])

    def interior_edges(self) -> np.ndarray:
        """Edges shared by two faces: (E, 4) vertices (x0, x1, x2, x3) with the edge
        x0-x1, x2 opposite it in the face where x0 -> x1 runs counter-clockwise, x3
        opposite it in the other face."""
        F = self.faces
        T = F.shape[0]
        # Directed half-edges (F[k], F[k+1]) with the opposite vertex F[k+2].
        tail = F.ravel()
        head = F[:, [1, 2, 0]].ravel()
        opp = F[:, [2, 0, 1]].ravel()
        n = self.n_vertices
        key = tail.astype(np.int64) * n + head
        rev = head.astype(np.int64) * n + tail
        order = np.argsort(key)
        pos = np.searchsorted(key[order], rev)
        pos = np.minimum(pos, 3 * T - 1)
        twin = order[pos]
        has = key[twin] == rev
        first = has & (tail < head)  # each interior edge once
        h = np.flatnonzero(first)
        return np.c_[tail[h], head[h], opp[h], opp[twin[h]]].astype(np.int64)

    def locate(self, point) -> tuple[int, np.ndarray]:
        """Face containing rest point (2,) and its barycentric coordinates (3,)."""
        p = np.asarray(point, float)
        a, b, c = (self.rest[self.faces[:, k]] for k in range(3))
        M = np.stack([b - a, c - a], axis=2)  # (T, 2, 2)
        lam = np.linalg.solve(M, (p - a)[..., None])[..., 0]
        bary = np.c_[1.0 - lam.sum(1), lam]
        k = int(np.argmax(bary.min(axis=1)))
        return k, bary[k]


def grid_mesh(size: tuple[float, float], resolution: tuple[int, int]) -> TriangleMesh:
    """An a x b vertex grid over [0, w] x [0, h] (vertex i * b + j at (i, j) spacing),
    with alternating diagonals (the same faces as the B-spline render mesh)."""
    a, b = resolution
    x = np.linspace(0.0, size[0], a)
    y = np.linspace(0.0, size[1], b)
    X, Y = np.meshgrid(x, y, indexing="ij")
    faces = grid_faces(a, b).astype(np.int64)
    mesh = TriangleMesh(np.c_[X.ravel(), Y.ravel()], faces, (float(size[0]), float(size[1])))
    return _orient(mesh)


def equilateral_mesh(size: tuple[float, float], n: int) -> TriangleMesh:
    """Near-equilateral triangles with `n` vertices along the width: rows spaced by
    about sqrt(3)/2 of the spacing; odd rows shifted by half a spacing and closed by
    vertices on the sides."""
    w, h = size
    dx = w / (n - 1)
    rows = max(1, int(round(h / (dx * np.sqrt(3.0) / 2.0))))
    y = np.linspace(0.0, h, rows + 1)
    even = np.linspace(0.0, w, n)
    odd = np.concatenate([[0.0], (np.arange(n - 1) + 0.5) * dx, [w]])
    pts, starts = [], []
    for r in range(rows + 1):
        xs = even if r % 2 == 0 else odd
        starts.append(sum(len(p) for p in pts))
        pts.append(np.c_[xs, np.full(xs.size, y[r])])
    faces = []
    for r in range(rows):
        A, B = pts[r][:, 0], pts[r + 1][:, 0]
        ia, ib = starts[r], starts[r + 1]
        i = j = 0
        # Zip the two rows: advance along the row whose next vertex comes first.
        while i < A.size - 1 or j < B.size - 1:
            if j == B.size - 1 or (i < A.size - 1 and A[i + 1] < B[j + 1] - 1e-12 * w):
                faces.append((ia + i, ia + i + 1, ib + j))
                i += 1
            elif i == A.size - 1 or B[j + 1] < A[i + 1] - 1e-12 * w:
                faces.append((ia + i, ib + j + 1, ib + j))
                j += 1
            else:  # aligned next vertices (the side columns): close a right triangle pair
                faces.append((ia + i, ia + i + 1, ib + j))
                i += 1
    mesh = TriangleMesh(np.concatenate(pts), np.asarray(faces, np.int64), (float(w), float(h)))
    return _orient(mesh)


def _orient(mesh: TriangleMesh) -> TriangleMesh:
    """Make every face counter-clockwise in the rest plane."""
    flip = mesh.areas() < 0.0
    mesh.faces[flip] = mesh.faces[flip][:, [0, 2, 1]]
    if np.any(np.abs(mesh.areas()) < 1e-14 * mesh.size[0] * mesh.size[1]):
        raise ValueError("degenerate triangle in the mesh")
    return mesh
