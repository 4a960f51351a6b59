"""A top opening too wide to rest on is drawn in with an elastic band.

Such a garment has nothing to rest on and slides off (skirt_06 of the corpus: its
waistband is 157 cm round, `waistband.waist` = 1.86 x the body's waist, on a trunk at
most 107 cm round). GarmentCode's sampler makes such waistbands on purpose, and
GarmentCodeData holds them to the body (attachment springs on `lower_interface` edges for
400 frames). Here the opening gets what a dressmaker would thread through it: an elastic
band (sim/energies/drawstring.py) along its edge, cut SNUG x the body's girth where the
opening sits and tightened while gravity comes on. It acts only where the garment could
not otherwise stay on (an opening at the trunk's heights wider than the trunk everywhere
below it, girth.loose_opening), found once the seams are sewn (the opening is then one
loop of the welded garment mesh), and the report says so (`drawstring`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..verify import stack_meshes, weld
from .girth import loose_opening, open_edges, trunk_centre, trunk_girth

# The band's rest length against the body's girth where the opening sits: an elastic cut
# a tenth short grips (at EA = 40 N, 4 N of tension round the waist).
SNUG = 0.9


def body_mesh(sim):
    """The bodies as they stand, stacked (V, F), or None without one."""
    body_pos = sim.obstacle_positions()
    bodies = [(body_pos[m.name], m.faces) for m in sim.topologies() if m.kind != "cloth"]
    return stack_meshes(bodies) if bodies else None


def draw_in(sim, window: tuple[float, float]) -> dict | None:
    """Thread the band through the garment's top opening when nothing below it could hold
    it up (girth.loose_opening); its rest length goes from the opening's length to SNUG x the body's
    girth at the opening's height over `window` (s). Returns the report entry, or None
    when the garment needs no band."""
    body = body_mesh(sim)
    pos = sim.positions()
    cloth = [(p, pos[p.name], p.topology.faces) for p in sim.model.pieces]
    if not cloth or body is None:
        return None
    V, F = stack_meshes([(X, T) for _, X, T in cloth])
    X, T, label = weld(V, F)
    found = loose_opening(X, T, *body)
    if found is None:
        return None
    loop, length, widest, _ = found
    z = float(X[loop, 2].mean())
    girth = trunk_girth(*body, z, trunk_centre(body[0])[:2]) or widest
    rows, names = _segments(cloth, label, loop)
    if not rows:
        return None
    G = sp.vstack(rows).tocsr()
    now = np.linalg.norm(G @ sim.C, axis=1)
    ratio = SNUG * girth / now.sum()
    sim.model.drawstring.draw(G, now, ratio * now, window)
    return {"panels": names, "opening_cm": round(100 * length, 1), "trunk_below_cm": round(100 * widest, 1),
            "girth_at_opening_cm": round(100 * girth, 1), "height_m": round(z, 3),
            "band_cm": round(100 * SNUG * girth, 1), "segments": int(G.shape[0])}


def _segments(cloth, label: np.ndarray, loop: np.ndarray) -> tuple[list, list[str]]:
    """The pieces' mesh edges along the welded loop: rows W[b] - W[a] of their ends'
    interpolation, and the pieces they lie on."""
    edges = {}  # welded (lo, hi) -> (piece, a, b)
    offset = 0
    for piece, X, F in cloth:
        for a, b in open_edges(F):
            u, v = label[offset + a], label[offset + b]
            edges[(min(u, v), max(u, v))] = (piece, a, b)
        offset += len(X)
    rows, names = [], []
    for u, v in zip(loop, np.roll(loop, -1)):
        hit = edges.get((min(u, v), max(u, v)))
        if hit is None:
            continue
        piece, a, b = hit
        rows.append(piece.W[b] - piece.W[a])
        if piece.name not in names:
            names.append(piece.name)
    return rows, names

