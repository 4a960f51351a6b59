"""Seams between pieces: matched parameter samples -> seam energy samples.

A seam is (piece_a, uv_a (S, 2), piece_b, uv_b (S, 2)): uv_a[s] is sewn to uv_b[s]
(sim.patches.PatchSeam). Once closed, the two cloths meet edge to edge along it; their
contact meshes then share the seam's vertices (sim/seams/mesh.py, sim/seams/contact.py),
so the barrier never holds a closed seam open. With contact.seams = "band" the meshes are
plain grids and contact-mesh vertices near the same sample of both sides are excluded
from contact instead (excluded_pairs): cheaper, but cloth right next to a seam may cross.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..embedding import interpolation_matrix
from .energy import SeamSamples
from .spec import SeamSpec


def _rows(piece, uv, n_cp):
    n, m = piece.patch.shape
    uv = np.asarray(uv, float)
    return interpolation_matrix(uv[:, 0], uv[:, 1], n, m, piece.offset, n_cp)


def _arc_weights(points: np.ndarray) -> np.ndarray:
    """Length each sample stands for along the polyline through `points` (S, d)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    w = np.zeros(len(points))
    w[:-1] += 0.5 * seg
    w[1:] += 0.5 * seg
    return w


def seam_samples(seams: list[SeamSpec], pieces: dict, n_cp: int, rest: np.ndarray) -> SeamSamples:
    """Stacked samples of every seam; rest: (n_cp, 2) rest control points (weights)."""
    Na, Nb, w = [], [], []
    for s in seams:
        a = _rows(pieces[s.piece_a], s.uv_a, n_cp)
        b = _rows(pieces[s.piece_b], s.uv_b, n_cp)
        Na.append(a)
        Nb.append(b)
        # Both sides have (nearly) the same rest length; average them.
        w.append(0.5 * (_arc_weights(a @ rest) + _arc_weights(b @ rest)))
    return SeamSamples(sp.vstack(Na).tocsr(), sp.vstack(Nb).tocsr(), np.concatenate(w))


def nearest_pairs(sample_rest: np.ndarray, sample_seam: np.ndarray, pair_rest: np.ndarray,
                  pair_seam: np.ndarray) -> np.ndarray:
    """(S,) index of the matched contact-vertex pair nearest each seam sample, by rest
    position on side a within the same seam; -1 where the seam has no pairs."""
    out = np.full(len(sample_seam), -1, np.int64)
    for k in np.unique(pair_seam):
        s, p = np.flatnonzero(sample_seam == k), np.flatnonzero(pair_seam == k)
        if len(s):
            d = np.linalg.norm(sample_rest[s, None, :] - pair_rest[None, p, :], axis=2)
            out[s] = p[d.argmin(axis=1)]
    return out


def excluded_pairs(seams: list[SeamSpec], pieces: dict, vertex_offsets: dict, rest_vertices: dict,
                   n_cp: int, rest: np.ndarray, band: float = 2.5) -> set[tuple[int, int]]:
    """Contact-mesh vertex pairs (i < j) that must never collide: across each seam near the
    same sample, and among all pieces meeting at a junction (where seams of three or more
    panels end at one point, vertices of panels without a common seam meet too).

    rest_vertices[name]: (V, 2) rest positions of a piece's contact-mesh vertices;
    vertex_offsets[name]: index of its first vertex in the collision mesh.
    """
    pairs: set[tuple[int, int]] = set()
    ends = []  # (seam index, piece, rest position (S, 2), near-vertex lists) per seam side
    for k, s in enumerate(seams):
        sides = []
        for name, uv in ((s.piece_a, s.uv_a), (s.piece_b, s.uv_b)):
            X = rest_vertices[name]
            radius = band * _spacing(pieces[name])
            pts = _rows(pieces[name], uv, n_cp) @ rest  # sample rest positions
            d = np.linalg.norm(X[None, :, :] - pts[:, None, :], axis=2)  # (S, V)
            near = [vertex_offsets[name] + np.flatnonzero(row < radius) for row in d]
            sides.append(near)
            ends.append((k, name, pts, near, radius))
        for j in range(len(sides[0])):
            # Window of neighbouring samples, so bands overlap where samples are sparse.
            va = np.unique(np.concatenate(sides[0][max(j - 1, 0):j + 2]))
            vb = np.unique(np.concatenate(sides[1][max(j - 1, 0):j + 2]))
            _add_pairs(pairs, va, sides[1][j])
            # Within each side too: the seam allowance folds sharply where a seam pulls
            # (a fitted drape starts so), a crease of the cloth itself, not a contact.
            _add_pairs(pairs, va, va)
            _add_pairs(pairs, vb, vb)
    # Junctions: sample ends of different seams on one piece that nearly coincide.
    for a in range(len(ends)):
        ka, pa, Pa, na, ra = ends[a]
        for b in range(a + 1, len(ends)):
            kb, pb, Pb, nb, rb = ends[b]
            if ka == kb or pa != pb:
                continue
            d = np.linalg.norm(Pa[:, None, :] - Pb[None, :, :], axis=2)
            for i, j in zip(*np.nonzero(d < max(ra, rb))):
                # The partners across both seams meet here: exclude them from each other.
                other_a = ends[a ^ 1][3][i]
                other_b = ends[b ^ 1][3][j]
                _add_pairs(pairs, other_a, other_b)
                _add_pairs(pairs, other_a, nb[j])
                _add_pairs(pairs, other_b, na[i])
    return pairs


def _add_pairs(pairs: set, va, vb) -> None:
    """Add every (i, j), i in va, j in vb, i != j, as (min, max)."""
    I, J = np.meshgrid(np.asarray(va, np.int64), np.asarray(vb, np.int64), indexing="ij")
    I, J = I.ravel(), J.ravel()
    keep = I != J
    pairs.update(zip(np.minimum(I, J)[keep].tolist(), np.maximum(I, J)[keep].tolist()))


def _spacing(piece) -> float:
    """Mean edge length of a piece's contact mesh in the rest state, m."""
    X = piece.topology.rest
    f = piece.topology.faces
    e = np.linalg.norm(X[f[:, 1]] - X[f[:, 0]], axis=1)
    return float(e.mean())
