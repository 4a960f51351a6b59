"""The independent crossing check (garment/verify.py): its bounding-box candidates lose no
intersecting pair, against a test of every triangle pair."""

from __future__ import annotations

import numpy as np
import pytest

from garment.verify import _segments_hit_triangles, intersecting_triangles


def soup(rng, n: int, size: float, spread: float):
    """n random triangles of about `size` in a cube of `spread`, with a few 5x larger (an
    uneven mesh: the candidates' search radius is set by the largest)."""
    centres = rng.uniform(0.0, spread, (n, 1, 3))
    scale = np.where(rng.random((n, 1, 1)) < 0.05, 5.0 * size, size)
    V = (centres + scale * rng.standard_normal((n, 3, 3))).reshape(-1, 3)
    return V, np.arange(3 * n).reshape(n, 3)


def every_pair(V1, F1, V2, F2, same: bool) -> set:
    I, J = np.meshgrid(np.arange(len(F1)), np.arange(len(F2)), indexing="ij")
    I, J = I.ravel(), J.ravel()
    if same:
        I, J = I[I < J], J[I < J]
    A, B = V1[F1][I], V2[F2][J]
    hit = np.zeros(len(I), bool)
    for e in range(3):
        hit |= _segments_hit_triangles(A[:, e], A[:, (e + 1) % 3], B[:, 0], B[:, 1], B[:, 2])
        hit |= _segments_hit_triangles(B[:, e], B[:, (e + 1) % 3], A[:, 0], A[:, 1], A[:, 2])
    return set(zip(I[hit].tolist(), J[hit].tolist()))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_candidates_lose_no_intersecting_pair(seed):
    rng = np.random.default_rng(seed)
    V1, F1 = soup(rng, 300, 0.02, 0.3)
    V2, F2 = soup(rng, 250, 0.03, 0.3)
    expected = every_pair(V1, F1, V2, F2, same=False)
    assert len(expected) > 20  # enough crossings to lose some
    assert set(map(tuple, intersecting_triangles(V1, F1, V2, F2).tolist())) == expected
    within = every_pair(V1, F1, V1, F1, same=True)  # one mesh; no two of its triangles share a vertex
    assert len(within) > 20
    assert set(map(tuple, intersecting_triangles(V1, F1).tolist())) == within
