"""The band drawn through an opening too wide to rest on (garment/dress/drawstring.py),
on a two-piece tube round a solid of revolution whose girths are known exactly."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from garment.dress.drawstring import SNUG, draw_in
from sim.energies.drawstring import DrawstringEnergy
from tests.garment.dress.test_girth import N, body, polygon, tube


def two_halves(r: float, z0: float, z1: float):
    """The open tube of test_girth cut into two pieces along two vertical lines; the
    pieces repeat the cut's vertices bit for bit (sewn seams do), each vertex its own
    control point: [(name, V, F)]."""
    X, T = tube(r, z0, z1)
    column = np.arange(len(X)) % N
    pieces = []
    for name, keep in (("front", column <= N // 2), ("back", (column >= N // 2) | (column == 0))):
        faces = T[keep[T].all(axis=1)]
        used = np.unique(faces)
        index = -np.ones(len(X), np.int64)
        index[used] = np.arange(len(used))
        pieces.append((name, X[used], index[faces]))
    return pieces


def fake_sim(pieces):
    """What draw_in asks of a simulator: pieces with interpolation rows W (each vertex a
    control point of its own), their positions, the body and the drawstring energy."""
    V, F = body()
    offset, model_pieces, C = 0, [], []
    n = sum(len(X) for _, X, _ in pieces)
    for name, X, faces in pieces:
        W = sp.csr_matrix((np.ones(len(X)), (np.arange(len(X)), offset + np.arange(len(X)))), shape=(len(X), n))
        model_pieces.append(SimpleNamespace(name=name, W=W, topology=SimpleNamespace(faces=faces)))
        C.append(X)
        offset += len(X)
    C = np.concatenate(C)
    model = SimpleNamespace(pieces=model_pieces, drawstring=DrawstringEnergy(n))
    return SimpleNamespace(
        model=model, C=C, positions=lambda: {p.name: p.W @ C for p in model_pieces},
        obstacle_positions=lambda: {"body": V},
        topologies=lambda: [SimpleNamespace(name="body", faces=F, kind="obstacle")])


def test_an_opening_wider_than_the_trunk_gets_a_band_snug_round_the_body_where_it_sits():
    sim = fake_sim(two_halves(0.25, 0.7, 1.0))  # 157 cm round; the trunk at most 107 cm
    report = draw_in(sim, (0.6, 0.8))
    assert report is not None and sorted(report["panels"]) == ["back", "front"]
    assert report["opening_cm"] == pytest.approx(100 * polygon(0.25), abs=0.05)
    # At z = 1.0 m the body's profile runs from r = 0.17 (0.85 m) to 0.12 (1.05 m).
    girth = polygon(0.17 + (0.12 - 0.17) * 0.15 / 0.2)
    assert report["girth_at_opening_cm"] == pytest.approx(100 * girth, abs=0.05)
    band = sim.model.drawstring
    assert band.G.shape[0] == N == report["segments"]  # the top loop, every edge once
    assert band.lengths(sim.C).sum() == pytest.approx(polygon(0.25), rel=1e-12)
    band.set_time(0.6)
    assert band.rest.sum() == pytest.approx(polygon(0.25), rel=1e-12)  # no pull at first
    band.set_time(0.8)
    assert band.rest.sum() == pytest.approx(SNUG * girth, rel=1e-3)
    assert band.value(sim.C) > 0.0


def test_an_opening_the_hips_hold_gets_no_band():
    sim = fake_sim(two_halves(0.15, 0.7, 1.0))  # 94 cm round: narrower than the hips
    assert draw_in(sim, (0.6, 0.8)) is None and not sim.model.drawstring.active
