"""Malformed input gauntlet: every bad scene, body sequence, panel, pattern or patch file
gives one paragraph naming the file and the problem, a non-zero exit, no traceback and
no partial outputs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from garment.cli import main
from sim.errors import InputError
from garment.io.patchfile import load_patchset

from tests.support.panels import bad_panels, write_obj

SCENE = """
[[cloth]]
name = "sheet"
size = [0.3, 0.3]
control_points = [6, 6]
origin = [-0.15, -0.15, 0.2]

[time]
dt = 0.01
frames = 2
"""


def body_npz(tmp: Path, case: str) -> str:
    """An icosphere body sequence with one defect."""
    m = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
    verts = np.stack([m.vertices, m.vertices + [0, 0, 0.01]])
    arrays = {"verts": verts, "faces": np.asarray(m.faces), "frame_dt": 0.04}
    if case == "nan":
        verts[1, 2, 1] = np.nan
    elif case == "cm":
        arrays["verts"] = verts * 100.0
    elif case == "no_faces":
        del arrays["faces"]
    elif case == "bad_index":
        arrays["faces"] = arrays["faces"] + 500
    elif case == "flat_verts":
        arrays["verts"] = verts.reshape(2, -1)
    elif case == "y_up":  # a standing person exported Y-up: 1.7 m along Y
        arrays["verts"] = verts * [4.0, 17.0, 3.0]
    np.savez(tmp / "body.npz", **arrays)
    return 'animation = "body.npz"'


def obj_dir(tmp: Path) -> str:
    d = tmp / "frames"
    d.mkdir()
    trimesh.creation.icosphere(subdivisions=1, radius=0.05).export(d / "f1.obj")
    trimesh.creation.icosphere(subdivisions=2, radius=0.05).export(d / "f2.obj")
    return 'animation = "frames"\nfps = 25'


def with_obstacle(body: str) -> str:
    return SCENE + f'\n[[obstacle]]\nname = "body"\n{body}\n'


# (id, scene text or a function of tmp_path giving it, extra CLI args, fragments in the message)
SCENES = [
    ("unknown_key", SCENE.replace("dt = 0.01", "dtt = 0.01"), [], ["time.dtt"]),
    ("unknown_table", SCENE + "\n[clothes]\nx = 1\n", [], ["clothes"]),
    ("wrong_type", SCENE.replace("frames = 2", 'frames = "two"'), [], ["time.frames"]),
    ("wrong_length", SCENE.replace("[6, 6]", "[6, 6, 6]"), [], ["cloth[0].control_points"]),
    ("nan_number", SCENE.replace("dt = 0.01", "dt = nan"), [], ["time.dt"]),
    ("negative", SCENE.replace("size = [0.3, 0.3]", "size = [-0.3, 0.3]"), [], ["cloth[0].size"]),
    ("toml_syntax", SCENE + "\n[time\n", [], ["<toml>"]),
    ("pin_unknown_cloth", SCENE + '\n[[pin]]\ncloth = "shirt"\ncorners = ["u0v0"]\n', [], ["pin", "shirt"]),
    ("missing_mesh", with_obstacle('mesh = "nowhere.obj"'), [], ["nowhere.obj", "no such file"]),
    ("garbage_mesh", lambda t: (t / "junk.obj").write_text("this is not\na mesh\n") and with_obstacle(
        'mesh = "junk.obj"'), [], ["junk.obj"]),
    ("body_nan", lambda t: with_obstacle(body_npz(t, "nan")), [], ["body.npz", "non-finite"]),
    ("body_centimetres", lambda t: with_obstacle(body_npz(t, "cm")), [], ["body.npz", "not in metres"]),
    ("body_missing_faces", lambda t: with_obstacle(body_npz(t, "no_faces")), [], ["body.npz", "lacks faces"]),
    ("body_inconsistent_faces", lambda t: with_obstacle(body_npz(t, "bad_index")), [], ["body.npz", "faces index"]),
    ("body_wrong_shape", lambda t: with_obstacle(body_npz(t, "flat_verts")), [], ["body.npz", "verts has shape"]),
    ("body_not_npz", lambda t: (t / "body.npz").write_bytes(b"\x00garbage") and with_obstacle(
        'animation = "body.npz"'), [], ["body.npz", "not an NPZ archive"]),
    ("body_y_up", lambda t: with_obstacle(body_npz(t, "y_up")), [], ["body.npz", "looks Y-up", 'up = "y"']),
    ("obj_frames_topology", lambda t: with_obstacle(obj_dir(t)), [], ["f2.obj", "topology differs"]),
    ("missing_body", with_obstacle('animation = "gone.npz"'), [], ["gone.npz"]),
    ("cloth_inside_body", SCENE.replace("0.2]", "0.0]") + '\n[[obstacle]]\nname = "ball"\n'
     'sphere = { center = [0.0, 0.0, 0.0], radius = 0.05 }\n', [], ["scene.toml", "intersects", "and obstacle 'ball'"]),
    ("resume_without_checkpoint", SCENE, ["--resume"], ["no checkpoint"]),
]


def scene_case(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(text(tmp_path) if callable(text) else text)
    return path


def check_clean_failure(code: int, err: str, fragments, outputs) -> None:
    assert code != 0
    assert "Traceback" not in err
    paragraph = err.strip()
    assert paragraph and "\n\n" not in paragraph, err  # one paragraph
    assert paragraph.startswith("error:"), err
    for f in fragments:
        assert f in paragraph, (f, err)
    for p in outputs:
        assert not p.exists(), f"partial output {p}"


@pytest.mark.parametrize("case, text, args, fragments", SCENES, ids=[c[0] for c in SCENES])
def test_bad_scene_inputs(tmp_path, capsys, case, text, args, fragments):
    scene = scene_case(tmp_path, text)
    out, frames = tmp_path / "out" / "run.rrd", tmp_path / "out" / "frames"
    code = main(["simulate", str(scene), "-o", str(out), "--mesh-dir", str(frames), "-q", *args])
    check_clean_failure(code, capsys.readouterr().err, fragments, [tmp_path / "out"])


def test_missing_scene_file(tmp_path, capsys):
    code = main(["simulate", str(tmp_path / "nope.toml"), "-o", str(tmp_path / "run.rrd"), "-q"])
    check_clean_failure(code, capsys.readouterr().err, ["nope.toml", "no such file"], [tmp_path / "run.rrd"])


def test_resume_with_a_checkpoint_of_another_scene(tmp_path, capsys):
    scene = scene_case(tmp_path, SCENE)
    out = tmp_path / "run.rrd"
    assert main(["simulate", str(scene), "-o", str(out), "-q", "--frames", "1"]) == 0
    scene.write_text(SCENE.replace("dt = 0.01", "dt = 0.02"))
    code = main(["simulate", str(scene), "-o", str(out), "-q", "--resume"])
    err = capsys.readouterr().err
    check_clean_failure(code, err, ["run.ckpt.npz", "different scene"], [tmp_path / "run.part2.rrd"])


# ------------------------------------------------------------------ panels and patterns


PANELS = [(name, fragment) for name, (_, _, fragment) in bad_panels().items()
          if name in ("hole", "nonmanifold", "degenerate", "two_pieces", "folded")]


@pytest.mark.parametrize("name, fragment", PANELS, ids=[p[0] for p in PANELS])
def test_bad_panels_through_conform(tmp_path, capsys, name, fragment):
    V, F, _ = bad_panels()[name]
    path = write_obj(tmp_path / "bad.obj", [(name, V, F)])
    out = tmp_path / "out"
    code = main(["conform", str(path), "-o", str(out), "-q"])
    check_clean_failure(code, capsys.readouterr().err, ["bad.obj", f"panel {name}", fragment], [out])


def garmentcode(tmp: Path, case: str) -> Path:
    panel = {"translation": [0, 0, 0], "rotation": [0, 0, 0],
             "vertices": [[0, 0], [20, 0], [20, 20], [0, 20]],
             "edges": [{"endpoints": [0, 1]}, {"endpoints": [1, 2]}, {"endpoints": [2, 3]}, {"endpoints": [3, 0]}]}
    spec = {"pattern": {"panels": {"front": panel}, "stitches": []}, "properties": {"units_in_meter": 100}}
    if case == "no_pattern":
        spec = {"properties": {}}
    elif case == "no_edges":
        del panel["edges"]
    elif case == "vertex_type":
        panel["vertices"][1] = "twenty"
    elif case == "bad_stitch":
        spec["pattern"]["stitches"] = [[{"panel": "front", "edge": 0}, {"panel": "back", "edge": 1}]]
    path = tmp / "pattern.json"
    path.write_text("{ not json" if case == "not_json" else json.dumps(spec))
    return path


GARMENTCODE = [
    ("not_json", "not a GarmentCode pattern"),
    ("no_pattern", "not a GarmentCode pattern"),
    ("no_edges", "panel front"),
    ("vertex_type", "panel front"),
    ("bad_stitch", "stitches[0]"),
]


@pytest.mark.parametrize("case, fragment", GARMENTCODE, ids=[g[0] for g in GARMENTCODE])
def test_bad_garmentcode_through_conform(tmp_path, capsys, case, fragment):
    path = garmentcode(tmp_path, case)
    out = tmp_path / "out"
    code = main(["conform", str(path), "-o", str(out), "-q"])
    check_clean_failure(code, capsys.readouterr().err, ["pattern.json", fragment], [out])


def test_panel_obj_syntax_and_missing_file(tmp_path, capsys):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2\n")
    out = tmp_path / "out"
    check_clean_failure(main(["conform", str(bad), "-o", str(out), "-q"]), capsys.readouterr().err,
                        ["bad.obj:2"], [out])
    check_clean_failure(main(["conform", str(tmp_path / "gone.obj"), "-o", str(out), "-q"]),
                        capsys.readouterr().err, ["gone.obj", "no such file"], [out])


PATCHFILES = [
    ("not_json", "{ nope", "not JSON"),
    ("wrong_format", json.dumps({"format": "other"}), "not a patch file"),
    ("wrong_version", json.dumps({"format": "bspline-garment/patches", "version": 99}), "version 99"),
    ("rest_shape", json.dumps({"format": "bspline-garment/patches", "version": 1, "patches": [
        {"name": "a", "control_points": [5, 5], "rest": [[0, 0]], "world": []}]}), "patches[0]"),
    ("missing_key", json.dumps({"format": "bspline-garment/patches", "version": 1, "patches": [
        {"name": "a", "rest": [], "world": []}]}), "patches[0]"),
    ("seam_patch", json.dumps({"format": "bspline-garment/patches", "version": 1, "patches": [],
                               "seams": [{"name": "s", "a": {"patch": "x"}, "b": {}}]}), "seams[0]"),
]


@pytest.mark.parametrize("case, text, fragment", PATCHFILES, ids=[p[0] for p in PATCHFILES])
def test_bad_patch_files(tmp_path, case, text, fragment):
    path = tmp_path / "patches.json"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        load_patchset(path)
    msg = str(e.value)
    assert "patches.json" in msg and fragment in msg and "\n" not in msg
