"""`garment dress` end to end on a small garment: a two-panel tube skirt with uneven
(gathered) side seams, from a GarmentCode pattern in centimetres, on a standing cylinder
body in metres and Y-up. Checks the report against the files it wrote and the
independent crossing check; plus the reader's `right_wrong` stitches."""

import json

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh
from scipy.sparse.csgraph import connected_components

from garment.cli import main
from garment.dress.frame import detect
from garment.dress.job import DressOptions, dress, mean_height, verdict
from garment.io.garmentcode import read_garmentcode
from garment.verify import intersecting_triangles, shared_vertices


def rect(w, h, x0=0.0):
    return [[x0, 0], [x0 + w, 0], [x0 + w, h], [x0, h]]


def panel(vertices, translation, rotation=(0, 0, 0)):
    edges = [{"endpoints": [i, (i + 1) % len(vertices)]} for i in range(len(vertices))]
    return {"vertices": vertices, "edges": edges, "translation": list(translation), "rotation": list(rotation)}


def tube_skirt(path, back_height=34.0):
    """Front 40 x 30 cm in front of the body, back 40 x back_height cm behind it (turned
    180 degrees about Y so both face out); the side seams join edges of different lengths."""
    front = panel(rect(40, 30), (-20, 80, 18))
    back = panel(rect(40, back_height), (20, 80 - (back_height - 30), -18), (0, 180, 0))
    spec = {"pattern": {"panels": {"front": front, "back": back},
                        # edge 1 is the right side (going up), edge 3 the left side (going down)
                        "stitches": [[{"panel": "front", "edge": 1}, {"panel": "back", "edge": 3}],
                                     [{"panel": "front", "edge": 3}, {"panel": "back", "edge": 1}]]},
            "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}
    path.write_text(json.dumps(spec))
    return path


def cylinder_body(path):
    """A standing cylinder (r = 10 cm, 1.7 m) with a hip (a 16 cm sphere at 65 cm) the
    skirt comes to rest on: Y-up, in metres, feet on y = 0."""
    trunk = trimesh.creation.cylinder(radius=0.10, height=1.7, sections=24).subdivide_to_size(0.08)
    trunk.apply_translation([0, 0, 0.85])
    hip = trimesh.creation.icosphere(subdivisions=2, radius=0.16)
    hip.apply_translation([0, 0, 0.65])
    body = trimesh.util.concatenate([trunk, hip])
    V = np.asarray(body.vertices)[:, [0, 2, 1]] * [1, 1, -1]  # Z-up to Y-up
    trimesh.Trimesh(V, np.asarray(body.faces), process=False).export(path)
    return path


def test_units_and_up_axis_detected():
    person = np.array([[0, 0, 0], [0.5, 1.75, 0.3]])
    assert detect(person).unit == "m" and detect(person).up == "y"
    assert detect(person[:, [0, 2, 1]] * 100).unit == "cm" and detect(person[:, [0, 2, 1]] * 100).up == "z"
    assert detect(person * 10).unit == "dm"  # MakeHuman
    assert detect(person * 1000).unit == "mm"
    with pytest.raises(Exception, match="cannot tell the body's units"):
        detect(np.array([[0, 0, 0], [5.0, 5.0, 5.0]]))


def test_right_wrong_stitch_runs_the_same_way(tmp_path):
    spec = json.loads(tube_skirt(tmp_path / "p.json").read_text())
    spec["pattern"]["stitches"][0].append("right_wrong")
    (tmp_path / "rw.json").write_text(json.dumps(spec))
    _, normal = read_garmentcode(tmp_path / "p.json")
    _, flipped = read_garmentcode(tmp_path / "rw.json")
    # The same edge pair: normally the start of one meets the end of the other; with
    # right_wrong start meets start.
    np.testing.assert_allclose(flipped[0].points_b, normal[0].points_b[::-1], atol=1e-12)
    np.testing.assert_allclose(flipped[1].points_b, normal[1].points_b, atol=1e-12)
    spec["pattern"]["stitches"][0][2:] = ["right_wrong", "extra"]
    (tmp_path / "bad.json").write_text(json.dumps(spec))
    with pytest.raises(Exception, match=r"stitches\[0\]"):
        read_garmentcode(tmp_path / "bad.json")


def test_gathered_seam_samples_at_equal_length_fractions(tmp_path):
    _, seams = read_garmentcode(tube_skirt(tmp_path / "p.json", back_height=40.0))
    a, b = seams[0].points_a, seams[0].points_b
    la = np.linalg.norm(np.diff(a, axis=0), axis=1)
    lb = np.linalg.norm(np.diff(b, axis=0), axis=1)
    np.testing.assert_allclose(lb / la, 40.0 / 30.0, rtol=1e-9)  # the longer edge eased in evenly


def test_a_split_step_is_counted_in_its_phase_with_why_it_failed(tmp_path, monkeypatch):
    """A failed step is retried as two halves; the report counts it in its phase (the
    failed attempt's time is in the phase's seconds, not its iterations) and says why."""
    import sim.recovery

    real, calls = sim.recovery.failure, []

    def fails_once(s, st):
        calls.append(st.time)
        return "a failure made up for the test" if len(calls) == 3 else real(s, st)

    monkeypatch.setattr(sim.recovery, "failure", fails_once)
    pattern = tube_skirt(tmp_path / "skirt.json")
    with pytest.warns(sim.recovery.SplitWarning):
        report = dress(pattern, cylinder_body(tmp_path / "body.obj"), tmp_path / "out", {"max_time": 0.05})
    assert [p["splits"] for p in report["phases"].values()] == [1, 0, 0]
    assert report["phases"]["sewing"]["steps"] == 5  # the third taken as two halves counts once
    assert len(report["splits"]) == 1 and "a failure made up for the test" in report["splits"][0]
    assert report["splits"][0].startswith("t = 0.02 s")


def test_dress_a_small_garment_end_to_end(tmp_path):
    pattern = tube_skirt(tmp_path / "skirt.json")
    body = cylinder_body(tmp_path / "body.obj")
    out = tmp_path / "out"
    report = dress(pattern, body, out, {"max_time": 2.5})  # at rest at 1.24 s (settle_dt 0.08: 1.96 s)
    assert report["status"] == "ok", report
    assert report["body_frame"] == "m, Y-up"
    assert report["seam_gap_max_mm"] < 1.0
    assert report["crossings"] == 0 and report["dofs"] > 0
    assert report["body_lag_mm"] < 0.1  # the body grew back all the way: nothing held it
    assert json.loads((out / "report.json").read_text())["status"] == "ok"
    # Where the time went: every step in one phase (0.6 s of sewing: 0.32 s at dt = 0.01 s,
    # to the first frame end once the body grows, 0.28 s at grow_dt = 0.02 s; then the
    # ramp, 0.6-0.8 s, and the settling at settle_dt).
    phases = report["phases"]
    o = DressOptions()
    ramp_steps = int(o.gravity_ramp / o.settle_dt + 1e-9)  # steps ending within the ramp
    assert [phases[k]["steps"] for k in ("sewing", "gravity_ramp")] == [32 + 14, ramp_steps]
    assert sum(p["steps"] for p in phases.values()) == 46 + round((report["simulated_s"] - o.sew_time) / o.settle_dt)
    assert all(p["newton_iterations"] >= p["steps"] for p in phases.values())
    assert 0 < report["placing_s"] + sum(p["seconds"] for p in phases.values()) <= report["seconds"]
    assert (out / "run.rrd").stat().st_size > 0
    # garment.obj: the settled garment in the body file's frame, independently clean
    # against the body and itself.
    G = trimesh.load(out / "garment.obj", process=False)
    B = trimesh.load(body, process=False)
    X, T = shared_vertices(np.asarray(G.vertices), np.asarray(G.faces))
    assert len(intersecting_triangles(X, T, np.asarray(B.vertices), np.asarray(B.faces))) == 0
    assert len(intersecting_triangles(X, T)) == 0
    # Hanging around the hips of a Y-up body: below where the panels started (y <= 1.1 m).
    assert 0.5 < X[:, 1].min() and X[:, 1].max() < 1.1
    # The side seams closed: the front and back meet (one connected garment).
    adjacency = sp.coo_matrix((np.ones(3 * len(T)), (T.ravel(), np.roll(T, 1, axis=1).ravel())), (len(X),) * 2)
    assert connected_components(adjacency, directed=False)[0] == 1


def test_a_run_stopped_by_the_simulator_reports_how_far_it_got(tmp_path, monkeypatch):
    import sim.driver
    from sim.errors import SimulationError

    drive = sim.driver.drive

    def three_frames_then_stuck(sim_, frames, *args, **kwargs):
        drive(sim_, 3, *args, **kwargs)
        raise SimulationError("Newton hit its iteration cap")

    monkeypatch.setattr(sim.driver, "drive", three_frames_then_stuck)
    out = tmp_path / "out"
    report = dress(tube_skirt(tmp_path / "skirt.json"), cylinder_body(tmp_path / "body.obj"), out)
    assert report["status"] == "sewing" and "iteration cap" in report["error"]
    assert report["simulated_s"] == pytest.approx(0.12)  # 3 frames of 4 steps of 0.01 s
    # The seams still closing (the widest first, as at the end of a run) and the
    # independent check of the 4 frames written (the start and 3 more).
    gaps = list(report["worst_seams_mm"].values())
    assert gaps == sorted(gaps, reverse=True) and gaps[0] == pytest.approx(report["seam_gap_max_mm"], abs=0.01)
    assert gaps[0] > 1.0
    assert report["crossings"] == 0
    assert json.loads((out / "report.json").read_text())["worst_seams_mm"] == report["worst_seams_mm"]


def test_dress_command_reports_bad_input(tmp_path, capsys):
    body = tmp_path / "box.obj"
    trimesh.creation.box((5, 5, 5)).export(body)
    code = main(["dress", str(tube_skirt(tmp_path / "s.json")), "--body", str(body), "-o", str(tmp_path / "o")])
    assert code == 2
    assert "cannot tell the body's units" in capsys.readouterr().err


def test_dress_command_refuses_unknown_settings_and_scenes_without_a_body(tmp_path, capsys):
    pattern = tube_skirt(tmp_path / "s.json")
    body = cylinder_body(tmp_path / "b.obj")
    assert main(["dress", str(pattern), "--body", str(body), "-o", str(tmp_path / "o"), "--set", "knot=3"]) == 2
    assert "unknown dress setting 'knot'" in capsys.readouterr().err
    assert main(["dress", str(pattern), "--body", str(body), "-o", str(tmp_path / "o"), "--set", "dt=-1"]) == 2
    assert "dress setting dt = '-1': must be > 0" in capsys.readouterr().err
    assert main(["dress", str(pattern), "--body", str(body), "-o", str(tmp_path / "o"), "--set", "newton_extrapolate=-1"]) == 2
    assert "must be >= 0" in capsys.readouterr().err
    assert DressOptions.with_overrides({"newton_extrapolate": "0", "eps_v": "1e-3"}).newton_extrapolate == 0
    scene = tmp_path / "scene.toml"
    scene.write_text('[[garment]]\nsource = "s.json"\n')
    assert main(["dress", str(scene), "-o", str(tmp_path / "o")]) == 2
    assert "needs a scene with [[garment]] source and an [[obstacle]] mesh" in capsys.readouterr().err
    assert not (tmp_path / "o" / "report.json").exists()


def test_a_panel_pinched_to_nothing_is_named_with_where_it_pinches(tmp_path):
    from conform.pipeline import ConformOptions
    from garment.dress.job import _fold_reason

    # A 40 x 30 cm torso with a 30 cm strap whose sides come within 0.5 mm of each other
    # halfway up (upper_garment_06's back torso: 0.1 mm), and the same strap 2 cm wide there.
    def strap(waist):
        half = waist / 2
        return [[0, 0], [40, 0], [40, 30], [22, 30], [20 + half, 45], [21, 60], [18, 60], [20 - half, 45],
                [17, 30], [0, 30]]

    options = ConformOptions(knot_span=0.04)
    path = tmp_path / "pinched.json"
    path.write_text(json.dumps({"pattern": {"panels": {"back": panel(strap(0.05), (0, 0, 0))}, "stitches": []},
                                "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}))
    panels, _ = read_garmentcode(path)
    reason = _fold_reason("back", panels, options)
    assert "panel back's outline narrows to" in reason and "(20.0, 45.0) cm" in reason
    width = float(reason.split("narrows to ")[1].split(" mm")[0])
    assert 0.5 <= width < 3.0
    path.write_text(json.dumps({"pattern": {"panels": {"back": panel(strap(2.0), (0, 0, 0))}, "stitches": []},
                                "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}))
    panels, _ = read_garmentcode(path)
    assert "narrows" not in _fold_reason("back", panels, options)


def test_the_report_names_the_gravest_failure_first():
    seams = {"stitch1": 2.5}
    assert verdict(True, 3, 600.0, 2.5e-3, seams)[0] == "nan"
    status, error = verdict(False, 16, 600.0, 2.5e-3, seams)  # crossings in a run that also timed out
    assert status == "intersection" and error.startswith("16 intersecting")
    assert verdict(False, 0, 600.0, 2.5e-3, seams) == ("timeout", "not at rest after 600 s of wall-clock time")
    # Lying still with a seam open until the limit: the seam is what failed, not the time.
    assert verdict(False, 0, 600.0, 2.5e-3, seams, still=True) == ("sewing",
                                                                   "at rest with seams still open: stitch1 2.5 mm")
    assert verdict(False, 0, 600.0, 0.5e-3, {"stitch1": 0.5}, still=True)[0] == "timeout"
    assert verdict(False, 0, None, 2.5e-3, seams) == ("sewing", "seams still open: stitch1 2.5 mm")
    assert verdict(False, 0, None, 0.9996e-3, {"stitch1": 1.0}) == ("ok", None)
    # Slid off the body: said as such, before the time limit it would otherwise run into.
    status, error = verdict(False, 0, 600.0, 0.5e-3, {"stitch1": 0.5}, fell=(1.23, 0.31))
    assert status == "placement" and "slid off the body: by t = 1.23 s it had dropped 0.31 m" in error
    why = "its top opening (wb_back, wb_front) is 157 cm round, and the body's trunk is at most 107 cm round"
    assert verdict(False, 0, None, 0.5e-3, {"stitch1": 0.5}, fell=(1.28, 0.26, why))[1].endswith("; " + why)
    assert verdict(False, 2, None, 0.5e-3, seams, fell=(1.0, 0.3))[0] == "intersection"
    # Still moving when the simulated time ran out: not settled, whatever its seams.
    assert verdict(False, 0, None, 0.5e-3, {"stitch1": 0.5}, moving=(2.52, 26.3)) == (
        "timeout", "not at rest after 2.52 s of simulated time (max_time) (RMS control-point speed 26.3 mm/s)")


def test_mean_height_of_a_garment_counts_every_vertex_of_every_piece():
    tri = np.array([[0, 1, 2]])
    skirt = (np.array([[0.2, 0.0, 0.5], [0.3, 0.0, 1.0], [0.2, 0.1, -0.15]]), tri)
    top = (np.array([[0.2, 0.0, 1.2], [0.3, 0.0, 1.5], [0.2, 0.1, 1.3], [0.0, 0.0, 1.4]]), tri)
    assert abs(mean_height([skirt, top]) - (0.5 + 1.0 - 0.15 + 1.2 + 1.5 + 1.3 + 1.4) / 7) < 1e-12
    assert abs(mean_height([skirt]) - 0.45) < 1e-12
