"""Tucks and knife pleats folded into the placement before sewing (conform/pleats.py)."""

from __future__ import annotations

import numpy as np
import pytest

import conform.pleats as pleats
from conform import ConformOptions
from conform.pipeline import conform_all
from garment.cli import main
from sim.errors import InputError
from garment.io.garments import read_pattern
from garment.io.panels import read_panels
from garment.io.patchfile import load_patchset
from sim.patches import Panel
from sim.seams.spec import PanelSeam
from garment.scene import load_scene, parse_scene

from tests.support.panels import pleated, polygon_panel
from tests.support.paths import ASSETS

RECT = np.array([[0.0, 0.0], [0.3, 0.0], [0.3, 0.15], [0.0, 0.15]])
# A knife pleat in the top edge (y = 0.15) as GarmentCode sews one: roots D and A, tips B
# and C, three 20 mm layers D-B, B-C, C-A; each tuck sews 14 mm from its roots inwards.
D, B, C, A = 0.10, 0.12, 0.14, 0.16


def _stretch(x0, x1, y=0.15, k=5):
    x = np.linspace(x0, x1, k)
    return np.stack([x, np.full(k, y)], axis=1)


def _knife(band_on=(C, A)):
    """Panel p with a knife pleat, and a band panel sewn to p's top edge along band_on."""
    tucks = [PanelSeam("t1", "p", "p", _stretch(C, C - 0.014), _stretch(D, D + 0.014)),
             PanelSeam("t2", "p", "p", _stretch(A, A - 0.014), _stretch(B, B + 0.014))]
    band = PanelSeam("band", "band", "p", _stretch(0.0, band_on[1] - band_on[0], 0.0), _stretch(*band_on))
    return tucks + [band]


def _profile_layers(fold, x_at):
    """Heights of the three layers where each passes the folded position x_at."""
    out = []
    for lo, hi in ((D, B), (B, C), (C, A)):
        s = fold.side(_stretch(lo, hi, k=2001))
        x, h = fold.profile(s)
        order = np.argsort(x)
        assert x[order[0]] < x_at < x[order[-1]]
        out.append(np.interp(x_at, x[order], h[order]))
    return out


def test_a_knife_pleat_folds_at_its_tips_and_brings_every_stitch_together():
    fold, notes = pleats.plan_fold(Panel("p", "test", RECT), _knife(), span=0.008)
    assert notes == []
    np.testing.assert_allclose(np.sort(fold.side(np.array([[B, 0.15], [C, 0.15]]))), np.sort(fold.lines),
                               atol=1e-12)
    np.testing.assert_allclose(fold.groups, [np.sort(fold.side(np.array([[D, 0.15], [A, 0.15]])))], atol=1e-12)
    pairs = np.concatenate([t.pairs for t in fold.tucks])
    x = fold.fully_folded(pairs.ravel()).reshape(-1, 2)
    assert np.abs(x[:, 0] - x[:, 1]).max() < 1e-9
    # Folded only part of the way, the cloth bends without stretching ...
    s = np.linspace(fold.groups[0, 0] - 0.05, fold.groups[0, 1] + 0.05, 20001)
    x, h = fold.profile(s)
    assert np.hypot(np.diff(x), np.diff(h)).sum() == pytest.approx(s[-1] - s[0], rel=1e-6)
    # ... lifts off the panel by millimetres, and the cloth past the pleat is level again,
    # shortened along the side.
    assert np.abs(h).max() > 3e-3
    before, after = s < fold.groups[0, 0] - fold.width, s > fold.groups[0, 1] + fold.width
    np.testing.assert_allclose(x[before], s[before], atol=1e-9)
    assert np.abs(h[before]).max() < 1e-12 and np.abs(h[after]).max() < 2e-4
    shortened = (s - x)[after]
    assert np.ptp(shortened) < 1e-9 and shortened[0] > 2e-3


@pytest.mark.parametrize("band_on, top", [((C, A), 2), ((D, B), 0)])
def test_the_layer_sewn_to_another_panel_ends_up_on_top(monkeypatch, band_on, top):
    monkeypatch.setattr(pleats, "FOLD_ANGLE", np.radians(175.0))
    monkeypatch.setattr(pleats, "TURN_WIDTH", 0.05)
    fold, _ = pleats.plan_fold(Panel("p", "test", RECT), _knife(band_on), span=0.008)
    # Nearly fully folded, the three layers stack over the middle of the folded pleat.
    mid = float(np.mean(fold.profile(fold.lines)[0]))
    h = _profile_layers(fold, mid)
    assert np.argmax(h) == top and np.argmin(h) == 2 - top  # the middle layer in between
    assert min(abs(h[0] - h[1]), abs(h[1] - h[2])) > 1e-4


def test_a_lone_tuck_folds_flat_at_its_first_root_and_tip():
    tuck = PanelSeam("t", "p", "p", _stretch(0.16, 0.146), _stretch(0.12, 0.134))
    fold, notes = pleats.plan_fold(Panel("p", "test", RECT), [tuck], span=0.008)
    assert notes == [] and fold.lines.size == 2
    # At its tip (x = 0.14) and the root first along the side direction.
    tip, roots = fold.side(np.array([[0.14, 0.15]])), np.sort(fold.side(np.array([[0.12, 0.15], [0.16, 0.15]])))
    np.testing.assert_allclose(np.sort(fold.lines), np.sort([tip[0], roots[0]]), atol=1e-12)
    x = fold.fully_folded(fold.tucks[0].pairs.ravel()).reshape(-1, 2)
    assert np.abs(x[:, 0] - x[:, 1]).max() < 1e-9


def test_darts_and_seams_between_parallel_sides_are_not_tucks():
    dart = PanelSeam("dart", "p", "p", np.array([[0.10, 0.15], [0.14, 0.05]]), np.array([[0.18, 0.15], [0.14, 0.05]]))
    tube = PanelSeam("tube", "p", "p", np.array([[0.0, 0.0], [0.0, 0.15]]), np.array([[0.3, 0.0], [0.3, 0.15]]))
    assert pleats.find_tucks("p", [dart, tube]) is None


def test_a_dart_from_a_pleats_folds_waits_for_its_tucks_as_the_band_does():
    """A seam of the panel with itself that starts on the pleat's layers (dress_knife's
    seam43, from its two knife pleats' folds down into the bodice) waits for the tucks;
    one clear of the pleat, and the tucks themselves, do not."""
    dart = PanelSeam("dart", "p", "p", np.array([[B, 0.15], [B + 0.004, 0.14], [B + 0.008, 0.13]]),
                     np.array([[C, 0.15], [C - 0.004, 0.14], [C - 0.008, 0.13]]))
    apart = PanelSeam("apart", "p", "p", np.array([[0.24, 0.15], [0.25, 0.12]]), np.array([[0.28, 0.15], [0.26, 0.12]]))
    fold, notes = pleats.plan_fold(Panel("p", "test", RECT), _knife() + [dart, apart], span=0.008)
    assert notes == [] and sorted(t.seam for t in fold.tucks) == ["t1", "t2"]
    faces = pleats.pleat_faces(fold, _knife() + [dart, apart])
    assert {name: sorted(tucks) for name, tucks in faces.items()} == {"band": ["t1", "t2"], "dart": ["t1", "t2"]}


def test_pleats_shallower_than_the_net_can_fold_stay_flat_and_say_why():
    fold, notes = pleats.plan_fold(Panel("p", "test", RECT), _knife(), span=0.02)
    assert fold is None and len(notes) == 2 and all("under 30.0 mm" in n for n in notes)


def test_a_panel_whose_pleats_are_too_shallow_for_the_seam_span_is_given_a_finer_one():
    panel, seams = Panel("p", "test", RECT), _knife()  # both tucks 20 mm deep
    assert pleats.fold_span("p", seams, 0.010) == 0.010  # folds at the seam span already
    span = pleats.fold_span("p", seams, 0.020)
    assert span == pytest.approx(0.0133)  # 20 mm / PLEAT_DEPTH, rounded down to 0.1 mm
    assert pleats.plan_fold(panel, seams, 0.020)[0] is None
    fold, notes = pleats.plan_fold(panel, seams, span)
    assert notes == [] and fold.lines.size == 2
    # Not finer than the seam span / PLEAT_REFINE: these pleats then stay flat.
    assert pleats.fold_span("p", seams, 0.032) == pytest.approx(0.020)
    assert pleats.plan_fold(panel, seams, 0.020)[0] is None
    assert pleats.fold_span("band", seams, 0.020) == 0.020  # no tucks


def test_dress_knife_bodice_pleats_fold_at_their_own_span_not_at_the_seam_span():
    panels, seams = read_panels(ASSETS / "garments" / "dress_knife.obj")
    spans = {p.name: pleats.fold_span(p.name, seams, 0.008) for p in panels}
    # Their shallowest pleats (7.3 and 6.2 mm) would ask for 4.8 and 4.1 mm: held at 5 mm.
    assert {n: h for n, h in spans.items() if h < 0.008} == pytest.approx({"panel6": 0.005, "panel13": 0.005})
    warps, notes = pleats.fold_panels(panels, seams, 0.008, spans)
    assert sorted(warps) == ["panel11", "panel13", "panel4", "panel6"]
    flat = {name: sorted(n.split(":")[0] for n in why) for name, why in notes.items()}
    assert flat == {"panel6": ["seam48", "seam49"], "panel13": ["seam52", "seam53"]}
    for name in ("panel6", "panel13"):
        fold = warps[name].fold
        assert fold.lines.size == 6 and len(fold.tucks) == 6
        assert fold.width == pytest.approx(pleats.TURN_WIDTH * spans[name])
        pairs = np.concatenate([t.pairs for t in fold.tucks])
        x = fold.fully_folded(pairs.ravel()).reshape(-1, 2)
        assert np.abs(x[:, 0] - x[:, 1]).max() < 3e-3  # the bent waist read as one line


def test_dress_knife_folds_its_skirt_pleats_and_leaves_the_bodice_pleats_flat():
    panels, seams = read_panels(ASSETS / "garments" / "dress_knife.obj")
    warps, notes = pleats.fold_panels(panels, seams, 0.008)
    assert sorted(warps) == ["panel11", "panel4"]
    for name, warp in warps.items():
        fold = warp.fold
        assert fold.lines.size == 8 and len(fold.groups) == 4 and len(fold.tucks) == 8
        pairs = np.concatenate([t.pairs for t in fold.tucks])
        x = fold.fully_folded(pairs.ravel()).reshape(-1, 2)
        assert np.abs(x[:, 0] - x[:, 1]).max() < 2.5e-3  # the pattern's own mismatch
        # Every pleat's face is the layer the waistband is sewn to: the last in panel11's
        # side direction, the first in panel4's (mirrored about the front centre).
        assert abs(warp.normal[1]) == pytest.approx(1.0)  # front panels: lifted along -y ...
        assert warp.normal[1] < 0  # ... away from the body
    assert warps["panel4"].fold.angles[0] * warps["panel11"].fold.angles[0] * \
        (warps["panel4"].along @ warps["panel11"].along) < 0
    assert any("under 12.0 mm" in n for n in notes["panel6"])
    # The waistband's seam onto each pleat's face waits for that pleat's two tucks.
    faces = {name: sorted(tucks) for w in warps.values() for name, tucks in pleats.pleat_faces(w.fold, seams).items()}
    assert faces == {f"seam{60 + k}": [f"seam{86 + 2 * k}", f"seam{87 + 2 * k}"] for k in range(4)} | \
        {f"seam{66 + k}": [f"seam{74 + 2 * k}", f"seam{75 + 2 * k}"] for k in range(4)}


def test_a_pleated_panel_conforms_to_a_folded_net_with_little_strain():
    band = polygon_panel("band", np.array([[0.0, -0.05], [0.06, -0.05], [0.06, 0.0], [0.0, 0.0]]), spacing=0.002)
    panel = polygon_panel("p", RECT, spacing=0.002)
    options = ConformOptions(knot_span=0.04, seam_span=0.008, fold_pleats=False)
    flat = conform_all([panel, band], _knife((0.14, 0.20)), options)
    folded = conform_all([panel, band], _knife((0.14, 0.20)), ConformOptions(knot_span=0.04, seam_span=0.008))
    assert "pleat_folds" not in flat.quality["p"] and folded.quality["p"]["pleat_folds"] == 2
    assert "pleat_span_mm" not in folded.quality["p"]  # 20 mm deep pleats fold at 8 mm
    assert np.abs(flat.patches[0].world[..., 2]).max() < 1e-12
    W = folded.patches[0].world
    assert np.abs(W[..., 2]).max() > 3e-3  # lifted off the plane at the pleat
    assert folded.quality["p"]["lift_max_strain"] < 0.1
    np.testing.assert_array_equal(folded.patches[1].world, flat.patches[1].world)  # the band stays put


@pytest.mark.parametrize("key", ["fold_pleats", "pleat_wait"])
def test_scene_garments_take_pleat_switches_as_booleans(key):
    source = str(ASSETS / "garments" / "dress_knife.obj")
    scene = parse_scene({"garment": [{"source": source, key: False}]}, "dress.toml")
    assert not getattr(scene.garments[0], key)
    assert getattr(parse_scene({"garment": [{"source": source}]}, "dress.toml").garments[0], key)  # on by default
    with pytest.raises(InputError, match=f"dress.toml.*{key}.*true or false"):
        parse_scene({"garment": [{"source": source, key: "yes"}]}, "dress.toml")


def test_the_bundled_dress_scene_folds_its_pleats_by_default():
    scene = load_scene(ASSETS / "scenes" / "dress_rumba.toml")
    text = (ASSETS / "scenes" / "dress_rumba.toml").read_text()
    assert "fold_pleats" not in text and "pleat_wait" not in text  # no knob: the defaults
    assert [g.fold_pleats for g in scene.garments] == [True]
    assert [g.pleat_wait for g in scene.garments] == [True]
    # Nor its grading: a garment with tucks is graded at them by default, and the body
    # file's frame is the panels' (no translate).
    assert "seam_span" not in text and "translate" not in text
    assert [g.seam_span for g in scene.garments] == [None]


def test_garment_conform_folds_pleats_unless_told_not_to(tmp_path):
    source = pleated(tmp_path / "pleat.obj")
    for flag, out in ((["--no-fold-pleats"], "flat"), ([], "folded")):
        code = main(["conform", str(source), "-o", str(tmp_path / out), "-q", "--knot-span", "40",
                     "--seam-span", "8"] + flag)
        assert code == 0
    flat, folded = (load_patchset(tmp_path / d / "patches.json") for d in ("flat", "folded"))
    assert folded.quality["skirt"]["pleat_folds"] == 2 and "pleat_folds" not in flat.quality["skirt"]
    lift = np.abs(folded.patches[0].world[..., 1] - flat.patches[0].world[..., 1]).max()
    assert lift > 3e-3  # the skirt lifted off its plane (y = 0) at the pleat


def test_a_garment_with_tucks_is_graded_at_its_short_seams_by_default():
    panels, seams = read_panels(ASSETS / "garments" / "dress_knife.obj")
    assert ConformOptions(knot_span=0.04).for_garment(panels, seams).seam_span == pleats.TUCK_SEAM_SPAN
    # Not finer than asked, not coarser than the knot span: a seam span at the knot span
    # or above is a uniform net, and so is one without tucks.
    assert ConformOptions(knot_span=0.04, seam_span=0.012).for_garment(panels, seams).seam_span == 0.012
    assert ConformOptions(knot_span=0.008).for_garment(panels, seams).seam_span is None
    assert ConformOptions(knot_span=0.04, seam_span=0.04).for_garment(panels, seams).seam_span is None
    shirt, shirt_seams = read_pattern(ASSETS / "garments" / "shirt_mean.json", 0.04)
    assert not pleats.has_tucks(shirt, shirt_seams)
    assert ConformOptions(knot_span=0.04).for_garment(shirt, shirt_seams).seam_span is None


def test_garment_conform_says_it_graded_a_pleated_pattern(tmp_path, capsys):
    source = pleated(tmp_path / "pleat.obj")
    assert main(["conform", str(source), "-o", str(tmp_path / "auto"), "--knot-span", "40"]) == 0
    assert "nets graded to 8 mm spans at its short seams" in " ".join(capsys.readouterr().err.split())
    assert main(["conform", str(source), "-o", str(tmp_path / "uniform"), "--knot-span", "40",
                 "--seam-span", "40"]) == 0
    assert "graded" not in capsys.readouterr().err
    auto, uniform = (load_patchset(tmp_path / d / "patches.json") for d in ("auto", "uniform"))
    assert auto.patches[0].rest.size > uniform.patches[0].rest.size  # finer at the tucks
