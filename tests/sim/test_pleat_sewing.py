"""A knife pleat sewn shut from a folded placement (conform/pleats.py): a skirt panel whose
top edge carries a GarmentCode-style knife pleat (two interleaved tucks) and a band sewn
along that edge to the flat cloth and the pleat's face. Checked every step with the
independent intersection test (tests/support/intersections.py)."""

from __future__ import annotations

import numpy as np
import pytest

from garment.scene import parse_scene

from garment.build import build_simulator

from tests.support.intersections import assert_garment_clean
from tests.support.panels import pleated


def _scene(tmp_path, face, dart=False, **garment):
    doc = {
        "garment": [{"name": "g", "source": str(pleated(tmp_path / "pleat.obj", face, dart)), "knot_span_mm": 40,
                     "seam_span_mm": 8, "seam_stiffness": 1e6, **garment}],
        "contact": {"dhat": 1e-3, "kappa": "adaptive", "mu": 0.0},
        "time": {"dt": 0.01, "frames": 30},
    }
    return build_simulator(parse_scene(doc, tmp_path / "pleat.toml"))


@pytest.mark.parametrize("face", ["last", pytest.param("first", marks=pytest.mark.slow)])
def test_a_folded_knife_pleat_sews_shut_with_its_layers_in_order(tmp_path, face):
    sim = _scene(tmp_path, face)
    assert [p.name for p in sim.model.pieces] == ["g.skirt", "g.band"]
    for step in range(30):
        sim.step()
        assert_garment_clean(sim.model.pieces, sim.C, f"step {step}")
    # No layer between a seam's two sides: no matched pair held open (from the flat
    # layout this pleat holds 5 open, 3-5 mm apart). What stays open is where three
    # layers meet at a root, each within a barrier's reach (dhat = 1 mm) of the next, so
    # below two reaches; it moves with the trajectory (the band's seams 0.9-1.4 mm over
    # steps 30-80), not towards a tighter value.
    assert sim.seam_pairs_held_open() == 0
    gaps = sim.seam_gaps()
    assert max(gaps.values()) < 2e-3, gaps


def test_the_band_waits_on_the_pleat_until_its_tucks_close(tmp_path):
    """`pleat_wait`: the band's samples on the pleat's face (seam3's, not the rest of
    it) carry no force until both tucks are within SewingOptions.pleat_wait_gap; then they pull
    for good, and a checkpoint keeps that."""
    assert all(not s.after for s in _scene(tmp_path, "last", pleat_wait=False).model.seams)
    sim = _scene(tmp_path, "last")  # on by default
    assert [tuple(sorted(s.after)) for s in sim.model.seams] == [(), (), (), (0, 1)]
    ((on_pleat, tucks),) = sim.model.sewing.faces
    start = sum(len(s.uv_a) for s in sim.model.seams[:3])
    assert np.all((on_pleat >= start) & (on_pleat < start + len(sim.model.seams[3].uv_a)))
    assert 2 <= len(on_pleat) <= len(sim.model.seams[3].uv_a) // 2  # the face, 2 of the band's 26 cm
    before = sim.model.seam.samples.gaps(sim.C)
    assert max(before[t].max() for t in tucks) > sim.model.sewing.options.pleat_wait_gap
    sim.step()
    assert not sim.model.seam.active[on_pleat].any() and sim.model.seam.active[start:on_pleat[0]].all()
    state = sim.state.copy()
    for _ in range(10):
        if sim.state.pleat_faces.all():
            break
        sim.step()
    assert sim.state.pleat_faces.all() and sim.model.seam.active[on_pleat].all()
    gaps = sim.model.seam.samples.gaps(sim.C)
    assert max(gaps[t].max() for t in tucks) <= sim.model.sewing.options.pleat_wait_gap * 1.5
    released = sim.state.copy()
    sim.state = state
    assert not sim.state.pleat_faces.any()
    sim.state = released
    assert sim.state.pleat_faces.all()


def test_a_dart_across_the_pleats_layers_waits_whole_for_its_tucks(tmp_path):
    """A seam of the skirt with itself from the pleat's tips down into it waits for the
    tucks with every sample, not only those on the pleated edge: pulled early, the layer
    between its legs is caught there (dress_knife's seam43, 3.3 mm open)."""
    sim = _scene(tmp_path, "last", dart=True)
    seams = sim.model.seams
    assert [tuple(sorted(s.after)) for s in seams] == [(), (), (), (0, 1), (0, 1)]
    start = np.cumsum([0] + [len(s.uv_a) for s in seams])
    faces = sim.model.sewing.faces
    assert len(faces) == 2
    on_dart, tucks = faces[1]
    np.testing.assert_array_equal(on_dart, np.arange(start[4], start[5]))  # all of it
    assert sorted((t.start, t.stop) for t in tucks) == [(start[0], start[1]), (start[1], start[2])]
    sim.step()
    assert not sim.model.seam.active[on_dart].any()
