"""Conforming from files: the OBJ panel reader, bad panels, the patch file and the
`garment conform` command (partial failure, JSON output, corner overrides, preview)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import trimesh
from PIL import Image

from conform import ConformOptions, PanelError, conform_all, pipeline
from conform.mips import MipsOptions
from conform.boundary import extract_outline
from conform.seams import invert
from garment.cli import main
from sim.errors import InputError
from garment.io.garmentcode import read_garmentcode
from garment.io.panels import read_panels
from garment.io.patchfile import load_patchset, save_patchset

from tests.support.panels import bad_panels, grid, rest_points, write_obj


# ------------------------------------------------------------------------------ bad panels


@pytest.mark.parametrize("name", list(bad_panels()))
def test_bad_panels_are_rejected_with_the_panel_named(tmp_path, name):
    V, F, fragment = bad_panels()[name]
    path = write_obj(tmp_path / "bad.obj", [(name, V, F)])
    (panel,), _ = read_panels(path)
    with pytest.raises(PanelError) as e:
        extract_outline(panel)
    msg = str(e.value)
    assert fragment in msg and f"panel {name}" in msg and "bad.obj" in msg


def test_garmentcode_outline_that_crosses_itself(tmp_path):
    spec = {"pattern": {"panels": {"bow": {
        "translation": [0, 0, 0], "rotation": [0, 0, 0],
        "vertices": [[0, 0], [20, 20], [20, 0], [0, 20]],
        "edges": [{"endpoints": [0, 1]}, {"endpoints": [1, 2]}, {"endpoints": [2, 3]}, {"endpoints": [3, 0]}]}},
        "stitches": []}, "properties": {"units_in_meter": 100}}
    path = tmp_path / "bow.json"
    path.write_text(json.dumps(spec))
    (panel,), _ = read_garmentcode(path)
    with pytest.raises(PanelError, match="panel bow: the outline crosses itself"):
        extract_outline(panel)


def test_unreadable_inputs(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_panels(tmp_path / "missing.obj")
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2\n")
    with pytest.raises(InputError, match="bad.obj:2"):
        read_panels(bad)


# --------------------------------------------------------------------- the whole command


@pytest.fixture
def two_panels_and_a_hole(tmp_path):
    """front (0.2 x 0.1) and back (beside it) sewn along their touching sides, plus a
    panel with a hole."""
    Va, Fa = grid(11, 6)
    Vb, Fb = grid(11, 6, origin=(0.3, 0.0))
    Vh, Fh, _ = bad_panels()["hole"]
    ny = 6
    right_of_a = [10 * ny + j for j in range(ny)]  # x = 0.2
    left_of_b = [len(Va) + j for j in range(ny)]  # x = 0.3 (global ids)
    stitches = [(right_of_a[j], left_of_b[j], left_of_b[j], 0.0) for j in range(ny)]
    path = write_obj(tmp_path / "garment.obj", [("front", Va, Fa), ("back", Vb, Fb), ("holey", Vh + [0, 0.5], Fh)],
                     [stitches])
    return path


def test_conform_command_partial_failure(tmp_path, capsys, two_panels_and_a_hole):
    out = tmp_path / "out"
    code = main(["conform", str(two_panels_and_a_hole), "-o", str(out), "--json", "--knot-span", "25"])
    assert code == 1  # one panel failed, the others converted
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    rows = {r["panel"]: r for r in doc["panels"]}
    assert rows["holey"]["status"] == "failed" and "hole" in rows["holey"]["error"]
    assert "panel holey" in captured.err and "Traceback" not in captured.err
    for name in ("front", "back"):
        r = rows[name]
        assert r["status"] == "ok" and r["control_points"] == [10, 6]
        assert r["boundary_error_mm"] < 1e-6 and r["min_jacobian_ratio"] > 0.99
        assert abs(r["area_error_pct"]) < 1e-9 and r["seconds"] > 0
        assert set(r) >= {"panel", "status", "control_points", "boundary_error_mm", "min_jacobian_ratio",
                          "area_error_pct", "seconds"}

    ps = load_patchset(out / "patches.json")
    assert [p.name for p in ps.patches] == ["front", "back"]
    assert "holey" in ps.failures
    np.testing.assert_allclose(ps.patch("front").world[..., 2], 0.5 * ps.patch("front").rest[..., 1], atol=1e-9)
    # The seam: front's side u1 (x = 0.2) sewn to back's side u0 (x = 0.3), both along v.
    (seam,) = ps.seams
    assert (seam.patch_a, seam.patch_b) == ("front", "back")
    assert [(iv.side, iv.t0, iv.t1) for iv in seam.intervals_a] == [("u1", 0.0, 4.0)]
    assert [(iv.side, iv.t0, iv.t1) for iv in seam.intervals_b] == [("u0", 0.0, 4.0)]
    np.testing.assert_allclose(seam.uv_a[:, 1], seam.uv_b[:, 1], atol=1e-9)
    # Provenance: the corner vertices and each side's input boundary vertices.
    prov = ps.provenance["front"]
    assert prov["corner_vertex_ids"] == [0, 60, 65, 5]
    assert prov["sides"]["u1"]["boundary_vertex_ids"] == list(range(60, 66))
    # The file round-trips, a seam's wait for a pleat's tucks included.
    assert seam.after == ()
    ps.seams[0] = dataclasses.replace(seam, after=("tuck1", "tuck2"))
    save_patchset(tmp_path / "again.json", ps)
    again = load_patchset(tmp_path / "again.json")
    np.testing.assert_array_equal(again.patch("back").rest, ps.patch("back").rest)
    assert again.seams[0].intervals_b[0].side == "u0"
    assert again.seams[0].after == ("tuck1", "tuck2")


def test_conform_command_table_corners_and_preview(tmp_path, capsys, two_panels_and_a_hole):
    out = tmp_path / "out"
    png = tmp_path / "preview.png"
    code = main(["conform", str(two_panels_and_a_hole), "-o", str(out), "--panels", "front",
                 "--corners", "front=12,60,65,17", "--control-points", "8x6", "--preview", str(png), "-q"])
    assert code == 0
    table = capsys.readouterr().out
    assert "front" in table and "8x6" in table and "holey" not in table
    ps = load_patchset(out / "patches.json")
    assert ps.provenance["front"]["corner_vertex_ids"] == [12, 60, 65, 17]
    np.testing.assert_allclose(ps.patch("front").rest[0, 0], [0.04, 0.0])
    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[0] > 500 and (img < 200).any()  # something was drawn


@pytest.mark.parametrize("args, fragment", [
    (["--corners", "front=1,2,3"], "exactly 4"),
    (["--corners", "nowhere=1,2,3,4"], "no panel named nowhere"),
    (["--corners", "front=1,2,3,999"], "corner vertex 999 is not on the panel's boundary"),
    (["--control-points", "4x9"], "N, M >= 5"),
    (["--seam-span", "0"], "--seam-span: must be > 0"),
    (["--panels", "sleeve"], "no panel named sleeve"),
])
def test_conform_command_bad_options(tmp_path, capsys, two_panels_and_a_hole, args, fragment):
    code = main(["conform", str(two_panels_and_a_hole), "-o", str(tmp_path / "o"), "-q", "--panels", "front"] + args)
    err = capsys.readouterr().err
    assert code in (1, 2) and fragment in err and "Traceback" not in err


def _fuzz_seed_panels(path, mutate=None):
    """The panel OBJ the fuzz test mutates (tests/garment/test_fuzz.py make_seeds): a 0.2
    x 0.15 m front, a 0.15 m square back beside it, two stitches; mutate(text) -> text."""
    V, F = grid(5, 4, (0.2, 0.15))
    V2, F2 = grid(4, 4, (0.15, 0.15), (0.3, 0.0))
    write_obj(path, [("front", V, F), ("back", V2, F2)], seams=[[(3, 20, 21, 0.5), (7, 24, 25, 0.0)]])
    if mutate is not None:
        path.write_text(mutate(path.read_text()))
    return path


def test_a_stray_vertex_fails_its_panel_with_the_work_its_area_gets(tmp_path, capsys, monkeypatch):
    """A fuzzed panel file that hung `garment conform --knot-span 60` (> 30 s, 40 s alone):
    the back's corner moved from y = 0.15 to 5 m makes a spike 5 m long and 5 cm wide, both
    pairs of sides long around 0.14 m^2 of cloth, so the net was 85 x 86 for what needs
    ~250 cells and untangling it failed at 85 x 86, 107, 134 and 167. The untangling budget
    (pipeline.untangle_budget) stops it after the work a panel of that area gets. The work
    is counted in untangling steps x net cells, not seconds, so a loaded machine cannot
    fail it (a timed bound of 20 s failed at 23.7 s on a busy CI host)."""
    budgets, work = [], []
    budget_of, solve = pipeline.untangle_budget, pipeline._solve

    def counted_budget(need, options):
        budgets.append(budget_of(need, options))
        return budgets[-1]

    def counted_solve(X, *args, **kwargs):
        res = solve(X, *args, **kwargs)
        work.append((len(budgets), res.untangle_iterations * pipeline._cells(*X.shape[:2])))
        return res

    monkeypatch.setattr(pipeline, "untangle_budget", counted_budget)
    monkeypatch.setattr(pipeline, "_solve", counted_solve)
    path = _fuzz_seed_panels(tmp_path / "panels.obj", lambda t: t.replace("vt 0.45 0.15\n", "vt 0.45 5\n"))
    code = main(["conform", str(path), "-o", str(tmp_path / "out"), "-q", "--knot-span", "60"])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err  # the front converted, the back failed
    assert "panels.obj: panel back: could not untangle the control net (85 x 86)" in err
    assert "28 times the cells" in err and "0.15, 5, 4.95, 0.15 m" in err
    assert "stray vertex" in err and "--corners" in err
    assert [p.name for p in load_patchset(tmp_path / "out" / "patches.json").patches] == ["front"]
    # The back's level (the last budget asked for) spent no more than its budget, which is
    # a fraction of the four full attempts the hang made on its 83 x 84 interior cells.
    spent = sum(w for level, w in work if level == len(budgets))
    hang = 4 * MipsOptions().untangle_iterations * 83 * 84
    assert 0 < spent <= budgets[-1] < hang / 10


def test_panel_names_in_the_table_are_escaped(tmp_path, capsys):
    """Group names come from the file: a NUL byte or rich markup ([/x] raised MarkupError)
    in a name is printed escaped, in the table and the progress bar."""
    name = "b[/x]\x00\x1b[31m"
    path = _fuzz_seed_panels(tmp_path / "panels.obj", lambda t: t.replace("g back", "g " + name))
    assert main(["conform", str(path), "-o", str(tmp_path / "out"), "--knot-span", "60"]) == 0
    captured = capsys.readouterr()
    assert "b[/x]\\x00\\x1b[31m" in captured.out and "Traceback" not in captured.err
    assert not any(c in captured.out + captured.err for c in "\x00\x1b")


def test_output_directory_that_is_a_file(tmp_path, capsys, two_panels_and_a_hole):
    blocker = tmp_path / "taken"
    blocker.write_text("")
    assert main(["conform", str(two_panels_and_a_hole), "-o", str(blocker), "-q"]) == 2
    err = capsys.readouterr().err
    assert "taken" in err and "output directory" in err and "Traceback" not in err


def test_patch_file_errors(tmp_path):
    bad = tmp_path / "p.json"
    bad.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(InputError, match="not a patch file"):
        load_patchset(bad)
    bad.write_text(json.dumps({"format": "bspline-garment/patches", "version": 1, "patches": [
        {"name": "a", "control_points": [5, 5], "rest": [[0, 0]], "world": []}]}))
    with pytest.raises(InputError, match=r"patches\[0\]"):
        load_patchset(bad)


def test_seam_points_map_back_onto_the_rest_points(two_panels_and_a_hole):
    panels, seams = read_panels(two_panels_and_a_hole)
    ps = conform_all(panels[:2], seams, ConformOptions(knot_span=0.03))
    (seam,) = ps.seams
    for name, uv, pts in ((seam.patch_a, seam.uv_a, seams[0].points_a), (seam.patch_b, seam.uv_b, seams[0].points_b)):
        np.testing.assert_allclose(rest_points(ps.patch(name).rest, uv), pts, atol=1e-9)
    # Inverting the rest map finds interior points too.
    X = ps.patch("front").rest
    uv = invert(X, np.array([[0.05, 0.05], [0.17, 0.02]]))
    np.testing.assert_allclose(rest_points(X, uv), [[0.05, 0.05], [0.17, 0.02]], atol=1e-10)


def test_flat_meshes_in_other_formats(tmp_path):
    Va, Fa = grid(5, 4)
    Vb, Fb = grid(4, 4, origin=(0.5, 0.0))
    V = np.concatenate([Va, Vb])
    F = np.concatenate([Fa, Fb + len(Va)])
    # Placed on a tilted plane in 3D: the rest layout is that plane's 2D frame.
    R = np.array([[1, 0, 0], [0, np.cos(0.7), -np.sin(0.7)], [0, np.sin(0.7), np.cos(0.7)]])
    V3 = np.column_stack([V, np.zeros(len(V))]) @ R.T + [0.1, 0.2, 0.3]
    path = tmp_path / "flat.ply"
    trimesh.Trimesh(V3, F, process=False).export(path)
    panels, seams = read_panels(path)
    assert [p.name for p in panels] == ["panel0", "panel1"] and seams == []
    ps = conform_all(panels, [], ConformOptions(knot_span=0.05))
    assert not ps.failures
    np.testing.assert_allclose(ps.quality["panel0"]["input_area_m2"], 0.02, rtol=1e-6)  # PLY: float32
    # The lift reproduces the 3D placement (an isometry of the layout).
    W = ps.patch("panel0").world
    d = np.linalg.norm(W[1:] - W[:-1], axis=-1) / np.linalg.norm(np.diff(ps.patch("panel0").rest, axis=0), axis=-1)
    np.testing.assert_allclose(d, 1.0, atol=1e-5)
    # A curved mesh without a flat layout is refused.
    V3[:, 2] += 0.1 * V3[:, 0] ** 2
    trimesh.Trimesh(V3, F, process=False).export(path)
    with pytest.raises(InputError, match="not flat"):
        read_panels(path)


def test_outline_self_intersections_are_the_pairs_testing_every_pair_finds():
    """The sweep's candidates (boxes overlapping in x, then y) lose no crossing: against
    every pair tested (boxes overlapping, then the orientations), on star-shaped loops
    wild enough to cross themselves, some on a coarse grid so that segments touch, lie
    along each other and share x."""
    from conform.boundary import self_intersections

    def orient(u, v, w):
        return (v[0] - u[0]) * (w[1] - u[1]) - (v[1] - u[1]) * (w[0] - u[0])

    def every_pair(P):
        B, size = len(P), float(np.ptp(P, axis=0).max())
        tol = 1e-12 * size
        out = []
        for i in range(B):
            for j in range(i + 2, B):
                if (i - j) % B == 1:
                    continue
                p1, p2, q1, q2 = P[i], P[(i + 1) % B], P[j], P[(j + 1) % B]
                apart = (np.minimum(p1, p2) > np.maximum(q1, q2) + tol) | (np.minimum(q1, q2) > np.maximum(p1, p2) + tol)
                if not apart.any() and orient(q1, q2, p1) * orient(q1, q2, p2) <= tol * size and \
                        orient(p1, p2, q1) * orient(p1, p2, q2) <= tol * size:
                    out.append((i, j))
        return out

    rng = np.random.default_rng(4)
    crossed = 0
    for trial in range(40):
        B = int(rng.integers(4, 60))
        t = np.sort(rng.uniform(0, 2 * np.pi, B))
        r = 1 + rng.uniform(0, (0.05, 2.0)[trial % 2], B)
        P = np.stack([r * np.cos(t), r * np.sin(t)], 1)
        if trial % 4 == 0:
            P = np.round(P * 4) / 4
        expected = every_pair(P)
        crossed += bool(expected)
        assert self_intersections(P) == expected, trial
    assert 5 < crossed < 40  # loops that cross themselves and loops that do not
