"""Splitting darted panels into several patches (conform/split.py): where the cuts go,
how seams move onto the pieces, and that the pieces meet the conforming targets where one
patch does not."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conform import ConformOptions, conform_all
from conform.boundary import extract_outline, sample_polygon
from conform.split import darts_of, split_panel, split_seams
from garment.cli import main
from garment.io.garmentcode import read_garmentcode
from garment.io.patchfile import load_patchset, save_patchset
from sim.patches import Panel
from sim.seams.spec import PanelSeam

from tests.support.panels import interval_length, rest_points


def skirt_pattern(path, dart_depth=20.0, dart_width=3.0, with_band=True):
    """A GarmentCode pattern (cm): a 50 x 60 skirt panel with two darts from the waist
    (at x = 17 and 33) and, optionally, a 10 cm band sewn along the whole hem."""
    w2 = 0.5 * dart_width
    tip = 60.0 - dart_depth
    V = [[0, 0], [50, 0], [50, 60], [33 + w2, 60], [33, tip], [33 - w2, 60], [17 + w2, 60], [17, tip],
         [17 - w2, 60], [0, 60]]
    panels = {"skirt": {"translation": [0, 0, 0], "rotation": [0, 0, 0], "vertices": V,
                        "edges": [{"endpoints": [k, (k + 1) % len(V)]} for k in range(len(V))]}}
    stitches = [[{"panel": "skirt", "edge": 3}, {"panel": "skirt", "edge": 4}],
                [{"panel": "skirt", "edge": 6}, {"panel": "skirt", "edge": 7}]]
    if with_band:
        B = [[0, -10], [50, -10], [50, 0], [0, 0]]
        panels["band"] = {"translation": [0, 0, 0], "rotation": [0, 0, 0], "vertices": B,
                          "edges": [{"endpoints": [k, (k + 1) % 4]} for k in range(4)]}
        stitches.append([{"panel": "skirt", "edge": 0}, {"panel": "band", "edge": 2}])
    path.write_text(json.dumps({"pattern": {"panels": panels, "stitches": stitches},
                                "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}))
    return path


def test_cuts_continue_the_darts_and_pieces_keep_the_area(tmp_path):
    panels, seams = read_garmentcode(skirt_pattern(tmp_path / "skirt.json"))
    skirt = panels[0]
    darts = darts_of("skirt", seams)
    assert [d.seam for d in darts] == ["stitch0", "stitch1"]
    np.testing.assert_allclose([d.tip for d in darts], [[0.33, 0.4], [0.17, 0.4]], atol=1e-12)
    np.testing.assert_allclose([d.axis for d in darts], [[0, -1], [0, -1]], atol=1e-12)
    sp = split_panel(skirt, extract_outline(skirt), darts)
    # Each cut runs from the tip straight down to the hem.
    np.testing.assert_allclose([c.p1 for c in sp.cuts], [[0.33, 0.0], [0.17, 0.0]], atol=1e-12)
    assert sp.piece_names() == ["skirt.0", "skirt.1", "skirt.2"]
    areas = [p.panel.area for p in sp.pieces]
    half = 0.5 * 0.015 * 0.2  # half a dart wedge
    np.testing.assert_allclose(areas, [0.17 * 0.6 - half, 0.16 * 0.6 - 2 * half, 0.17 * 0.6 - half],
                               rtol=1e-12)
    assert sum(areas) == pytest.approx(skirt.area, rel=1e-9)
    # The hem seam crosses both cut ends: three runs, the cut ends inserted exactly.
    moved = split_seams(seams, sp, tol=1e-3)
    hem = [s for s in moved if s.name.startswith("stitch2")]
    assert [(s.name, s.panel_a, s.panel_b) for s in hem] == [
        ("stitch2.0", "skirt.0", "band"), ("stitch2.1", "skirt.1", "band"), ("stitch2.2", "skirt.2", "band")]
    assert hem[0].points_a[-1] == pytest.approx([0.17, 0.0]) and hem[1].points_a[0] == pytest.approx([0.17, 0.0])
    np.testing.assert_allclose(hem[1].points_b[0], hem[0].points_b[-1])
    for s in hem:  # still matched point to point
        np.testing.assert_allclose(s.points_a, s.points_b, atol=1e-12)
    darts_now = {s.name: (s.panel_a, s.panel_b) for s in moved if s.name in ("stitch0", "stitch1")}
    assert darts_now == {"stitch0": ("skirt.2", "skirt.1"), "stitch1": ("skirt.1", "skirt.0")}
    assert [s.name for s in moved[-2:]] == ["skirt.cut0", "skirt.cut1"]


def test_split_skirt_meets_the_targets_and_its_seams_match(tmp_path):
    panels, seams = read_garmentcode(skirt_pattern(tmp_path / "skirt.json"))
    ps = conform_all(panels, seams, ConformOptions(knot_span=0.02))
    assert not ps.failures
    assert [p.name for p in ps.patches] == ["skirt.0", "skirt.1", "skirt.2", "band"]
    summary = ps.splits["skirt"]
    assert summary["patches"] == ["skirt.0", "skirt.1", "skirt.2"] and len(summary["cuts"]) == 2
    assert abs(summary["area_error_gauss2_pct"]) < 1e-6  # the reader's exact area: 3e-11 relative
    assert abs(summary["area_error_reduced_pct"]) < 0.1
    for name in summary["patches"]:
        q = ps.quality[name]
        assert q["inverted_points"] == 0 and q["min_jacobian_ratio"] > 0.5 and q["max_jacobian_ratio"] < 2.0, name
        assert q["boundary_error_mm"] < q["tolerance_mm"], name
        assert abs(q["area_error_reduced_pct"]) < 0.1 and abs(q["area_error_gauss2_pct"]) < 1e-9, name
        assert min(q["corner_angles_deg"]) > 80, name  # quads: the tips are no corners
        prov = ps.provenance[name]
        assert prov["panel"] == "skirt" and prov["patch"] == name and prov["pieces"] == 3
    # The cuts and darts are seams between neighbouring pieces; both sides have the same
    # rest length (the cut's, the dart leg's), and a cut's matched samples coincide at rest.
    seam = {s.name: s for s in ps.seams}
    for name, length in (("skirt.cut0", 0.4), ("skirt.cut1", 0.4), ("stitch0", np.hypot(0.2, 0.015)),
                         ("stitch1", np.hypot(0.2, 0.015))):
        s = seam[name]
        Xa, Xb = ps.patch(s.patch_a).rest, ps.patch(s.patch_b).rest
        La = sum(interval_length(Xa, iv) for iv in s.intervals_a)
        Lb = sum(interval_length(Xb, iv) for iv in s.intervals_b)
        assert La == pytest.approx(length, abs=1e-3) and Lb == pytest.approx(length, abs=1e-3), name
        if "cut" in name:
            assert np.abs(rest_points(Xa, s.uv_a) - rest_points(Xb, s.uv_b)).max() < 1e-3, name
    # The hem seam now runs along three pieces, each run on one patch side.
    runs = [seam[f"stitch2.{k}"] for k in range(3)]
    assert [r.patch_a for r in runs] == ["skirt.0", "skirt.1", "skirt.2"]
    assert all(len(r.intervals_a) == 1 and r.intervals_a[0].side == "v0" for r in runs)
    total = sum(interval_length(ps.patch("band").rest, iv) for r in runs for iv in r.intervals_b)
    assert total == pytest.approx(0.5, abs=1e-3)


def test_split_options(tmp_path):
    # Shallow darts leave the sides balanced: "auto" keeps one patch, "darts" cuts anyway.
    panels, seams = read_garmentcode(skirt_pattern(tmp_path / "shallow.json", dart_depth=5.0, with_band=False))
    assert [p.name for p in conform_all(panels, seams, ConformOptions(knot_span=0.04)).patches] == ["skirt"]
    cut = conform_all(panels, seams, ConformOptions(knot_span=0.04, split="darts"))
    assert [p.name for p in cut.patches] == ["skirt.0", "skirt.1", "skirt.2"]


@pytest.mark.slow
def test_one_patch_around_deep_darts_is_what_splitting_avoids(tmp_path):
    """split="never" on the deep-darted skirt: one strongly distorted patch (measured at
    30 mm: 69 x 22, Jacobian ratio 0.04-7.0, reduced-rule area error 0.19 %, ~6 s) against
    three pieces (0.85-1.04, 0.004 %, ~1.3 s)."""
    panels, seams = read_garmentcode(skirt_pattern(tmp_path / "skirt.json", with_band=False))
    whole = conform_all(panels, seams, ConformOptions(knot_span=0.03, split="never"))
    cut = conform_all(panels, seams, ConformOptions(knot_span=0.03))
    assert [p.name for p in whole.patches] == ["skirt"] and not whole.splits
    q = whole.quality["skirt"]
    assert q["min_jacobian_ratio"] < 0.1 and abs(q["area_error_reduced_pct"]) > 0.1
    for name in cut.splits["skirt"]["patches"]:
        assert cut.quality[name]["min_jacobian_ratio"] > 0.8
        assert abs(cut.quality[name]["area_error_reduced_pct"]) < 0.01


def test_conform_command_rows_per_piece(tmp_path, capsys):
    src = skirt_pattern(tmp_path / "skirt.json")
    out = tmp_path / "out"
    assert main(["conform", str(src), "-o", str(out), "--json", "-q"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [r["panel"] for r in doc["panels"]] == ["skirt.0", "skirt.1", "skirt.2", "band"]
    assert all(r["status"] == "ok" for r in doc["panels"])
    assert doc["splits"]["skirt"]["patches"] == ["skirt.0", "skirt.1", "skirt.2"]
    ps = load_patchset(out / "patches.json")
    assert ps.splits["skirt"]["cuts"][0]["dart"] == "stitch0"
    assert ps.provenance["skirt.1"]["sides"]["u0"].get("cut") or ps.provenance["skirt.1"]["sides"]["u1"].get("cut")
    save_patchset(tmp_path / "again.json", ps)
    assert load_patchset(tmp_path / "again.json").splits == ps.splits
    # The table: one row per patch and a summary row for the split panel.
    assert main(["conform", str(src), "-o", str(out), "-q"]) == 0
    table = capsys.readouterr().out
    assert "skirt.2" in table and "3 patches" in table and "split" in table


def ear_clip(P: np.ndarray) -> np.ndarray:
    """Triangles (F, 3) of the simple counter-clockwise polygon P (V, 2), by ear clipping."""
    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    idx = list(range(len(P)))
    tris = []
    while len(idx) > 3:
        for k in range(len(idx)):
            a, b, c = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            if cross(P[a], P[b], P[c]) <= 1e-14:
                continue
            others = [i for i in idx if i not in (a, b, c)]
            Q = P[others]
            inside = ((cross(P[a], P[b], Q.T) >= 0) & (cross(P[b], P[c], Q.T) >= 0) & (cross(P[c], P[a], Q.T) >= 0))
            if not inside.any():
                tris.append((a, b, c))
                idx.pop(k)
                break
        else:
            raise ValueError("no ear")
    tris.append(tuple(idx))
    return np.asarray(tris)


def test_a_darted_mesh_panel_is_split_and_lifted_from_its_mesh():
    corners = np.array([[0, 0], [0.5, 0], [0.5, 0.6], [0.265, 0.6], [0.25, 0.35], [0.235, 0.6], [0, 0.6]])
    rest, _ = sample_polygon(corners, 0.02)
    faces = ear_clip(rest)
    world = np.column_stack([rest, 0.5 * rest[:, 1]])  # a sheared placement: lift is exact
    panel = Panel("skirt", "test", rest, faces=faces, world=world)
    leg = np.linspace(0.0, 1.0, 14)[:, None]
    dart = PanelSeam("dart", "skirt", "skirt", np.array([0.265, 0.6]) + leg * [-0.015, -0.25],
                     np.array([0.235, 0.6]) + leg * [0.015, -0.25])
    ps = conform_all([panel], [dart], ConformOptions(knot_span=0.03, split="darts"))
    assert [p.name for p in ps.patches] == ["skirt.0", "skirt.1"] and not ps.failures
    assert ps.splits["skirt"]["cuts"][0]["to"] == pytest.approx([0.25, 0.0])
    for p in ps.patches:
        q = ps.quality[p.name]
        assert q["inverted_points"] == 0 and q["boundary_error_mm"] < q["tolerance_mm"]
        assert abs(q["area_error_gauss2_pct"]) < 1e-9 and abs(q["area_error_reduced_pct"]) < 0.1
        np.testing.assert_allclose(p.world[..., 2], 0.5 * p.rest[..., 1], atol=1e-9)  # from the mesh
    assert {(s.name, s.patch_a, s.patch_b) for s in ps.seams} == {("dart", "skirt.1", "skirt.0"),
                                                                 ("skirt.cut0", "skirt.0", "skirt.1")}
