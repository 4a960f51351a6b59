"""Seams: two separated panels are pulled together and held closed; stitched neighbours
never produce a barrier, and nothing passes through anything."""

from __future__ import annotations

import numpy as np

from garment.materials import PRESETS
from garment.model import Patch
from garment.scene import ContactSpec
from sim.seams import SeamSpec
from sim.simulator import Simulator
from tests.intersections import intersecting_pairs

N = 8


def _two_panels(gap: float, stiffness: float = 1e6) -> Simulator:
    a = Patch.rectangle("a", (0.2, 0.2), (N, N), (-0.2 - gap / 2, -0.1, 0.0), (1, 0, 0), (0, 1, 0))
    b = Patch.rectangle("b", (0.2, 0.2), (N, N), (gap / 2, -0.1, 0.0), (1, 0, 0), (0, 1, 0))
    t = np.linspace(0.0, N - 2.0, 30)
    seam = SeamSpec("a", np.c_[np.full(30, N - 2.0), t], "b", np.c_[np.zeros(30), t])
    return Simulator([a, b], [PRESETS["cotton"]] * 2, gravity=(0.0, 0.0, -9.81), dt=0.01,
                     contact=ContactSpec(enabled=True, adaptive_kappa=True), seams=[seam],
                     seam_stiffness=stiffness)


def test_seam_energy_is_the_gap_squared():
    sim = _two_panels(0.02)
    gaps = sim.seam.samples.gaps(sim.C)
    np.testing.assert_allclose(gaps, 0.02, rtol=1e-12)  # straight edges 2 cm apart
    w = sim.seam.samples.weights
    assert abs(w.sum() - 0.2) < 1e-12  # 0.2 m of seam
    assert abs(sim.seam.value(sim.C) - 0.5 * 1e6 * 0.2 * 0.02**2) < 1e-9


def test_open_seam_closes_and_stays_closed_without_barriers():
    sim = _two_panels(0.03)
    fa, fb = sim.pieces[0].topology.faces, sim.pieces[1].topology.faces
    for _ in range(15):
        st = sim.step()
        xa, xb = sim.positions("a"), sim.positions("b")
        assert intersecting_pairs(xa, fa, xb, fb) == 0
        assert intersecting_pairs(xa, fa) == 0 and intersecting_pairs(xb, fb) == 0
    # Closed to well under 1 mm, and the touching seam edges make no contact at all.
    assert sim.seam.samples.gaps(sim.C).max() < 1e-4
    assert st.extra["contact_count"] == 0
    assert st.extra["seam_gap_max"] == sim.seam.samples.gaps(sim.C).max()  # reported per step
    assert st.converged
