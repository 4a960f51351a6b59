"""Blocked seam pairs (sim/seams/contact.py): a pair whose merge would cross cloth is held
weakly only while cloth lies between its two sides or once they are nearly closed; with
nothing between them the seam keeps pulling them shut (a dart whose folded neighbours
refuse the one-pair merge, dress_knife's seam47)."""

from __future__ import annotations

import numpy as np

import sim.seams.contact as seams_mod
from sim.materials import PRESETS
from sim.model import ContactOptions, bspline_model
from sim.patches import Patch
from sim.simulator import Simulator

from tests.support.scenes import edge_seam, panel, two_panels

HOLD_GAP = 1e-4  # m: the sides' gap once moved together, below HOLD_BELOW x reach


def _with_layer(gap: float) -> Simulator:
    """two_panels(gap) plus a 10 cm wide vertical strip in the plane x = 0, standing
    between the facing sides of a and b over |y| < 0.05 m."""
    a = panel("a", (-0.2 - gap / 2, -0.1, 0.0))
    b = panel("b", (gap / 2, -0.1, 0.0))
    layer = Patch.rectangle("layer", (0.1, 0.04), (6, 5), (0.0, -0.05, -0.02), (0, 1, 0), (0, 0, 1))
    return Simulator(bspline_model([a, b, layer], [PRESETS["cotton"]] * 3, gravity=(0.0, 0.0, 0.0), dt=0.01,
                                   contact=ContactOptions(adaptive_kappa=True), seams=[edge_seam()],
                                   seam_stiffness=1e6))


def _every_merge_crosses(monkeypatch):
    """Every merge tested crosses cloth: update_blocked blocks every pair it tests, and
    sew refuses every merge."""
    monkeypatch.setattr(seams_mod, "cloth_crossings_at", lambda mesh, x, vertices, same: np.asarray(vertices))
    monkeypatch.setattr(seams_mod.ipctk, "has_intersections", lambda mesh, x: True)
    monkeypatch.setattr(seams_mod, "crossings_at", lambda mesh, x, n, labels: labels)


def test_blocked_pairs_are_held_only_where_cloth_lies_between_their_sides(monkeypatch):
    sim = _with_layer(0.006)  # sides 6 mm apart, within the block reach (10 d_hat)
    _every_merge_crosses(monkeypatch)
    sc, model = sim.model.seam_contact, sim.model
    model.blocked_pairs(sim.C)
    held = model.held_pairs(sim.C)
    assert (sc.state == seams_mod.BLOCKED).all()
    x = sc.W_own @ sim.C
    mid_y = 0.5 * (x[sc.pairs[:, 0], 1] + x[sc.pairs[:, 1], 1])
    between = np.abs(mid_y) < 0.05 - 1e-3
    outside = np.abs(mid_y) > 0.05 + 0.02  # clear of the strip's edge and its triangles
    assert between.sum() >= 5 and outside.sum() >= 5
    assert held[between].all()  # the strip separates their sides
    assert not held[outside].any()  # nothing does: the seam pulls them at full strength


def test_the_seam_pulls_blocked_pairs_fully_until_nearly_closed_then_holds_them(monkeypatch):
    # Through the step's wiring (Sewing.hold): a blocked pair with nothing between its
    # sides keeps its samples at full stiffness while open, and held_fraction once its
    # sides are within HOLD_BELOW of the block reach.
    sim = two_panels(0.006)
    _every_merge_crosses(monkeypatch)
    st = sim.step()
    sc, energy = sim.model.seam_contact, sim.model.seam
    assert st.extra["seam_pairs_blocked"] == len(sc.pairs)  # every pair tested is blocked
    assert energy.active.all() and not energy.held.any()  # ... and pulled at full strength
    reach = sim.model.sewing.options.block_reach * sim.model.barrier.dhat
    C = sim.C.copy()
    closed = sc.W_own @ C
    # Move b onto a, as if the seam had pulled the sides together: every pair is then held.
    shift = (closed[sc.pairs[:, 0]] - closed[sc.pairs[:, 1]]).mean(axis=0)
    C[sim.model.pieces[1].slice] += shift * (1.0 - HOLD_GAP / np.linalg.norm(shift))
    sim.model.blocked_pairs(C)
    held = sim.model.held_pairs(C)
    assert (sc.gaps(C) < seams_mod.HOLD_BELOW * reach).all()
    assert held.all()
