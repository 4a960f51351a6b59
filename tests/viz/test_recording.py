"""Reading recordings back: damaged files, summaries, and `garment inspect` end to end."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest

from garment.cli import main
from sim.errors import InputError
from garment.scene import loads_scene
from garment.build import build_simulator
from sim.sinks import Frame
from sim.stats import StepStats
from viz.recording import export_mesh, load_recording
from viz.render import FrameBuffer
from viz.rerun_sink import RerunSink

from tests.support.meshes import MESHES, positions
from tests.support.scenes import HANGING_SHEET

N = 12  # frames in the recordings that get damaged


@pytest.fixture(scope="module")
def flushed_rrd(tmp_path_factory):
    """N frames, flushed after every frame so the file grows frame by frame (as a long
    run's does) and truncation keeps a prefix of the frames."""
    path = tmp_path_factory.mktemp("rrd") / "run.rrd"
    sink = RerunSink(path, flush_interval=0.0)
    sink.open(MESHES)
    for k in range(N):
        steps = [StepStats(step=k, time=k / 30, newton_iterations=3)] if k else []
        sink.write(Frame(k, k / 30, {m.name: positions(m, k) for m in MESHES}, steps))
    sink.close()
    return path


def assert_frames_exact(rec) -> None:
    for m in MESHES:
        for k in rec.frames:
            np.testing.assert_array_equal(rec.positions_at(m.name, k), positions(m, k).astype(np.float32))


def test_intact_file(flushed_rrd):
    rec = load_recording(flushed_rrd)
    assert rec.damaged is None and rec.frames == list(range(N))
    assert_frames_exact(rec)


@pytest.mark.parametrize("fraction", [0.35, 0.7])
def test_truncated_recording_keeps_intact_frames(flushed_rrd, tmp_path, fraction):
    data = flushed_rrd.read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: int(len(data) * fraction)])
    rec = load_recording(cut)
    assert rec.damaged and "cut.rrd" in rec.damaged
    assert 0 < len(rec.frames) < N
    assert rec.frames == list(range(len(rec.frames)))  # a prefix: the tail is what was lost
    assert_frames_exact(rec)
    assert rec.recording_id == load_recording(flushed_rrd).recording_id


def test_corrupted_bytes_skip_only_the_damaged_part(flushed_rrd, tmp_path):
    data = bytearray(flushed_rrd.read_bytes())
    i = len(data) // 2
    data[i:i + 64] = b"\xff" * 64
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(bytes(data))
    rec = load_recording(bad)
    assert rec.damaged
    assert len(rec.frames) >= N // 2  # everything but the frames in the damaged message(s)
    assert_frames_exact(rec)


def test_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_recording(tmp_path / "missing.rrd")
    junk = tmp_path / "junk.rrd"
    junk.write_text("not a recording at all\n" * 10)
    with pytest.raises(InputError, match="not a readable Rerun recording"):
        load_recording(junk)


def test_inspect_cli_on_damaged_file(flushed_rrd, tmp_path, capsys):
    cut = tmp_path / "cut.rrd"
    data = flushed_rrd.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    assert main(["inspect", str(cut), "--json"]) == 1
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert summary["damaged"] and 0 < summary["frames"] < N
    assert "is damaged" in captured.err and "intact frames" in captured.err
    assert "Traceback" not in captured.err

    assert main(["inspect", str(tmp_path / "nope.rrd")]) == 2
    assert "nope.rrd" in capsys.readouterr().err


def test_export_mesh_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    verts = rng.random((10, 3)).astype(np.float32)
    faces = np.array([[0, 1, 2], [2, 3, 4], [5, 6, 9]])
    for name in ("m.obj", "m.ply"):
        mesh = meshio.read(export_mesh(tmp_path / name, verts, faces))
        np.testing.assert_array_equal(mesh.points.astype(np.float32), verts)
        np.testing.assert_array_equal(mesh.cells_dict["triangle"], faces)
    with pytest.raises(InputError):
        export_mesh(tmp_path / "m.stl", verts, faces)


def test_simulate_inspect_round_trip(tmp_path, capsys):
    """simulate -> .rrd -> inspect: same frame count and the same float32 positions."""
    scene = tmp_path / "small.toml"
    scene.write_text(HANGING_SHEET)
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", str(scene), "-o", str(rrd), "--control-net", "-q"]) == 0

    # The same run from Python, frames kept in memory.
    sc = loads_scene(HANGING_SHEET)
    sim = build_simulator(sc)
    kept = FrameBuffer()
    sim.run(sc.time.frames, sc.time.steps_per_frame, [kept])
    want = np.stack([f[2]["sheet"] for f in kept.frames()])  # float32

    capsys.readouterr()
    assert main(["inspect", str(rrd), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == sc.time.frames + 1 == len(want)
    assert summary["meshes"]["sheet"]["vertices"] == want.shape[1]
    assert summary["time_range"] == pytest.approx([0.0, sc.time.frames * sc.time.steps_per_frame * sc.time.dt])
    assert summary["stats"]["newton_iterations"]["count"] == sc.time.frames * sc.time.steps_per_frame
    assert "/control_net/sheet" in summary["entities"]

    rec = load_recording(rrd)
    np.testing.assert_array_equal(rec.positions("sheet"), want)

    # --frame K --export: the garment mesh at frame K, float32 exact.
    out = tmp_path / "f2.obj"
    assert main(["inspect", str(rrd), "--frame", "2", "--export", str(out), "-q"]) == 0
    mesh = meshio.read(out)
    np.testing.assert_array_equal(mesh.points.astype(np.float32), want[2])
    np.testing.assert_array_equal(mesh.cells_dict["triangle"], rec.faces("sheet"))
    last = tmp_path / "last.ply"
    assert main(["inspect", str(rrd), "--frame", "-1", "--export", str(last), "-q"]) == 0
    np.testing.assert_array_equal(meshio.read(last).points, want[-1])

    # Text summary, and a frame that does not exist.
    assert main(["inspect", str(rrd)]) == 0
    text = capsys.readouterr().out
    assert rec.recording_id in text and "newton_iterations" in text and "5 frames" in text
    assert main(["inspect", str(rrd), "--frame", "99", "--export", str(out)]) == 2
    assert "--frame 99" in capsys.readouterr().err
