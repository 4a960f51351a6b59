"""USD export (garment/io/usd.py) through `garment inspect RUN.rrd --export out.usd`: read
back with pxr, points of every frame against the recording, topology, stage metadata,
and no file (not even a temporary one) after an error or SIGTERM."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from garment.cli import main
from garment.io import usd
from sim.sinks import Frame, MeshTopology
from viz.recording import load_recording
from viz.rerun_sink import RerunSink

from tests.support.meshes import MESHES, grid_topology, positions

N = 10  # frames
BODY = MeshTopology("body.torso", grid_topology("b", 3, 3).faces, np.zeros((0, 2)), np.zeros((0, 2)), kind="body")
BODY_MOVES = (4, 7)  # the body holds still between these frames


def body_positions(k: int) -> np.ndarray:
    """(9, 3) m: a plate 0.2 m below the cloth that steps sideways at BODY_MOVES."""
    x = grid_topology("b", 3, 3).rest
    shift = 0.05 * sum(k >= m for m in BODY_MOVES)
    return np.column_stack([x[:, 0] + shift, x[:, 1], np.full(len(x), -0.2)])


@pytest.fixture(scope="module")
def rrd(tmp_path_factory):
    path = tmp_path_factory.mktemp("usd") / "run.rrd"
    sink = RerunSink(path)
    sink.open([*MESHES, BODY])
    for k in range(N):
        x = {m.name: positions(m, k) for m in MESHES} | {BODY.name: body_positions(k)}
        sink.write(Frame(k, k * 0.04, x))
    sink.close()
    return path


def test_usd_round_trip(rrd, tmp_path):
    out = tmp_path / "out" / "run.usd"
    assert main(["inspect", str(rrd), "--export", str(out), "-q"]) == 0
    rec = load_recording(rrd)
    stage = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert stage.GetTimeCodesPerSecond() == pytest.approx(25.0)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, N - 1)
    assert stage.GetDefaultPrim().GetPath() == "/World"

    paths = {"front": "/World/cloth/front", "back": "/World/cloth/back", "body.torso": "/World/bodies/body_torso"}
    worst = 0.0
    for name, prim_path in paths.items():
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(prim_path))
        assert mesh and mesh.GetPrim().GetDisplayName() == name
        counts = np.array(mesh.GetFaceVertexCountsAttr().Get())
        indices = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
        assert (counts == 3).all()
        np.testing.assert_array_equal(indices, rec.faces(name))
        for k in range(N):  # every frame, including the body's unsampled still ones
            got = np.array(mesh.GetPointsAttr().Get(Usd.TimeCode(k)))
            worst = max(worst, float(np.abs(got - rec.positions_at(name, k)).max()))
    assert worst <= 1e-6, worst
    # The body is sampled where it moves and just before: 0, 3, 4, 6, 7 (and nothing else).
    body = UsdGeom.Mesh(stage.GetPrimAtPath(paths["body.torso"]))
    assert body.GetPointsAttr().GetTimeSamples() == [0, 3, 4, 6, 7]
    assert len(UsdGeom.Mesh(stage.GetPrimAtPath(paths["front"])).GetPointsAttr().GetTimeSamples()) == N
    assert sorted(p.name for p in out.parent.iterdir()) == ["run.usd"]


def test_usd_options_and_bad_input(rrd, tmp_path, capsys):
    out = tmp_path / "front.usda"
    assert main(["inspect", str(rrd), "--export", str(out), "--mesh", "front", "--up", "y", "-q"]) == 0
    assert out.read_text().startswith("#usda")
    stage = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert [p.GetPath().pathString for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)] == ["/World/cloth/front"]

    capsys.readouterr()
    assert main(["inspect", str(rrd), "--export", str(tmp_path / "x.usd"), "--frame", "2"]) == 2
    assert "--frame" in capsys.readouterr().err
    assert main(["inspect", str(rrd), "--export", str(tmp_path / "x.usd"), "--mesh", "nope"]) == 2
    assert "nope" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [out]


@pytest.mark.parametrize("where", ["build", "rename"])
@pytest.mark.parametrize("failure", ["error", "sigterm"])
def test_no_file_after_an_error_or_sigterm(rrd, tmp_path, monkeypatch, capsys, failure, where):
    """A failure while the stage is built (after its first mesh) or once the temporary
    file is written (SIGTERM to this process: `garment.cli.main` exits 130) leaves
    neither the file nor its temporary."""
    real = {"build": usd._define_mesh, "rename": os.replace}[where]
    calls = []

    def fail_on_second(*args):
        calls.append(args)
        if where == "rename" or len(calls) == 2:
            assert where == "build" or os.path.getsize(args[0]) > 0  # the temporary is there
            if failure == "sigterm":
                os.kill(os.getpid(), signal.SIGTERM)  # delivered before the next bytecode
            else:
                raise OSError("disk full")
        return real(*args)

    if where == "build":
        monkeypatch.setattr(usd, "_define_mesh", fail_on_second)
    else:
        monkeypatch.setattr(usd.os, "replace", fail_on_second)
    out = tmp_path / "run.usd"
    handler = signal.getsignal(signal.SIGTERM)
    if failure == "sigterm":
        assert main(["inspect", str(rrd), "--export", str(out), "-q"]) == 130
        assert "interrupted" in capsys.readouterr().err
    else:
        with pytest.raises(OSError, match="disk full"):
            main(["inspect", str(rrd), "--export", str(out), "-q"])
    monkeypatch.undo()
    assert signal.getsignal(signal.SIGTERM) is handler  # restored
    assert calls and list(tmp_path.iterdir()) == []
