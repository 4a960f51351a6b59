"""Panels one patch cannot cover (conform/pipeline.py rescue_splits): a narrow strap on a
torso panel, and a slit no seam declares. With splitting off, the single patch folds
over or cannot be untangled; by default the panel is cut (at the neck, at the notch) and
every piece conforms without folding, the pieces keeping the panel's area."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conform import ConformOptions, conform_all
from conform.boundary import extract_outline
from conform.pipeline import rescue_splits
from conform.quality import folded
from conform.split import necks_of, notches_of
from garment.io.garmentcode import read_garmentcode


def pattern(path, vertices):
    """A one-panel GarmentCode pattern (cm) with straight edges and no stitches."""
    panels = {"front": {"translation": [0, 0, 0], "rotation": [0, 0, 0], "vertices": vertices,
                        "edges": [{"endpoints": [k, (k + 1) % len(vertices)]} for k in range(len(vertices))]}}
    path.write_text(json.dumps({"pattern": {"panels": panels, "stitches": []},
                                "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}))
    return read_garmentcode(path)


# A 40 x 30 cm torso with a strap 30 cm long rising from the middle of its top (5 cm wide
# at its root, 3 cm at its end).
STRAP = [[0, 0], [40, 0], [40, 30], [22, 30], [21, 60], [18, 60], [17, 30], [0, 30]]
# A 50 x 60 cm skirt panel with a 45 cm slit up from its hem (1 cm open at the hem).
SLIT = [[0, 0], [24.5, 0], [25, 45], [25.5, 0], [50, 0], [50, 60], [0, 60]]


def conformed(panels, seams, split):
    ps = conform_all(panels, seams, ConformOptions(knot_span=0.04, split=split))
    return ps, [p for p in ps.patches if folded(p)]


@pytest.mark.parametrize("shape", ["strap", "slit"])
def test_a_panel_one_patch_cannot_cover_is_cut_into_pieces_that_do_not_fold(tmp_path, shape):
    panels, seams = pattern(tmp_path / "p.json", STRAP if shape == "strap" else SLIT)
    whole, whole_folds = conformed(panels, seams, "never")
    assert whole.failures or whole_folds  # one patch: no valid net
    ps, folds = conformed(panels, seams, "auto")
    assert not ps.failures and not folds
    assert len(ps.patches) >= 2
    assert ps.splits["front"]["converted"]
    assert {ps.panel_of(p.name) for p in ps.patches} == {"front"}  # through nested cuts too
    # Pieces cover the panel: their areas add up to it (exact 2 x 2 Gauss rule).
    assert abs(ps.splits["front"]["area_error_gauss2_pct"]) < 0.5
    # The cuts are seams between the pieces, mapped onto both patch boundaries.
    cut_seams = [s for s in ps.seams if ".cut" in s.name]
    assert len(cut_seams) == len(ps.patches) - 1


def test_the_strap_is_cut_across_its_base_and_the_slit_along_its_axis(tmp_path):
    panels, _ = pattern(tmp_path / "strap.json", STRAP)
    necks = necks_of(extract_outline(panels[0]), 0.16)
    a, b = necks[0].tip, necks[0].tip + necks[0].depth * necks[0].axis
    # The narrowest neck joins the strap's two sides near its root (y = 0.30 m).
    assert necks[0].depth < 0.06
    assert min(a[1], b[1]) >= 0.29 and max(a[1], b[1]) < 0.40
    assert min(a[0], b[0]) < 0.18 and max(a[0], b[0]) > 0.21
    panels, seams = pattern(tmp_path / "slit.json", SLIT)
    notches = notches_of(extract_outline(panels[0]))
    assert len(notches) == 1
    np.testing.assert_allclose(notches[0].tip, [0.25, 0.45], atol=0.011)
    np.testing.assert_allclose(notches[0].axis, [0.0, 1.0], atol=0.02)
    split = next(rescue_splits(panels[0], extract_outline(panels[0]), seams, ConformOptions(knot_span=0.04)))
    np.testing.assert_allclose(split.cuts[0].p1, [0.25, 0.60], atol=0.011)  # up to the waist


# A piece of upper_garment_06's back torso (mm, 5 x 7 control points): its strap pinches
# to 0.1 mm at row 3. Every grid of it is one-to-one, but the simulator's mesh of a sewn
# piece, with seam vertices on the true boundary, turns triangles over there.
PINCH = np.array([
    [[3.41, 0.0], [3.92, 16.39], [3.85, 49.19], [3.11, 81.98], [1.96, 114.76], [0.66, 147.53], [0.0, 163.92]],
    [[7.57, 0.34], [6.43, 13.98], [4.44, 50.93], [3.1, 82.1], [2.56, 113.29], [2.77, 149.96], [3.85, 163.98]],
    [[15.9, 1.02], [11.6, 12.99], [5.47, 51.62], [3.17, 82.26], [3.53, 113.02], [7.45, 151.44], [11.55, 164.12]],
    [[24.23, 1.7], [16.79, 14.22], [6.7, 50.54], [3.17, 82.4], [4.64, 114.43], [12.39, 150.96], [19.26, 164.25]],
    [[28.39, 2.03], [19.37, 16.52], [7.73, 48.62], [3.05, 82.44], [5.52, 116.49], [15.05, 149.27], [23.11, 164.32]],
]) * 1e-3


def test_a_piece_whose_seamed_mesh_turns_over_counts_as_folded():
    from types import SimpleNamespace

    from conform.quality import _grid_folds, _seamed_folds
    from sim.embedding import default_resolution

    n, m = PINCH.shape[:2]
    res = default_resolution(n, m, 2.0)
    assert not _grid_folds(PINCH.reshape(-1, 2), n, m, res)  # the plain grid is fine
    assert not _grid_folds(PINCH.reshape(-1, 2), n, m, (4 * (n - 2) + 1, 4 * (m - 2) + 1))
    assert _seamed_folds(PINCH, res)
    assert folded(SimpleNamespace(shape=(n, m), rest=PINCH))
    # The same net widened to 4 mm at the pinch is a valid piece.
    wide = PINCH.copy()
    wide[:, :, 0] += np.linspace(0.0, 4e-3, n)[:, None] * np.exp(-((wide[:, :, 1] - 0.082) / 0.04) ** 2)
    assert not folded(SimpleNamespace(shape=(n, m), rest=wide))


# A torso and a yoke meeting in a 0.1 mm waist at y = 40 cm (two V's tip to tip), as
# upper_garment_06's armhole and back neckline all but meet.
PINCHED = [[0, 0], [40, 0], [40, 30], [20.005, 40], [40, 55], [40, 65], [0, 65], [0, 55], [19.995, 40], [0, 30]]


def test_a_pinched_panel_loses_the_sliver_at_its_pinch_and_both_lobes_conform(tmp_path):
    from conform.split import TRIM_WIDTH, trims_of

    panels, seams = pattern(tmp_path / "p.json", PINCHED)
    outline = extract_outline(panels[0])
    neck = necks_of(outline, 0.16)[0]
    assert neck.depth < 2e-3 and abs(neck.tip[1] - 0.40) < 0.01
    trims = trims_of(outline, neck)
    assert len(trims) == 2
    for t in trims:  # one cut into each lobe, where it is TRIM_WIDTH wide
        assert TRIM_WIDTH <= t.depth < 1.5 * TRIM_WIDTH
    assert sorted(np.sign(t.tip[1] - 0.40) for t in trims) == [-1, 1]
    ps, folds = conformed(panels, seams, "auto")
    assert not ps.failures and not folds
    assert len(ps.patches) == 2  # the sliver between the cuts is dropped ...
    assert not [s for s in ps.seams if ".cut" in s.name]  # ... and nothing sews across it
    # The sliver is two thin triangles (~15 cm^2 of 2,200): the pieces keep 99 %.
    assert -1.5 < ps.splits["front"]["area_error_gauss2_pct"] < 0


# jumpsuit_777_03's right hood (GarmentCode's sampler, seed 777; cm): its neckline, two
# cubic curves, swings up into an S whose far side comes within 4.9 mm of the hood's
# straight front edge. The flap below that neck hangs on by 4.9 mm.
HOOD = {"translation": [0, 0, 0], "rotation": [0, 0, 0],
        "vertices": [[-0.7680482086473797, -0.4767339684927805], [4.6190296611907256, 15.879496039367144],
                     [8.743018997592188, -3.966023532560566], [9.721657850376856, 49.02538160240815],
                     [4.953609641729476, 49.02538160240815]],
        "edges": [{"endpoints": [0, 1], "curvature": {"type": "cubic", "params": [
                      [0.19619729665320243, -0.4505397071336339], [0.7984764403920477, 0.43434028095289484]]}},
                  {"endpoints": [1, 2], "curvature": {"type": "cubic", "params": [
                      [0.1560547814152252, 0.5564645417505979], [0.8421109736826059, -0.5514296841342021]]}},
                  {"endpoints": [2, 3]}, {"endpoints": [3, 4]},
                  {"endpoints": [4, 0], "curvature": {"type": "quadratic", "params": [[0.2, -0.5]]}}]}


def test_a_neck_a_few_mm_wide_that_cannot_be_cut_across_is_trimmed_off_both_sides(tmp_path):
    from conform.split import PINCH, TRIM_WIDTH

    path = tmp_path / "hood.json"
    path.write_text(json.dumps({"pattern": {"panels": {"hood": HOOD}, "stitches": []},
                                "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}))
    panels, seams = read_garmentcode(path)
    neck = necks_of(extract_outline(panels[0]), 0.16)[0]
    assert PINCH < neck.depth < TRIM_WIDTH  # too wide for a pinch, too narrow to cut across
    whole, whole_folds = conformed(panels, seams, "never")
    assert whole.failures or whole_folds
    ps, folds = conformed(panels, seams, "auto")
    assert not ps.failures and not folds
    assert len(ps.patches) == 2 and not [s for s in ps.seams if ".cut" in s.name]
    # The sliver between the trims (at most TRIM_WIDTH across) is under 1 % of the hood.
    assert -1.0 < ps.splits["hood"]["area_error_gauss2_pct"] < 0
