"""Rerun sink layout: bodies, extra statistics, control nets, blueprint, live streaming."""

from __future__ import annotations

import socket

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

import garment.commands.simulate as simulate_cmd
from garment.cli import main
from sim.sinks import Frame, MeshTopology
from sim.stats import StepStats
from viz.recording import load_recording
from viz.rerun_sink import RerunSink, check_viewer_reachable, control_net_strips, step_scalars

from tests.support.meshes import grid_topology
from tests.support.scenes import HANGING_SHEET

CLOTH = grid_topology("sheet", 5, 4)
EMPTY = np.zeros((0, 2))
BALL = MeshTopology("ball", np.array([[0, 1, 2], [0, 2, 3]], np.int32), EMPTY, EMPTY, kind="body")
BALL_X = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)


def cloth_x(k: int) -> np.ndarray:
    return np.column_stack([CLOTH.rest, np.full(len(CLOTH.rest), -0.01 * k)])


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def entity_rows(path, entity: str) -> int:
    return sum(c.num_rows for c in RrdReader(path).stream() if c.entity_path == entity and not c.is_static)


def test_bodies_logged_once_while_static(tmp_path):
    path = tmp_path / "run.rrd"
    sink = RerunSink(path)
    sink.open([CLOTH, BALL])
    for k in range(4):
        ball = BALL_X + (0.0 if k < 3 else 0.5)  # still for 3 frames, then moves once
        sink.write(Frame(k, 0.1 * k, {"sheet": cloth_x(k), "ball": ball}, []))
    sink.close()

    assert entity_rows(path, "/bodies/ball") == 2  # frames 0 and 3
    rec = load_recording(path)
    assert rec.cloth_names == ["sheet"] and rec.body_names == ["ball"]
    assert rec.frames == [0, 1, 2, 3]
    # The reader carries the body forward over the frames it was not logged at.
    np.testing.assert_array_equal(rec.positions("ball")[2], BALL_X.astype(np.float32))
    np.testing.assert_array_equal(rec.positions("ball")[3], (BALL_X + 0.5).astype(np.float32))
    np.testing.assert_array_equal(rec.faces("ball"), BALL.faces)
    assert rec.entities["/bodies/ball"] == ["Mesh3D"]


def test_extra_statistics_become_time_series(tmp_path):
    steps = [
        StepStats(step=1, time=0.01, newton_iterations=3,
                  t_ccd=0.02, extra={"contact_count": 12.0, "min_distance": 1e-4, "flag": True}),
        StepStats(step=2, time=0.02, newton_iterations=4, t_ccd=0.03, extra={"contact_count": 15}),
    ]
    series = step_scalars(steps)
    assert "stats/flag" not in series  # a bool is not a time series
    rows, values = series["stats/min_distance"]
    assert rows.tolist() == [0] and values.tolist() == [1e-4]  # only the step that has it

    path = tmp_path / "run.rrd"
    sink = RerunSink(path)
    sink.open([CLOTH])
    sink.write(Frame(0, 0.0, {"sheet": cloth_x(0)}, []))
    sink.write(Frame(1, 0.02, {"sheet": cloth_x(1)}, steps))
    sink.close()

    rec = load_recording(path)
    contact = rec.scalars["/stats/contact_count"]
    assert contact.values.tolist() == [12.0, 15.0]
    assert contact.steps.tolist() == [1, 2] and contact.frames.tolist() == [1, 1]
    np.testing.assert_allclose(contact.times, [0.01, 0.02])
    assert rec.scalars["/stats/time/ccd"].values.tolist() == [0.02, 0.03]
    s = rec.summary()["stats"]
    assert s["newton_iterations"] == {"count": 2, "min": 3.0, "mean": 3.5, "max": 4.0}
    assert s["min_distance"]["count"] == 1
    # The default blueprint (3D view + plots) is in the file, in its own store.
    assert RrdReader(path).blueprints()


def test_control_nets_as_line_strips(tmp_path):
    C = np.random.default_rng(0).random((4, 3, 3))
    strips = control_net_strips(C)
    assert len(strips) == 4 + 3 and strips[0].shape == (3, 3) and strips[-1].shape == (4, 3)

    path = tmp_path / "run.rrd"
    sink = RerunSink(path, control_nets=lambda: {"sheet": C})
    sink.open([CLOTH])
    for k in range(2):
        sink.write(Frame(k, 0.1 * k, {"sheet": cloth_x(k)}, []))
    sink.close()
    comp = rr.LineStrips3D.descriptor_strips().component
    got = [c.to_record_batch().column(comp) for c in RrdReader(path).stream()
           if c.entity_path == "/control_net/sheet" and not c.is_static]
    assert sum(len(col) for col in got) == 2
    assert len(got[0][0]) == 7  # n + m strips per frame
    assert load_recording(path).cloth_names == ["sheet"]  # not mistaken for a mesh


def test_topology_static_positions_temporal(tmp_path):
    path = tmp_path / "run.rrd"
    sink = RerunSink(path)
    sink.open([CLOTH])
    for k in range(3):
        sink.write(Frame(k, 0.25 * k, {"sheet": cloth_x(k)}, []))
    sink.close()
    pos = rr.Mesh3D.descriptor_vertex_positions().component
    faces = rr.Mesh3D.descriptor_triangle_indices().component
    for c in RrdReader(path).stream():
        if c.entity_path != "/cloth/sheet":
            continue
        names = c.to_record_batch().schema.names
        if c.is_static:
            assert faces in names and pos not in names
        else:
            assert pos in names and faces not in names and {"frame", "sim_time"} <= set(c.timeline_names)
    rec = load_recording(path)
    assert [rec.time_of(k) for k in rec.frames] == [0.0, 0.25, 0.5]


def test_serve_and_connect(tmp_path):
    port = free_port()
    server = RerunSink(tmp_path / "served.rrd", serve=port)
    server.open([CLOTH])
    try:
        check_viewer_reachable(f"rerun+http://127.0.0.1:{port}/proxy")  # listening
        # A second run streams into the first one's server, as it would into a viewer.
        client = RerunSink(connect=f"rerun+http://127.0.0.1:{port}/proxy")
        client.open([CLOTH])
        client.write(Frame(0, 0.0, {"sheet": cloth_x(0)}, []))
        client.close()
        server.write(Frame(0, 0.0, {"sheet": cloth_x(0)}, []))
        server.close()  # flushes; the server keeps running until shutdown()
        assert not (tmp_path / "served.rrd").exists()
    finally:
        server.shutdown()
    assert load_recording(tmp_path / "served.rrd").frames == [0]
    with pytest.raises(ConnectionError):
        check_viewer_reachable(f"rerun+http://127.0.0.1:{port}/proxy")


def test_connect_without_viewer_fails_fast():
    with pytest.raises(ConnectionError, match="no Rerun viewer"):
        RerunSink(connect=f"rerun+http://127.0.0.1:{free_port()}/proxy").open([CLOTH])


def test_needs_a_destination():
    with pytest.raises(ValueError):
        RerunSink()


def test_simulate_serve_and_connect_cli(tmp_path, monkeypatch, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(HANGING_SHEET)
    port = free_port()
    seen = []

    def interrupt():  # instead of waiting for the user's Ctrl-C
        check_viewer_reachable(f"rerun+http://127.0.0.1:{port}/proxy")  # still serving after the run
        seen.append(True)
        raise KeyboardInterrupt

    monkeypatch.setattr(simulate_cmd, "wait_for_interrupt", interrupt)
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", str(scene), "-o", str(rrd), "--serve", str(port)]) == 0
    assert seen and load_recording(rrd).frames == list(range(5))
    assert f"127.0.0.1:{port}" in capsys.readouterr().err

    assert main(["simulate", str(scene), "--connect", f"rerun+http://127.0.0.1:{free_port()}/proxy", "-q"]) == 2
    assert "--connect" in capsys.readouterr().err
