"""Which segments pass through which triangles: candidates found and tested in one numba
pass (sim/bvh.py), ipctk's exact predicates deciding where round-off could. Seam paths
against the 47.5K-triangle corpus body: 1,500 paths of 20 cm 2.7 s -> 0.05 s, 100 loops
against the body's 71K edges 1.05 -> 0.05 s (ipctk's broad phase before).

garment/verify.py keeps its own segment test on purpose: the independent crossing check
shares no code with the simulator it judges."""

from __future__ import annotations

import ipctk
import numpy as np

from . import bvh

# Where round-off could decide the answer (a segment in or near the triangle's plane, an
# end or crossing on a border: GarmentCode lays panels edge to edge and flat in one
# plane), ipctk's test with exact orientation predicates decides, as it does in the
# simulator's own intersection check; the float test decides the rest.
UNSURE = 1e-9
PAD = 1e-7  # of the tree's extent: its boxes grow by this much, so no unsure pair is missed


def crossing_pairs(x: np.ndarray, edges: np.ndarray, faces: np.ndarray, face_tree: bvh.Tree | None = None) -> np.ndarray:
    """(K, 2) (edge, face) index pairs whose segment x[edge] passes through the triangle
    x[face]; pairs sharing a vertex are left out (neighbours touch by construction).
    face_tree: the tree over x[faces] (`bvh.build`), where one serves many calls."""
    x = np.ascontiguousarray(x, float)
    edges = np.ascontiguousarray(edges, np.int64).reshape(-1, 2)
    faces = np.ascontiguousarray(faces, np.int64).reshape(-1, 3)
    if not len(edges) or not len(faces):
        return np.zeros((0, 2), np.int64)
    # The tree goes over the larger set: few long seam paths walk a body's triangles; a
    # body's many short edges are found under a few large loop triangles.
    over_faces = face_tree is not None or len(faces) >= len(edges)
    tree = face_tree or bvh.build(x, faces if over_faces else edges)
    found = bvh.crossings(x, edges, faces, *tree, PAD * _extent(tree), UNSURE, over_faces)
    keep = found[:, 2] == bvh.HIT
    for k in np.flatnonzero(~keep):
        (i, j), (a, b, c) = edges[found[k, 0]], faces[found[k, 1]]
        keep[k] = ipctk.is_edge_intersecting_triangle(x[i], x[j], x[a], x[b], x[c])
    pairs = found[keep, :2]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def _extent(tree: bvh.Tree) -> float:
    """The longest side of the tree's root box: what the boxes are padded in proportion to."""
    return float((tree.hi[1] - tree.lo[1]).max())


class Triangles:
    """A triangle mesh (V (n, 3) m, F (m, 3)) and its tree, built once for the many sets of
    segments tested against one body in a step (a seam route tries ten heights)."""

    def __init__(self, V: np.ndarray, F: np.ndarray):
        self.V = np.ascontiguousarray(V, float)
        self.F = np.ascontiguousarray(F, np.int64).reshape(-1, 3)
        self.tree = bvh.build(self.V, self.F) if len(self.F) else None
        self._edges = None

    @property
    def edges(self) -> np.ndarray:
        """(E, 2) the unique edges of the triangles."""
        if self._edges is None:
            F = self.F
            self._edges = np.unique(np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
        return self._edges

    def crossed(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(K, 2) (k, face) pairs whose segment p_k q_k (p, q (S, 3)) passes through the face."""
        if len(p) == 0 or len(self.F) == 0:
            return np.zeros((0, 2), np.int64)
        x = np.concatenate([np.stack([p, q], axis=1).reshape(-1, 3), self.V])
        edges = np.arange(2 * len(p)).reshape(-1, 2)
        return crossing_pairs(x, edges, self.F + 2 * len(p), self.tree)
