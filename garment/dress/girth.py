"""How far round a garment's openings and a body's trunk are: why a garment slid off.

A garment stays on a still body where an opening (a waistband, a neckline) is narrower
than the body somewhere below it. skirt_06 of the corpus has a 157 cm waistband (its
design's `waistband.waist` is 1.86 x the body's waist) on a trunk at most ~100 cm round:
nothing holds it up, and the report should say so in those terms.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components

# Heights of the trunk, as fractions of the body's height, searched for its widest girth:
# from about the crotch to below the armpits.
TRUNK = (0.45, 0.72)
LEVELS = 28


def open_edges(T: np.ndarray) -> np.ndarray:
    """(E, 2) edges of the triangle mesh T used by one triangle only."""
    E = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    edges, count = np.unique(E, axis=0, return_counts=True)
    return edges[count == 1]


def boundary_loops(X: np.ndarray, T: np.ndarray) -> list[np.ndarray]:
    """Vertex loops of the open edges of the triangle mesh (X, T)."""
    nxt: dict[int, list[int]] = {}
    for a, b in open_edges(T):
        nxt.setdefault(int(a), []).append(int(b))
        nxt.setdefault(int(b), []).append(int(a))
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, prev, v = [start], -1, start
        seen.add(start)
        while True:
            options = [w for w in nxt[v] if w != prev and w not in seen]
            if not options:
                break
            prev, v = v, options[0]
            loop.append(v)
            seen.add(v)
        if len(loop) >= 3:
            loops.append(np.array(loop))
    return loops


def loop_length(X: np.ndarray, loop: np.ndarray) -> float:
    P = X[loop]
    return float(np.linalg.norm(P - np.roll(P, -1, axis=0), axis=1).sum())


def trunk_girth(body_V: np.ndarray, body_F: np.ndarray, z: float, centre: np.ndarray) -> float | None:
    """Length (m) round the body's cross-section at height z that encloses `centre` (x, y):
    the trunk, not an arm beside it. None where no loop does (between the legs)."""
    return _girth(trimesh.Trimesh(body_V, body_F, process=False), z, centre)


def _girth(mesh: trimesh.Trimesh, z: float, centre: np.ndarray) -> float | None:
    segments = trimesh.intersections.mesh_plane(mesh, [0.0, 0.0, 1.0], [0.0, 0.0, z])
    if len(segments) == 0:
        return None
    a, b = segments[:, 0, :2], segments[:, 1, :2]
    # Which loop a segment belongs to: segments sharing an end point are connected.
    ends = np.round(np.concatenate([a, b]) / 1e-7).astype(np.int64)
    _, key = np.unique(ends, axis=0, return_inverse=True)
    key = key.ravel()
    n = len(a)
    joins = sp.coo_matrix((np.ones(n), (key[:n], key[n:])), shape=(key.max() + 1,) * 2)
    loop = connected_components(joins, directed=False)[1][key[:n]]
    # The loop a ray from the centre along +x crosses an odd number of times encloses it.
    cx, cy = centre
    dy = b[:, 1] - a[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (cy - a[:, 1]) / dy
        x_hit = a[:, 0] + t * (b[:, 0] - a[:, 0])
    crosses = ((a[:, 1] > cy) != (b[:, 1] > cy)) & (x_hit > cx)
    length = np.linalg.norm(b - a, axis=1)
    best = None
    for r in np.unique(loop):
        mine = loop == r
        if crosses[mine].sum() % 2 == 1:
            girth = float(length[mine].sum())
            best = girth if best is None else min(best, girth)  # the innermost enclosing loop
    return best


def trunk_centre(body_V: np.ndarray) -> np.ndarray:
    """(3,) the middle of the body's vertices between 45 and 65 % of its height (feet and
    hands held forward would pull a bounding box's centre off the trunk)."""
    lo, hi = body_V[:, 2].min(), body_V[:, 2].max()
    h = (body_V[:, 2] - lo) / (hi - lo)
    trunk = body_V[(h > 0.45) & (h < 0.65)]
    return 0.5 * (trunk.min(0) + trunk.max(0))


def widest_trunk(body_V: np.ndarray, body_F: np.ndarray, below: float | None = None) -> tuple[float, float] | None:
    """(girth m, height m) of the trunk where it is widest (hips or chest), at or below
    the height `below` when given, or None."""
    lo, hi = body_V[:, 2].min(), body_V[:, 2].max()
    bottom, top = lo + TRUNK[0] * (hi - lo), lo + TRUNK[1] * (hi - lo)
    top = top if below is None else min(top, below)
    if top < bottom:
        return None
    centre = trunk_centre(body_V)[:2]
    mesh = trimesh.Trimesh(body_V, body_F, process=False)
    found = [(g, z) for z in np.linspace(bottom, top, LEVELS) if (g := _girth(mesh, float(z), centre)) is not None]
    return max(found) if found else None


def loose_opening(X: np.ndarray, T: np.ndarray, body_V: np.ndarray, body_F: np.ndarray):
    """(loop, its length m, the trunk's widest girth below it m, at height m) when the
    garment's (X, T) top opening sits at the trunk's heights and is wider than the trunk
    everywhere below it (nothing can hold it up), else None. An opening above the trunk
    (a neckline, a collar's edge) rests on the shoulders and arms, whatever its length:
    upper_garment_06's 151 cm neckline round its sleeves' tops. Both in the simulator's
    frame (Z-up, m)."""
    loops = boundary_loops(X, T)
    if not loops:
        return None
    top = max(loops, key=lambda loop: X[loop, 2].mean())
    lo, hi = body_V[:, 2].min(), body_V[:, 2].max()
    z = float(X[top, 2].mean())
    if z > lo + TRUNK[1] * (hi - lo):
        return None
    widest = widest_trunk(body_V, body_F, below=z)
    if widest is None:
        return None
    length = loop_length(X, top)
    return (top, length, *widest) if length > widest[0] else None
