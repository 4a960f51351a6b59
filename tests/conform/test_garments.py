"""Conforming the shared real inputs (../shared/assets): dress_knife's panel meshes and the
GarmentCode shirt and dress. A few panels run in the default set; whole garments are
marked slow (`pytest -m slow`). Targets (issue 5): no inverted quadrature point, boundary
fit error within max(1 mm, 0.5 % of the diameter), rest-area error < 0.1 % at 20 mm knot
spans. The < 2 s per panel target is timed by `garment bench conform-garments`, not here."""

from __future__ import annotations

import numpy as np
import pytest

from conform import ConformOptions, conform_all
from garment.bench import conform as conform_bench
from garment.io.garmentcode import euler_xyz, read_garmentcode
from garment.io.panels import read_panels

from tests.support.panels import interval_length
from tests.support.paths import SHARED_ASSETS

DRESS_KNIFE = SHARED_ASSETS / "panels_dress_knife" / "stage.obj"
SHIRT = SHARED_ASSETS / "patterns_garmentcode" / "shirt_mean_specification.json"
DRESS = SHARED_ASSETS / "patterns_garmentcode" / "dress_pencil_specification.json"

needs_assets = pytest.mark.skipif(not DRESS_KNIFE.exists() or not SHIRT.exists(), reason="shared assets missing")


def check_targets(ps, reduced_area_pct=0.1, slow_ok=()):
    assert not ps.failures
    for p in ps.patches:
        q = ps.quality[p.name]
        assert q["inverted_points"] == 0 and q["min_jacobian_ratio"] > 0, p.name
        assert q["boundary_error_mm"] < q["tolerance_mm"], p.name
        assert q["tolerance_mm"] == pytest.approx(max(1.0, 0.5e-2 * q["panel_diameter_mm"]), rel=1e-9)
        assert abs(q["area_error_gauss2_pct"]) < 0.1, p.name  # the patch's exact area
        if p.name not in slow_ok:
            assert abs(q["area_error_reduced_pct"]) < reduced_area_pct, p.name
        # A placement with folded pleats bends over a few knot spans (conform/pleats.py).
        assert q["lift_max_strain"] < (0.1 if q.get("pleat_folds") else 1e-3), p.name


@needs_assets
def test_dress_knife_reads():
    panels, seams = read_panels(DRESS_KNIFE)
    assert [p.name for p in panels] == [f"panel{k}" for k in range(14)]
    assert sum(len(p.faces) for p in panels) == 29456 and sum(len(p.rest) for p in panels) == 15656
    assert sum(len(s.points_a) for s in seams) == 851
    # 3D and 2D edge lengths agree (the placement is near-isometric).
    p = panels[0]
    e = p.faces[:, [0, 1]]
    l2 = np.linalg.norm(np.diff(p.rest[e], axis=1), axis=-1)
    l3 = np.linalg.norm(np.diff(p.world[e], axis=1), axis=-1)
    assert np.abs(l3 / l2 - 1).max() < 2e-3


@needs_assets
def test_garmentcode_reads_with_exact_areas_and_placement():
    panels, seams = read_garmentcode(SHIRT)
    assert len(panels) == 8 and len(seams) == 18
    for p in panels:
        x, y = p.rest[:, 0], p.rest[:, 1]
        polygon = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        assert polygon == pytest.approx(p.area, rel=2e-4)  # dense outline vs exact curves
        assert polygon > 0  # counter-clockwise
    # GarmentCode's rotation convention: R = Rz Ry Rx.
    R = euler_xyz([90, 0, 90])
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(R @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    # Sewn edges meet in 3D better when the second edge runs backwards (the convention).
    by = {p.name: p for p in panels}
    s = seams[16]  # right_ftorso - left_ftorso: the centre front
    a, b = by[s.panel_a].place(s.points_a), by[s.panel_b].place(s.points_b)
    assert np.linalg.norm(a - b, axis=1).max() < 1e-6


@needs_assets
def test_some_dress_knife_panels_meet_the_targets():
    panels, seams = read_panels(DRESS_KNIFE)
    chosen = [p for p in panels if p.name in ("panel3", "panel6", "panel10")]
    ps = conform_all(chosen, seams, ConformOptions(knot_span=0.02))
    check_targets(ps)
    assert ps.quality["panel6"]["pleat_folds"] > 0  # graded at its tucks by default, so they fold
    assert {s.patch_a for s in ps.seams} | {s.patch_b for s in ps.seams} <= {"panel3", "panel6", "panel10"}
    assert ps.seams  # panel3 - panel10 are sewn


@needs_assets
def test_shirt_sleeve_and_torso_meet_the_targets():
    panels, seams = read_garmentcode(SHIRT)
    chosen = [p for p in panels if p.name in ("left_sleeve_b", "left_ftorso")]
    ps = conform_all(chosen, seams, ConformOptions(knot_span=0.02))
    check_targets(ps)
    prov = ps.provenance["left_sleeve_b"]
    covered = sorted(e for side in prov["sides"].values() for e in side["pattern_edges"])
    assert covered == list(range(6))  # every pattern edge is on some side
    # Sleeve and torso are sewn along the armhole: one seam with boundary intervals.
    (seam,) = [s for s in ps.seams if {s.patch_a, s.patch_b} == {"left_sleeve_b", "left_ftorso"}]
    assert seam.intervals_a and seam.intervals_b


def test_distortion_sweep_quadrature_errors():
    cases = conform_bench.run((10,))
    assert {c["shape"] for c in cases} == set(conform_bench.shapes())
    for c in cases:
        assert c["area_error"] < 1e-3 and c["mass_error"] < 1e-3, c["shape"]
        assert c["energy_error"] < 5e-3, c["shape"]
        assert c["min_jacobian_ratio"] > 0.8
    # Errors grow with distortion: the mass matrix is exact on affine patches.
    by = {c["shape"]: c for c in cases}
    assert by["A10"]["mass_error"] < 1e-6 and by["S30"]["mass_error"] < 1e-5
    assert by["B165"]["mass_error"] < by["B135"]["mass_error"] < by["B105"]["mass_error"]


@pytest.mark.slow
@needs_assets
@pytest.mark.parametrize("source", [DRESS_KNIFE, SHIRT, DRESS], ids=["dress_knife", "shirt", "dress"])
def test_whole_garments_meet_the_targets(source):
    if source.suffix == ".json":
        panels, seams = read_garmentcode(source)
    else:
        panels, seams = read_panels(source)
    ps = conform_all(panels, seams, ConformOptions(knot_span=0.02))
    # Every patch, including the five pieces of the dress's skirt_back (split at its darts).
    check_targets(ps)
    for summary in ps.splits.values():
        assert abs(summary["area_error_reduced_pct"]) < 0.1
    # The dress: 4 more seams, the cuts (its darts now sew neighbouring pieces).
    expected = {DRESS_KNIFE: 94, SHIRT: len(seams), DRESS: len(seams) + 4}[source]
    assert len(ps.seams) == expected
    assert set(ps.splits) == ({"skirt_back"} if source == DRESS else set())


@pytest.mark.slow
@needs_assets
def test_dress_skirt_back_is_split_at_its_darts():
    """skirt_back (dress_pencil_specification.json): four darts of 19-21 cm in a 50 cm waist.
    One patch was 102 x 36, Jacobian ratio 0.06-22, reduced-rule area error 0.18 %, 5-7 s;
    cut from each dart tip straight down to the hem it becomes five quads."""
    panels, seams = read_garmentcode(DRESS)
    chosen = [p for p in panels if p.name == "skirt_back"]
    ps = conform_all(chosen, seams, ConformOptions(knot_span=0.02))
    names = [f"skirt_back.{k}" for k in range(5)]
    assert [p.name for p in ps.patches] == names
    check_targets(ps)
    for name in names:
        q = ps.quality[name]
        assert 0.5 < q["min_jacobian_ratio"] and q["max_jacobian_ratio"] < 1.5, name
        assert min(q["corner_angles_deg"]) > 80, name
    summary = ps.splits["skirt_back"]
    assert abs(summary["area_error_reduced_pct"]) < 0.05 and abs(summary["area_error_gauss2_pct"]) < 1e-5
    cuts = summary["cuts"]
    assert [c["dart"] for c in cuts] == ["stitch0", "stitch1", "stitch2", "stitch3"]
    for c in cuts:  # vertical, tip to hem
        assert abs(c["from"][0] - c["to"][0]) < 1e-9 and c["to"][1] == pytest.approx(0.0, abs=1e-12)
    # Cut seams: both sides of each cut have the cut's rest length (within the fit
    # tolerance), so welding the pieces does not stretch them.
    for k, c in enumerate(cuts):
        (seam,) = [s for s in ps.seams if s.name == f"skirt_back.cut{k}"]
        lengths = [sum(interval_length(ps.patch(patch).rest, iv) for iv in ivs)
                   for patch, ivs in ((seam.patch_a, seam.intervals_a), (seam.patch_b, seam.intervals_b))]
        assert lengths[0] == pytest.approx(1e-3 * c["length_mm"], abs=1e-3)
        assert lengths[1] == pytest.approx(1e-3 * c["length_mm"], abs=1e-3)
    # Each dart now sews two neighbouring pieces (seams to panels not converted here drop).
    darts = {s.name: {s.patch_a, s.patch_b} for s in ps.seams if s.name.startswith("stitch")}
    assert darts == {f"stitch{k}": {names[k], names[k + 1]} for k in range(4)}


def test_a_seam_shorter_than_the_fit_tolerance_on_both_panels_is_dropped():
    # GarmentCode's fitted shirts join front and back torso at the waist's side with a
    # 1.46 mm and a 0.75 mm edge: below a 1.9 mm boundary fit tolerance on both panels, the
    # seam is one point of both fitted boundaries and is dropped; dress_00's strap tips
    # (2.43 / 5.17 mm) and a seam short on one panel only are kept.
    from conform.seams import below_resolution
    from sim.seams.spec import PanelSeam

    def seam(la: float, lb: float) -> PanelSeam:
        t = np.linspace(0.0, 1.0, 3)[:, None]
        return PanelSeam("s", "front", "back", t * [la, 0.0], t * [0.0, lb])

    fit = {"front": 1.9e-3, "back": 1.9e-3}
    assert below_resolution(seam(1.46e-3, 0.75e-3), fit)
    assert not below_resolution(seam(2.43e-3, 5.17e-3), fit)
    assert not below_resolution(seam(1.46e-3, 30e-3), fit)
    assert not below_resolution(seam(1.46e-3, 0.75e-3), {"front": 1e-3, "back": 1.9e-3})
