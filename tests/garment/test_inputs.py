"""Issue 35: no input crashes, hangs or exhausts the machine. Each case a new user tried,
through the command line as they would: numbers, units and paths are checked before any
work, a request that will not fit in memory is refused up front with the setting to
change, nothing is left half-written, and every message is terminal-safe."""

from __future__ import annotations

import io
import json
import math
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

from garment.cli import main
from sim.budget import memory_limit, parse_bytes, simulation_bytes
from sim.errors import InputError, printable
from sim.files import atomic_write, read_npz, remove_partial_files, track_partial

from tests.garment.test_gauntlet import SCENE, check_clean_failure
from tests.support.panels import grid, write_obj
from tests.support.paths import ASSETS, ROOT, SHARED_ASSETS



def scene_file(tmp_path: Path, text: str = SCENE) -> Path:
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return path


def panel_obj(path: Path, bad: str | None = None) -> Path:
    """A 0.2 x 0.15 m panel OBJ (v placed in 3D, vt the layout) with one coordinate bad."""
    V, F = grid(5, 4, (0.2, 0.15))
    write_obj(path, [("front", V, F)])
    if bad is not None:
        lines = path.read_text().splitlines()
        k = {"v": 10, "vt": 11}[bad.split()[0]]  # vertex 5's v and vt lines
        lines[k] = bad
        path.write_text("\n".join(lines) + "\n")
    return path


def run_cli(*args: str, env: dict | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    """`garment ARGS` in a fresh process, as a user runs it."""
    env = {**os.environ, "NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR", str(ROOT / ".cache" / "numba")),
           **(env or {})}
    return subprocess.run([sys.executable, "-m", "garment.cli", *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout)


# ----------------------------------------------------------- NaN and inf in the input


@pytest.mark.parametrize("bad", ["v nan 0.05 0.025", "v 0.05 inf 0.025", "vt 0.05 nan", "v nan nan nan"])
def test_non_finite_panel_coordinates_are_bad_input(tmp_path, capsys, bad):
    """One NaN or inf in a panel OBJ died in an SVD with a traceback, or (NaN only in the
    3D `v` of a panel laid out by `vt`) was reported "ok" with every control point NaN."""
    path = panel_obj(tmp_path / "panel.obj", bad)
    out = tmp_path / "out"
    code = main(["conform", str(path), "-o", str(out), "-q"])
    check_clean_failure(code, capsys.readouterr().err, ["panel.obj:", "non-finite number"], [out])
    assert code == 2


def test_a_garment_with_nan_control_points_is_bad_input_not_a_time_step(tmp_path, capsys):
    """A patch file with NaN (written as null) control points used to simulate, retry with
    smaller steps and blame the time step (exit 3); it is bad input naming the file."""
    path = panel_obj(tmp_path / "panel.obj")
    assert main(["conform", str(path), "-o", str(tmp_path / "c"), "-q", "--knot-span", "50"]) == 0
    patches = tmp_path / "c" / "patches.json"
    doc = json.loads(patches.read_text())
    doc["patches"][0]["world"][1][1] = [None, None, None]
    patches.write_text(json.dumps(doc))
    scene = scene_file(tmp_path, f'[[garment]]\nname = "g"\nsource = "{patches}"\n[time]\nframes = 2\n')
    code = main(["simulate", str(scene), "-o", str(tmp_path / "run.rrd"), "-q"])
    check_clean_failure(code, capsys.readouterr().err, ["patches.json", "patches[0]", "world", "non-finite"],
                        [tmp_path / "run.rrd", tmp_path / "run.ckpt.npz"])
    assert code == 2
    # A panel OBJ conformed on the fly: the reader names the file and line.
    scene.write_text(f'[[garment]]\nname = "g"\nsource = "{panel_obj(tmp_path / "nan.obj", "v nan 0.05 0")}"\n')
    code = main(["simulate", str(scene), "-q"])
    check_clean_failure(code, capsys.readouterr().err, ["nan.obj:11", "non-finite"], [])
    assert code == 2


# ----------------------------------------------------------- hangs


def test_a_ply_cut_short_in_its_header_is_refused_at_once(tmp_path, capsys):
    """meshio's PLY header loop spins forever at the end of a file: it hung conform for
    minutes."""
    V, F = grid(5, 4, (0.2, 0.15))
    trimesh.Trimesh(np.column_stack([V, np.zeros(len(V))]), F, process=False).export(tmp_path / "whole.ply")
    raw = (tmp_path / "whole.ply").read_bytes()
    out = tmp_path / "out"
    for cut in (10, 60, raw.index(b"end_header") - 1):
        (tmp_path / "cut.ply").write_bytes(raw[:cut])
        start = time.perf_counter()
        code = main(["conform", str(tmp_path / "cut.ply"), "-o", str(out), "-q"])
        assert time.perf_counter() - start < 10
        check_clean_failure(code, capsys.readouterr().err, ["cut.ply", "header is cut short"], [out])


def test_another_librarys_reader_that_never_returns_is_stopped(tmp_path, monkeypatch):
    """Whatever else loops forever in a foreign reader stops at the time limit."""
    import garment.io.meshfile as meshfile

    def forever(path):
        while True:
            pass

    monkeypatch.setattr(meshfile, "_load", forever)
    monkeypatch.setattr(meshfile, "READ_SECONDS", 0.5)
    (tmp_path / "mesh.off").write_text("OFF\n")
    start = time.perf_counter()
    with pytest.raises(InputError, match=r"mesh.off: cannot read a triangle mesh: reading took more than \d s \(a damaged or truncated"):
        meshfile.read_mesh(tmp_path / "mesh.off")
    assert time.perf_counter() - start < 5


def test_a_reader_that_exits_or_prints_is_contained(tmp_path, monkeypatch, capsys):
    """meshio prints its errors and calls sys.exit(1) on a file it cannot read."""
    (tmp_path / "mesh.vtu").write_bytes(b"\x00\x01garbage\x1b[2J")
    with pytest.raises(InputError, match="mesh.vtu: cannot read a triangle mesh"):
        from garment.io.meshfile import read_mesh

        read_mesh(tmp_path / "mesh.vtu")
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""


# ----------------------------------------------------------- memory


def test_a_simulation_that_will_not_fit_is_refused_up_front(tmp_path):
    """control_points = [20000, 20000] was killed for memory; it is refused in seconds,
    with the estimate, the machine's memory and the setting to change."""
    scene = scene_file(tmp_path, SCENE.replace("[6, 6]", "[20000, 20000]"))
    start = time.perf_counter()
    r = run_cli("simulate", str(scene), "-o", str(tmp_path / "run.rrd"), "-q", timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert time.perf_counter() - start < 60
    assert "scene.toml: simulating 400000000 control points (1200000000 DOFs) needs about" in r.stderr
    assert "TiB of memory, more than the machine's memory" in r.stderr
    assert "reduce control_points of cloth 'sheet' (now 20000 x 20000)" in r.stderr
    assert not (tmp_path / "run.rrd").exists() and not (tmp_path / "run.ckpt.npz").exists()


def test_the_memory_limit_comes_from_the_machine_or_the_override(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("GARMENT_MEMORY_LIMIT", raising=False)
    limit, source = memory_limit()
    total = next(int(line.split()[1]) * 1024 for line in open("/proc/meminfo") if line.startswith("MemTotal"))
    assert limit <= total and source in ("the machine's memory", "the cgroup's memory limit",
                                         "the address-space limit (ulimit -v)")
    assert parse_bytes("2G") == 2 * 2**30 and parse_bytes("512M") == 512 * 2**20 and parse_bytes("1.5e9") == 1.5e9
    with pytest.raises(ValueError):
        parse_bytes("lots")
    # A 100^2 sheet: the estimate is what `garment simulate` measured (0.57 GB peak).
    assert 0.5e9 < simulation_bytes(100**2) < 0.9e9
    assert 3.2e9 < simulation_bytes(300**2) < 4.0e9  # measured 3.4 GB
    monkeypatch.setenv("GARMENT_MEMORY_LIMIT", "300M")
    scene = scene_file(tmp_path, SCENE.replace("[6, 6]", "[100, 100]"))
    code = main(["simulate", str(scene), "-q"])
    check_clean_failure(code, capsys.readouterr().err, [
        "simulating 10000 control points (30000 DOFs) needs about 660.3 MiB", "GARMENT_MEMORY_LIMIT (300.0 MiB)",
        "reduce control_points of cloth 'sheet' (now 100 x 100)"], [])


def test_a_render_whose_frames_will_not_fit_is_refused_before_the_run(tmp_path, capsys, monkeypatch):
    """--render keeps every frame in memory (12 bytes per vertex and frame)."""
    monkeypatch.setenv("GARMENT_MEMORY_LIMIT", "450M")
    video = tmp_path / "v.mp4"
    code = main(["simulate", str(scene_file(tmp_path)), "--frames", "100000", "--render", str(video), "-q"])
    check_clean_failure(code, capsys.readouterr().err, [
        "--render: keeping 100001 frames of", "vertices for the video needs about", "render fewer frames"], [video])


def test_metres_typed_for_millimetres_are_refused_with_the_fix(tmp_path, capsys):
    """`--knot-span 0.02` grew to 24 GB and ignored Ctrl-C."""
    shirt = ASSETS / "garments" / "shirt_mean.json"
    out = tmp_path / "out"
    code = main(["conform", str(shirt), "-o", str(out), "--knot-span", "0.02"])
    check_clean_failure(code, capsys.readouterr().err, [
        "--knot-span: 0.02 mm is below 0.5 mm, not a plausible value; looks like metres: write 20"], [out])
    scene = scene_file(tmp_path, f'[[garment]]\nsource = "{shirt}"\nknot_span_mm = 0.04\n')
    code = main(["simulate", str(scene), "-q"])
    check_clean_failure(code, capsys.readouterr().err, [
        "garment[0].knot_span_mm: 0.04 mm is below 0.5 mm", "looks like metres: write 40"], [])


def test_conforming_more_than_the_machine_holds_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("GARMENT_MEMORY_LIMIT", "1G")
    out = tmp_path / "out"
    start = time.perf_counter()
    code = main(["conform", str(ASSETS / "garments" / "shirt_mean.json"), "-o", str(out), "--knot-span", "1"])
    assert time.perf_counter() - start < 30
    check_clean_failure(code, capsys.readouterr().err, [
        "shirt_mean.json: conforming panel", "control points) needs about", "GARMENT_MEMORY_LIMIT (1.0 GiB)",
        "raise the knot span (now 1 mm)"], [out])


def half_disc(radius_cm: float = 10.0) -> dict:
    """A GarmentCode half disc: a straight edge and a circle edge, in cm."""
    return {"pattern": {"panels": {"disc": {
        "translation": [0, 0, 0], "rotation": [0, 0, 0], "vertices": [[0, 0], [2 * radius_cm, 0]],
        "edges": [{"endpoints": [0, 1]}, {"endpoints": [1, 0], "curvature": {
            "type": "circle", "params": [radius_cm, 0, 0]}}]}}, "stitches": []},
        "properties": {"units_in_meter": 100}}


def test_garmentcode_circle_radii_are_in_pattern_units(tmp_path):
    """A circle skirt's radius was read as metres (78 cm -> 78 m): 99883 outline points
    and a 149 GiB array in conform. The half disc of radius 10 cm has its exact area and
    outline length."""
    from garment.io.garmentcode import read_garmentcode

    path = tmp_path / "disc.json"
    path.write_text(json.dumps(half_disc()))
    (panel,), _ = read_garmentcode(path, spacing=0.003)
    assert panel.area == pytest.approx(math.pi * 0.1**2 / 2, rel=1e-4)
    length = np.linalg.norm(np.diff(np.vstack([panel.rest, panel.rest[:1]]), axis=0), axis=1).sum()
    assert length == pytest.approx(0.2 + math.pi * 0.1, rel=1e-3)
    assert len(panel.rest) < 200


def test_garmentcode_units_must_be_a_positive_number(tmp_path):
    """units_in_meter = 0 divided by zero (a traceback, found by the fuzzer: case 209)."""
    from garment.io.garmentcode import read_garmentcode

    path = tmp_path / "disc.json"
    for bad in (0, -100, "inf", "cm"):
        spec = half_disc()
        spec["properties"]["units_in_meter"] = bad
        path.write_text(json.dumps(spec))
        with pytest.raises(InputError, match=r"disc.json.*(units_in_meter must be a positive number|not a GarmentCode)"):
            read_garmentcode(path)


def test_the_outline_diameter_of_a_finely_sampled_circle_is_cheap():
    """All hull pairs of 100000 points took 149 GiB; rotating calipers take linear time."""
    from conform.boundary import diameter

    t = np.linspace(0, 2 * np.pi, 100_000, endpoint=False)
    start = time.perf_counter()
    assert diameter(np.column_stack([np.cos(t), 2 * np.sin(t)])) == pytest.approx(4.0)
    assert time.perf_counter() - start < 10
    rng = np.random.default_rng(1)
    P = rng.random((3000, 2)) * [3.0, 0.5]
    d = P[:, None] - P[None]
    assert diameter(P) == pytest.approx(np.sqrt((d**2).sum(-1).max()), rel=1e-12)


@pytest.mark.slow
@pytest.mark.skipif(not (SHARED_ASSETS / "garmentcode_corpus").is_dir(), reason="needs ../shared/assets")
@pytest.mark.parametrize("name", ["dress_04", "dress_06", "skirt_02"])
def test_the_sampled_circle_skirts_conform(tmp_path, name):
    """The corpus patterns with circle edges: a MemoryError traceback (149-400 GiB) before."""
    r = run_cli("conform", str(SHARED_ASSETS / "garmentcode_corpus" / f"{name}_specification.json"),
                "-o", str(tmp_path / "out"), "--json", "-q", env={"GARMENT_MEMORY_LIMIT": "4G"}, timeout=600)
    assert r.returncode in (0, 1) and "Traceback" not in r.stderr, r.stderr
    assert json.loads(r.stdout)["panels"]


# ----------------------------------------------------------- output paths


def test_outputs_that_cannot_be_written_are_refused_before_the_run(tmp_path, capsys):
    scene = scene_file(tmp_path)
    folder = tmp_path / "taken"
    folder.mkdir()
    cases = [
        (["-o", str(folder)], ["taken: is a folder; the recording (-o, [output] rrd) is a file", "taken/run.rrd"]),
        (["-o", "/proc/x/y.rrd"], ["/proc/x/y.rrd: cannot write in /proc"]),
        (["-o", str(tmp_path / "run.mp4")], ["run.mp4: the recording (-o, [output] rrd) must end in .rrd, got '.mp4'"]),
        (["-o", str(tmp_path / "run.rrd"), "--mesh-dir", str(scene)], ["scene.toml: is a file, but the per-frame"]),
        (["-o", str(tmp_path / "run.rrd"), "--checkpoint", str(folder)], ["taken: is a folder; the checkpoint"]),
        (["--render", str(tmp_path / "x.avi")], ["x.avi: render output must be .mp4, .gif or a folder"]),
        (["-o", str(scene / "run.rrd")], ["scene.toml is a file, not a folder"]),
    ]
    for args, fragments in cases:
        code = main(["simulate", str(scene), "-q", *args])
        check_clean_failure(code, capsys.readouterr().err, fragments, [tmp_path / "run.rrd"])
        assert code == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml", "taken"]  # no .tmp, no checkpoint
    assert not list(folder.iterdir())


def test_inspect_and_conform_outputs_are_checked_first(tmp_path, capsys):
    scene = scene_file(tmp_path)
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", str(scene), "-o", str(rrd), "-q"]) == 0
    for args, fragment in ((["--export", str(tmp_path)], "is a folder; the exported mesh (--export) is a file"),
                           (["--export", str(tmp_path / "m.stl")], "must end in .obj or .ply or .usd or .usda or .usdc, got '.stl'"),
                           (["--render", str(tmp_path / "r.webm")], "render output must be .mp4, .gif")):
        check_clean_failure(main(["inspect", str(rrd), *args]), capsys.readouterr().err, [fragment], [])
    panel = panel_obj(tmp_path / "panel.obj")
    check_clean_failure(main(["conform", str(panel), "-o", str(scene), "-q"]), capsys.readouterr().err,
                        ["scene.toml: is a file, but the output directory (-o) must be a folder"], [])
    check_clean_failure(main(["conform", str(panel), "-o", str(tmp_path / "c"), "--preview", str(tmp_path / "p.jpg")]),
                        capsys.readouterr().err, ["p.jpg: the preview (--preview) must end in .png"],
                        [tmp_path / "c"])


@pytest.mark.parametrize("frames", ["0", "-2"])
def test_frames_below_one_are_rejected_like_the_scene_file_does(tmp_path, capsys, frames):
    scene = scene_file(tmp_path)
    code = main(["simulate", str(scene), "-o", str(tmp_path / "run.rrd"), "-q", "--frames", frames])
    check_clean_failure(code, capsys.readouterr().err, [f"--frames: must be >= 1, got {frames}"],
                        [tmp_path / "run.rrd"])
    scene.write_text(SCENE.replace("frames = 2", f"frames = {frames}"))
    code = main(["simulate", str(scene), "-q"])
    check_clean_failure(code, capsys.readouterr().err, [f"time.frames: must be >= 1, got {frames}"], [])


def test_a_run_without_outputs_says_so(tmp_path, capsys):
    assert main(["simulate", str(scene_file(tmp_path)), "--frames", "1"]) == 0
    err = " ".join(capsys.readouterr().err.split())  # rich wraps lines
    assert "warning: this run writes no output (no -o, --mesh-dir or --render, and no [output]" in err
    assert main(["simulate", str(scene_file(tmp_path)), "--frames", "1", "-q"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("option, value, fragment", [
    ("--fps", "inf", "--fps: must be a finite number, got inf"),
    ("--fps", "0", "--fps: must be in (0, 1000], got 0"),
    ("--checkpoint-every", "-1", "--checkpoint-every: must be >= 0, got -1"),
    ("--max-splits", "40", "--max-splits: must be in [0, 30], got 40"),
    ("--serve", "70000", "--serve: must be in [0, 65535], got 70000"),
])
def test_command_line_numbers_are_checked(tmp_path, capsys, option, value, fragment):
    args = ["--render", str(tmp_path / "v.mp4")] if option == "--fps" else []
    code = main(["simulate", str(scene_file(tmp_path)), "-q", option, value, *args])
    check_clean_failure(code, capsys.readouterr().err, [fragment], [tmp_path / "v.mp4"])


# ----------------------------------------------------------- units


def test_a_cloth_in_centimetres_is_refused_with_the_fix(tmp_path, capsys):
    scene = scene_file(tmp_path, SCENE.replace("[0.3, 0.3]", "[60, 60]"))
    check_clean_failure(main(["simulate", str(scene), "-q"]), capsys.readouterr().err, [
        "scene.toml: cloth[0].size[0]: 60 m is above 20 m, not a plausible value; looks like centimetres: "
        "write 0.6"], [])


def test_a_static_obstacle_in_centimetres_is_refused_with_the_fix(tmp_path, capsys):
    """An animated body in cm was caught; a static one was not."""
    trimesh.creation.icosphere(subdivisions=2, radius=80.0).export(tmp_path / "body.obj")  # 1.6 m, in cm
    scene = scene_file(tmp_path, SCENE + '\n[[obstacle]]\nname = "body"\nmesh = "body.obj"\n')
    check_clean_failure(main(["simulate", str(scene), "-q"]), capsys.readouterr().err, [
        "body.obj: the obstacle is 160 m across after scaling; the file is probably not in metres (looks like "
        "centimetres: set scale = 0.01)"], [])
    # With scale = 0.1 the fix is relative to it: 0.001.
    scene.write_text(SCENE + '\n[[obstacle]]\nname = "body"\nmesh = "body.obj"\nscale = 0.1\n')
    check_clean_failure(main(["simulate", str(scene), "-q"]), capsys.readouterr().err, [
        "16 m across after scaling", "set scale = 0.001"], [])


def test_a_panel_file_in_centimetres_is_refused_with_the_fix(tmp_path, capsys):
    """Found by the fuzzer: one `vt` 0.45 -> 45 made a 45 m panel that conformed for
    minutes (no hang, but no answer either)."""
    V, F = grid(5, 4, (20.0, 15.0))  # cm
    path = write_obj(tmp_path / "panel.obj", [("front", V, F)])
    out = tmp_path / "out"
    start = time.perf_counter()
    code = main(["conform", str(path), "-o", str(out), "-q"])
    assert time.perf_counter() - start < 10
    check_clean_failure(code, capsys.readouterr().err, [
        "panel.obj: panel front: the layout is 20 m across; panel files are in metres (looks like centimetres: "
        "convert it to metres (x 0.01))"], [out])


# ----------------------------------------------------------- folders and garbage


def test_a_folder_where_a_file_is_expected_is_named_as_a_folder(tmp_path, capsys):
    """A folder given for a file got "no such file", though it exists."""
    d = tmp_path / "thing.obj"
    d.mkdir()
    rrd = tmp_path / "run.rrd"
    rrd.mkdir()
    for args, fragment in (
        (["conform", str(d), "-o", str(tmp_path / "o")], "thing.obj: is a folder, not a file"),
        (["inspect", str(rrd)], "run.rrd: is a folder, not a Rerun recording (.rrd)"),
        (["simulate", str(tmp_path)], "<file>: is a folder, not a scene file"),
    ):
        check_clean_failure(main(args), capsys.readouterr().err, [fragment], [tmp_path / "o"])
    for key in ('[[obstacle]]\nname = "body"\nmesh = "thing.obj"', '[[garment]]\nsource = "thing.obj"'):
        scene = scene_file(tmp_path, SCENE + "\n" + key + "\n")
        check_clean_failure(main(["simulate", str(scene), "-q"]), capsys.readouterr().err,
                            ["thing.obj is a folder, not a file"], [])


GARBAGE = b"v 0.1 0.2 \x1b[31mRED\x07\x00\xff\xfe" + b"x" * 5000 + b"\n"


def test_binary_garbage_is_never_echoed_raw(tmp_path, capsys):
    """Escape sequences, NUL and invalid UTF-8 from a file are escaped; long lines cut."""
    path = tmp_path / "junk.obj"
    path.write_bytes(b"v 0 0 0\n" + GARBAGE)
    code = main(["conform", str(path), "-o", str(tmp_path / "o"), "-q"])
    err = capsys.readouterr().err
    check_clean_failure(code, err, ["junk.obj:2: cannot read", "\\x1b[31mRED\\x07\\x00", "..."], [])
    assert all(c.isprintable() or c == "\n" for c in err) and len(err) < 300
    (tmp_path / "b.obj").write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" + GARBAGE)
    scene = scene_file(tmp_path, SCENE + '\n[[obstacle]]\nname = "b"\nmesh = "b.obj"\n')
    code = main(["simulate", str(scene), "-q"])
    err = capsys.readouterr().err
    assert code == 2 and all(c.isprintable() or c == "\n" for c in err) and "Traceback" not in err
    (tmp_path / "g.json").write_bytes(GARBAGE)  # a garment source: patch file or pattern?
    code = main(["simulate", str(scene_file(tmp_path, '[[garment]]\nsource = "g.json"\n')), "-q"])
    check_clean_failure(code, capsys.readouterr().err, ["g.json: not a GarmentCode pattern"], [])
    assert printable("a\x1b[2Jb\x00") == "a\\x1b[2Jb\\x00" and printable("x" * 50, 10).endswith("(40 more characters)")


def test_rerun_log_lines_do_not_leak_before_inspects_error(tmp_path):
    """Rust ERROR lines with colour codes came before `inspect`'s own one-line error."""
    junk = tmp_path / "junk.rrd"
    junk.write_bytes(np.random.default_rng(0).bytes(5000))
    r = run_cli("inspect", str(junk))
    assert r.returncode == 2
    assert r.stderr.startswith("error: ") and r.stderr.count("\n") == 1 and "\x1b" not in r.stderr
    assert "junk.rrd: not a readable Rerun recording" in r.stderr


# ----------------------------------------------------------- nothing half-written


def test_inspect_render_killed_by_sigterm_leaves_no_temporary_video(tmp_path):
    """`inspect --render` killed by SIGTERM left `.clip.<pid>.tmp.mp4` (the cleanup ran on
    exceptions only); SIGTERM now stops it like Ctrl-C: status 130, nothing left."""
    scene = scene_file(tmp_path, SCENE.replace("frames = 2", "frames = 200"))
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", str(scene), "-o", str(rrd), "-q"]) == 0
    out = tmp_path / "video"
    out.mkdir()
    env = {**os.environ, "NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR", str(ROOT / ".cache" / "numba"))}
    proc = subprocess.Popen([sys.executable, "-m", "garment.cli", "inspect", str(rrd), "--render",
                             str(out / "clip.mp4"), "--render-size", "1280x960", "-q"], cwd=ROOT, env=env,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not list(out.glob(".clip.*.tmp.mp4")):
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read() if proc.poll() else ""
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in err and "interrupted" in err
    assert list(out.iterdir()) == []


def test_atomic_writes_leave_nothing_on_failure_or_interrupt(tmp_path):
    target = tmp_path / "out.json"
    for error in (ValueError("disk full"), KeyboardInterrupt()):
        with pytest.raises(type(error)):
            with atomic_write(target) as tmp:
                tmp.write_text("half")
                raise error
        assert list(tmp_path.iterdir()) == []
    with atomic_write(target) as tmp:
        tmp.write_text("whole")
    assert target.read_text() == "whole" and list(tmp_path.iterdir()) == [target]


def test_a_hard_exit_removes_partial_files_and_keeps_the_recording(tmp_path):
    """The second signal exits at once: files being written are removed, the recording's
    stream (valid when cut short) is moved to its name."""
    stream, partial = tmp_path / ".run.rrd.1.tmp", tmp_path / ".f.npz.1.tmp"
    stream.write_bytes(b"frames")
    partial.write_bytes(b"half")
    track_partial(stream, tmp_path / "run.rrd")
    track_partial(partial)
    remove_partial_files()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.rrd"]
    assert (tmp_path / "run.rrd").read_bytes() == b"frames"


@pytest.mark.slow
def test_second_signal_leaves_a_readable_recording_and_no_temporary_files(tmp_path):
    from tests.garment.test_robustness import start_run
    from viz.recording import load_recording

    proc, _, rrd, frames = start_run(tmp_path)
    proc.send_signal(signal.SIGTERM)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and "Traceback" not in err
    assert not list(tmp_path.glob("**/.*tmp*")) and load_recording(rrd).frames


# ----------------------------------------------------------- NPZ archives


def test_npz_arrays_are_checked_before_they_are_read(tmp_path):
    np.savez(tmp_path / "objects.npz", verts=np.array([{"a": 1}], dtype=object))
    with pytest.raises(InputError, match="array 'verts' holds Python objects"):
        read_npz(tmp_path / "objects.npz")
    # A header claiming 4e9 x 3 doubles (89 GiB) over 96 stored bytes: refused unread.
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (4_000_000_000, 3)})
    with zipfile.ZipFile(tmp_path / "claims.npz", "w") as z:
        z.writestr("verts.npy", header.getvalue() + bytes(96))
    with pytest.raises(InputError, match=r"array 'verts' claims shape \(4000000000, 3\) \(89.4 GiB\) but the "
                                         r"archive stores 224 bytes of it"):
        read_npz(tmp_path / "claims.npz")
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(InputError, match="text.npz: not an NPZ archive"):
        read_npz(tmp_path / "text.npz")
