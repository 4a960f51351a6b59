"""The independent triangle-triangle intersection check for the tests: garment/verify.py
(no ipctk, no sim), plus helpers that read a simulator's pieces.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from garment.verify import intersecting_pairs, intersecting_triangles, shared_vertices  # noqa: F401


def stacked_cloth(pieces) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """A simulator's cloth pieces as one mesh: vertices W @ C, faces F, and the index of
    each face's piece (geometry read off the pieces, no simulator code)."""
    W = sp.vstack([p.W for p in pieces]).tocsr()
    faces, piece, offset = [], [], 0
    for k, p in enumerate(pieces):
        faces.append(p.topology.faces + offset)
        piece.append(np.full(len(p.topology.faces), k))
        offset += p.W.shape[0]
    return W, np.concatenate(faces), np.concatenate(piece)


def garment_intersections(pieces, C, body_vertices, body_faces) -> tuple[np.ndarray, int, int]:
    """A simulator's cloth at control points C: its vertices, and the intersecting triangle
    pairs cloth-body and cloth-cloth (sewn panels joined at their shared seam vertices)."""
    W, F, _ = stacked_cloth(pieces)  # the pieces' seam rows change when the seams merge
    x = W @ C
    if not np.all(np.isfinite(x)):
        return x, -1, -1
    return x, len(intersecting_triangles(x, F, body_vertices, body_faces)), len(intersecting_triangles(*shared_vertices(x, F)))


def assert_garment_clean(pieces, C, when: str, body_vertices=None, body_faces=None) -> np.ndarray:
    """garment_intersections asserted at one frame or step (`when`, e.g. "step 3"): every
    vertex finite, no garment-body pair, and no cloth-cloth pair (sewn panels share their
    seam vertices exactly; no other triangle pair may cross). Returns the vertices."""
    if body_vertices is None:
        body_vertices, body_faces = np.zeros((0, 3)), np.zeros((0, 3), int)
    x, body_pairs, cloth_pairs = garment_intersections(pieces, C, body_vertices, body_faces)
    assert np.all(np.isfinite(x)), when
    assert body_pairs == 0, f"garment-body intersection, {when}: {body_pairs} pairs"
    assert cloth_pairs == 0, f"cloth-cloth intersection, {when}: {cloth_pairs} pairs"
    return x
