"""A scene that names a garment and a still body and nothing of where the garment starts
is dressed as `garment dress` dresses (garment/dress/scene_file.py): end to end through
`garment simulate` on the small tube skirt and cylinder body of test_dress.py, checked
by the independent crossing test on every exported frame."""

import json

import numpy as np
import pytest

from garment.cli import main
from garment.dress.job import DressOptions
from garment.dress.scene_file import dress_settings, leaves_placement, scene_for_run
from garment.scene.read import read_scene_data
from sim.errors import InputError
from tests.support.check_frames import check_frame, frames

from .test_dress import cylinder_body, tube_skirt

SCENE = """
[scene]
name = "skirt"
[material]
preset = "cotton"
[[garment]]
name = "skirt"
source = "skirt.json"
knot_span_mm = 40
[[obstacle]]
name = "body"
mesh = "body.obj"
[contact]
mu = 0.3
[time]
frames = {frames}
"""


def write_scene(folder, text):
    tube_skirt(folder / "skirt.json")
    cylinder_body(folder / "body.obj")
    path = folder / "scene.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("table, key, value", [("obstacle", "inset", "0.02"), ("obstacle", "translate", "[0, 0, 0.1]"),
                                               ("time", "preroll", "0.3"), ("time", "sewing", '"quasistatic"')])
def test_a_scene_that_places_its_garment_is_taken_as_written(tmp_path, table, key, value):
    path = write_scene(tmp_path, SCENE.format(frames=5))
    assert leaves_placement(read_scene_data(path))
    text = path.read_text().replace(f"[{table}]\n" if table == "time" else "[[obstacle]]\n",
                                    (f"[{table}]\n" if table == "time" else "[[obstacle]]\n") + f"{key} = {value}\n")
    path.write_text(text)
    assert not leaves_placement(read_scene_data(path))


def test_the_scene_s_physical_choices_reach_the_dress_settings(tmp_path):
    path = write_scene(tmp_path, SCENE.format(frames=5))
    assert dress_settings(read_scene_data(path), path) == {"material": "cotton", "knot_span_mm": 40, "mu": 0.3}


def test_a_key_the_dressing_sets_itself_is_refused_with_the_way_out(tmp_path, capsys):
    path = write_scene(tmp_path, SCENE.format(frames=5) + "[load]\ngravity = [0.0, -9.81, 0.0]\n")
    with pytest.raises(InputError, match=r"\[load\] gravity: this scene leaves the garment's start to the toolkit"):
        dress_settings(read_scene_data(path), path)
    out = tmp_path / "out" / "run.rrd"
    assert main(["simulate", str(path), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "scene.toml" in err and "give [time] preroll" in err
    assert not out.exists()


def test_a_placement_free_scene_is_placed_sewn_and_settled_by_simulate(tmp_path):
    # 20 frames of 4 steps of 0.01 s: sewn on the slimmed body by 0.3 s, grown back by
    # 0.6 s, gravity ramped in by 0.8 s.
    path = write_scene(tmp_path, SCENE.format(frames=20))
    rrd, meshes = tmp_path / "out" / "skirt.rrd", tmp_path / "out" / "mesh"
    assert main(["simulate", str(path), "-o", str(rrd), "--mesh-dir", str(meshes), "-q"]) == 0
    assert (tmp_path / "out" / "skirt" / "patches.json").is_file() and rrd.stat().st_size > 0
    exported = frames(meshes)
    assert len(exported) == 21
    for k, m in exported.items():
        r = check_frame(m)
        assert r["finite"] and r["body"] == 0 and r["self"] == 0, (k, r)
    # Sewn: the two panels' seam vertices coincide bit for bit in the last frame (the
    # cloth is one connected surface), and it hangs on the hip below where it started.
    assert check_frame(exported[0])["shared"] == 0 and check_frame(exported[20])["shared"] > 0
    z = [m["verts"][:, 2] for m in exported[20].values() if m["cloth"]]
    assert max(v.max() for v in z) < 1.1


def test_a_placement_free_scene_on_an_animated_body_sews_on_its_first_pose_then_moves(tmp_path):
    # The cylinder body as a 3-frame animation sliding 2 cm along x (Y-up, 0.04 s frames):
    # it holds its first pose through the 0.6 s pre-roll while the skirt is sewn, then moves.
    import numpy as np
    import trimesh

    write_scene(tmp_path, "")
    body = trimesh.load(tmp_path / "body.obj", process=False)
    V = np.asarray(body.vertices)
    verts = np.stack([V + [0.01 * k, 0.0, 0.0] for k in range(3)])
    np.savez(tmp_path / "body.npz", verts=verts, faces=np.asarray(body.faces), frame_dt=0.04)
    text = SCENE.format(frames=18).replace('mesh = "body.obj"', 'animation = "body.npz"\nup = "y"')
    path = tmp_path / "scene.toml"
    path.write_text(text)
    assert leaves_placement(read_scene_data(path))
    rrd, meshes = tmp_path / "out" / "skirt.rrd", tmp_path / "out" / "mesh"
    assert main(["simulate", str(path), "-o", str(rrd), "--mesh-dir", str(meshes), "-q"]) == 0
    exported = frames(meshes)
    for k, m in exported.items():
        r = check_frame(m)
        assert r["finite"] and r["body"] == 0 and r["self"] == 0, (k, r)
    assert check_frame(exported[18])["shared"] > 0  # sewn

    def body_x(k):
        return next(m["verts"][:, 0].mean() for m in exported[k].values() if not m["cloth"])

    assert body_x(15) == pytest.approx(body_x(0), abs=1e-9)  # held through the pre-roll (0.6 s)
    assert body_x(18) - body_x(0) == pytest.approx(0.02, abs=1e-6)  # then the whole motion


def test_scene_for_run_dresses_a_placement_free_scene_and_takes_others_as_written(tmp_path):
    # What `garment simulate` runs, for the benchmarks and tests that build a scene file's
    # simulation themselves: the tube skirt placed (its patches written beside), the
    # garment keys given changed first; a scene that places its garment is only read.
    path = write_scene(tmp_path, SCENE.format(frames=4))
    points = {}
    for span in (40, 80):
        placed = tmp_path / f"placed{span}"
        scene = scene_for_run(path, placed, {"knot_span_mm": span})
        (garment,) = scene.garments
        assert garment.source == (placed / "patches.json").resolve() and garment.source.is_file()
        assert scene.time.preroll == pytest.approx(DressOptions().sew_time)
        points[span] = sum(np.prod(p["control_points"]) for p in json.loads(garment.source.read_text())["patches"])
    assert points[80] < points[40]  # conformed at the span given
    manual = tmp_path / "manual.toml"
    manual.write_text(SCENE.format(frames=4).replace("[time]", "[time]\npreroll = 0.3"))
    scene = scene_for_run(manual, tmp_path / "unused", {"knot_span_mm": 50, "seam_span_mm": None})
    assert scene.garments[0].knot_span == pytest.approx(0.05) and scene.garments[0].seam_span is None
    assert not (tmp_path / "unused").exists()
