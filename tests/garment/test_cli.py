"""End to end through the command line: scene -> simulate -> .rrd + per-frame meshes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from garment.cli import main
from garment.commands.simulate import print_how_to_open
from garment.io import read_frame
from garment.scene import loads_scene
from garment.build import build_simulator
from viz.recording import read_rrd_positions

from tests.support.scenes import HANGING_SHEET


def test_simulate_writes_recording_and_meshes(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(HANGING_SHEET)
    rrd, frames = tmp_path / "run.rrd", tmp_path / "frames"
    assert main(["simulate", str(scene), "-o", str(rrd), "--mesh-dir", str(frames)]) == 0
    out = capsys.readouterr().out  # how to open the outputs
    assert f"rerun {rrd}" in out and f"garment view {rrd}" in out and f"meshes:    {frames}" in out

    # The same scene from Python gives the same final frame: the CLI is a thin layer.
    sim = build_simulator(loads_scene(HANGING_SHEET))
    for _ in range(8):
        sim.step()
    expected = sim.positions("sheet")

    positions = read_rrd_positions(rrd)["sheet"]
    assert positions.shape[0] == 5  # initial frame + 4
    np.testing.assert_allclose(positions[-1], expected, atol=1e-6)
    verts, faces = read_frame(frames / "sheet_00004.npz")
    np.testing.assert_allclose(verts, expected, atol=1e-12)
    assert faces.max() < verts.shape[0]
    # The sheet fell: the free bottom edge is below where it started.
    assert expected[:, 2].min() < positions[0][:, 2].min() - 1e-3
    assert not list(tmp_path.glob("**/.*tmp"))


@pytest.mark.parametrize(
    "text, fragment",
    [
        (HANGING_SHEET.replace("dt = 0.01", "dtt = 0.01"), "time.dtt"),
        (HANGING_SHEET.replace("dt = 0.01", "dt = -0.01"), "time.dt"),
        (HANGING_SHEET.replace("[7, 6]", "[4, 6]"), "cloth[0].control_points"),
        (HANGING_SHEET + "\n[material]\nnu = 0.5\n", "material.nu"),
        (HANGING_SHEET + "\n[material]\nE_st = nan\n", "material.E_st"),
    ],
)
def test_bad_scene_exits_with_message(tmp_path, capsys, text, fragment):
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    out = tmp_path / "never.rrd"
    assert main(["simulate", str(scene), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "bad.toml" in err
    assert "Traceback" not in err
    assert not out.exists()


def test_missing_scene_file(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "nope.toml")]) == 2
    assert "nope.toml" in capsys.readouterr().err


def test_bench_json_plate(capsys):
    assert main(["bench", "plate", "--resolution", "16", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["benchmark"] == "plate"
    (case,) = data["cases"]
    assert case["resolution"] == 16 and case["dofs"] == 3 * 14 * 14
    assert case["rel_error"] < 0.01


def test_bench_json_cloth_case(capsys):
    assert main(["bench", "hanging", "--resolution", "12", "--steps", "2", "--json"]) == 0
    (case,) = json.loads(capsys.readouterr().out)["cases"]
    assert case["steps"] == 2 and case["newton_iterations_per_step"] >= 1
    assert case["seconds_per_step"] > 0 and case["dofs"] == 3 * (144 - 2)


def test_how_to_open_a_resumed_run(tmp_path, capsys):
    """Every part of a resumed recording, the video and the mesh folder; nothing missing."""
    rrd, video = tmp_path / "run.rrd", tmp_path / "run.mp4"
    for p in (rrd, tmp_path / "run.part2.rrd", video):
        p.write_bytes(b"")
    print_how_to_open(rrd, video, tmp_path / "no_frames", resumed=True)
    out = capsys.readouterr().out
    both = f"{rrd} {tmp_path / 'run.part2.rrd'}"
    assert f"rerun {both}" in out and f"garment view {both}" in out
    assert f"video:     {video}" in out and "meshes" not in out
    print_how_to_open(rrd, None, None)  # not resumed: the parts on disk are another run's
    assert "part2" not in capsys.readouterr().out
