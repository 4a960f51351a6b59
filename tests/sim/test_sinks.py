"""Round trips through the output sinks: Rerun recording and per-frame mesh files."""

from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from garment.io import MeshExportSink, read_frame
from sim.sinks import Frame
from sim.stats import StepStats
from viz.recording import read_rrd_faces, read_rrd_positions
from viz.rerun_sink import RerunSink, vertex_normals

from tests.support.meshes import MESHES, positions

N_FRAMES = 5
DT = 1.0 / 30.0  # s between frames


def frames():
    for k in range(N_FRAMES):
        steps = [
            StepStats(step=2 * k + s, time=(k + 0.5 * s) * DT, newton_iterations=3 + s, residual=1e-6,
                      energy=0.1 * k, converged=True, t_assembly=1e-3, t_total=5e-3)
            for s in range(2)
        ]
        yield Frame(k, k * DT, {m.name: positions(m, k) for m in MESHES}, steps)


def test_rerun_round_trip(tmp_path):
    path = tmp_path / "out" / "run.rrd"  # parent does not exist yet
    sink = RerunSink(path, recording_name="test")
    sink.open(MESHES)
    for f in frames():
        sink.write(f)
    assert not path.exists()  # only the temporary file exists until close()
    sink.close()
    assert path.exists()
    assert [p.name for p in path.parent.iterdir()] == ["run.rrd"]

    got = read_rrd_positions(path)
    faces = read_rrd_faces(path)
    assert set(got) == set(faces) == {m.name for m in MESHES}
    for m in MESHES:
        assert got[m.name].dtype == np.float32
        assert got[m.name].shape == (N_FRAMES, len(m.uv), 3)
        want = np.stack([positions(m, k) for k in range(N_FRAMES)]).astype(np.float32)
        np.testing.assert_array_equal(got[m.name], want)
        np.testing.assert_array_equal(faces[m.name], m.faces)

    # Stats: one row per step, on the frame, step and sim_time timelines.
    # (The batcher may split rows over several chunks, so gather them all.)
    rows = {}
    for c in RrdReader(path).stream():
        if c.entity_path == "/stats/newton_iterations":
            b = c.to_record_batch()
            rows.update(zip(zip(b.column("frame").to_pylist(), b.column("step").to_pylist()),
                            b.column("Scalars:scalars").to_pylist()))
    assert rows == {(k, 2 * k + s): [3.0 + s] for k in range(N_FRAMES) for s in range(2)}


def test_vertex_normals_flat_grid():
    m = MESHES[0]
    flat = np.column_stack([m.rest, np.zeros(len(m.rest))])
    n = vertex_normals(flat, m.faces)
    np.testing.assert_allclose(n, np.tile([0.0, 0.0, 1.0], (len(flat), 1)), atol=1e-7)


@pytest.mark.parametrize("fmt", ["npz", "obj", "ply"])
def test_mesh_export_round_trip(tmp_path, fmt):
    sink = MeshExportSink(tmp_path / "frames", fmt)
    sink.open(MESHES)
    for f in frames():
        sink.write(f)
    sink.close()

    files = sorted(p.name for p in (tmp_path / "frames").iterdir())
    assert files == sorted(f"{m.name}_{k:05d}.{fmt}" for m in MESHES for k in range(N_FRAMES))
    for m in MESHES:
        for k in range(N_FRAMES):
            verts, faces = read_frame(sink.path(m.name, k))
            # npz/ply are binary float64; obj is text with 17 significant digits.
            np.testing.assert_allclose(verts, positions(m, k), rtol=0, atol=1e-15)
            np.testing.assert_array_equal(faces, m.faces)


def test_npz_contents(tmp_path):
    sink = MeshExportSink(tmp_path, "npz")
    sink.open(MESHES)
    f = next(frames())
    sink.write(f)
    with np.load(sink.path("front", 0)) as d:
        assert d["verts"].dtype == np.float64 and d["faces"].dtype == np.int32
        np.testing.assert_array_equal(d["uv"], MESHES[0].uv)
        assert float(d["time"]) == f.time and int(d["frame"]) == 0


def test_unknown_format(tmp_path):
    with pytest.raises(ValueError):
        MeshExportSink(tmp_path, "stl")
