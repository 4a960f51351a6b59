"""Every reader fuzzed: hypothesis mutates valid files (truncates, flips and inserts
bytes, writes NaN, inf, huge and negative numbers into them, breaks indices, swaps JSON
and NPZ values for other types and shapes) and each mutated file is read in a forked
child (tests/garment/fuzz_worker.py). Every run must end with a clean exit status (0, 1
for a partial conform or a damaged recording, 2 for bad input), no traceback, within
30 s, below 2 GB of resident memory, and print only terminal-safe text.

The fast set reads FAST_EXAMPLES inputs per reader; the slow set SLOW_EXAMPLES (8,000 in
all) and prints the totals: inputs, tracebacks, hangs, peak memory, slowest run. Rigged
bodies (BVH, MakeHuman rig and weights, SMPL model .npz/.pkl and motion) are read from a
folder of their files with one of them mutated."""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.garment.bodies.synthetic import bend_motion, column_model, write_column_bvh, write_column_rig
from tests.support.panels import grid, write_obj
from tests.support.paths import ROOT

FAST_EXAMPLES = 25
SLOW_EXAMPLES = 400
ALLOWED_CODES = {0, 1, 2}
MAX_RSS_MB = 2048
MAX_SECONDS = 30.0

SCENE = """
[scene]
name = "fuzz"

[material]
preset = "cotton"

[[cloth]]
name = "sheet"
size = [0.3, 0.2]
control_points = [6, 5]
origin = [-0.15, -0.1, 0.2]
perturbation = { amplitude = 0.001, waves = [1, 1] }

[[pin]]
cloth = "sheet"
corners = ["u0v0", "u1v0"]
velocity = [0.0, 0.0, 0.1]
duration = 0.5

[[obstacle]]
name = "ball"
sphere = { center = [0.0, 0.0, 0.0], radius = 0.05, subdivisions = 2 }

[contact]
dhat = 1e-3
kappa = "adaptive"
mu = 0.2

[time]
dt = 0.01
frames = 2
steps_per_frame = 1

[output]
mesh_format = "obj"
"""


# ----------------------------------------------------------------------- seed files


def _garmentcode() -> dict:
    square = {"translation": [0, 0, 10], "rotation": [0, 10, 0],
              "vertices": [[0, 0], [20, 0], [20, 20], [0, 20]],
              "edges": [{"endpoints": [0, 1], "curvature": {"type": "quadratic", "params": [[0.5, 0.1]]}},
                        {"endpoints": [1, 2], "curvature": {"type": "circle", "params": [15, 0, 1]}},
                        {"endpoints": [2, 3], "curvature": {"type": "cubic", "params": [[0.3, 0.1], [0.7, -0.1]]}},
                        {"endpoints": [3, 0]}]}
    back = json.loads(json.dumps(square))
    back["translation"] = [0, 0, -10]
    return {"pattern": {"panels": {"front": square, "back": back}, "panel_order": ["front", "back"],
                        "stitches": [[{"panel": "front", "edge": 3}, {"panel": "back", "edge": 1}]]},
            "properties": {"units_in_meter": 100, "curvature_coords": "relative"}}


@pytest.fixture(scope="module")
def seeds(tmp_path_factory) -> dict[str, Path]:
    return make_seeds(tmp_path_factory.mktemp("seeds"))


def make_seeds(d: Path) -> dict[str, Path]:
    """One valid file (or folder) per reader, in folder d."""
    from garment.cli import main

    V, F = grid(5, 4, (0.2, 0.15))
    V2, F2 = grid(4, 4, (0.15, 0.15), (0.3, 0.0))
    obj = write_obj(d / "panels.obj", [("front", V, F), ("back", V2, F2)],
                    seams=[[(3, 20, 21, 0.5), (7, 24, 25, 0.0)]])
    flat = trimesh.Trimesh(np.column_stack([V, np.zeros(len(V))]), F, process=False)
    flat.export(d / "panel.ply")
    flat.export(d / "panel_ascii.ply", encoding="ascii")
    (d / "pattern.json").write_text(json.dumps(_garmentcode()))
    assert main(["conform", str(obj), "-o", str(d / "conformed"), "-q", "--knot-span", "60"]) == 0
    scene = d / "scene.toml"
    scene.write_text(SCENE)
    ball = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
    ball.export(d / "ball.obj")
    verts = np.stack([ball.vertices, ball.vertices + [0, 0, 0.01]]).astype(np.float32)
    np.savez(d / "body.npz", verts=verts, faces=np.asarray(ball.faces, np.int32), frame_dt=0.04)
    (d / "frames").mkdir()
    for k in range(2):
        trimesh.Trimesh(verts[k], ball.faces, process=False).export(d / "frames" / f"f{k}.obj")
    assert main(["simulate", str(scene), "-o", str(d / "run.rrd"), "-q"]) == 0
    rigged = _rigged_seeds(d)
    return {**rigged, "panel_obj": obj, "panel_ply": d / "panel.ply", "panel_ascii_ply": d / "panel_ascii.ply",
            "garmentcode": d / "pattern.json", "patches": d / "conformed" / "patches.json", "scene": scene,
            "body_npz": d / "body.npz", "body_dir": d / "frames", "obstacle": d / "ball.obj", "rrd": d / "run.rrd",
            "checkpoint": d / "run.ckpt.npz"}


def _rigged_seeds(d: Path) -> dict[str, Path]:
    """Folders holding a rigged body's files (tests/garment/bodies/synthetic.py), the one
    to mutate named to sort last (fuzz_one mutates a folder's last file)."""
    import pickle

    seeds = {}
    names = {"mesh": "body.obj", "rig": "rig.json", "weights": "weights.json", "motion": "motion.bvh"}
    for target in names:
        folder = d / f"skin_{target}"
        files = write_column_rig(folder)
        write_column_bvh(folder / "motion.bvh")
        files["motion"] = folder / "motion.bvh"
        files[target].rename(folder / f"z_{names[target]}")
        seeds[f"skin_{target}"] = folder
    model, motion = column_model(), bend_motion(frames=11)
    for target, (first, last) in {"model": (("motion.npz", motion), ("z_model.npz", model)),
                                  "motion": (("model.npz", model), ("z_motion.npz", motion))}.items():
        folder = d / f"smpl_{target}"
        folder.mkdir()
        for name, arrays in (first, last):
            np.savez(folder / name, **arrays)
        seeds[f"smpl_{target}"] = folder
    folder = d / "smpl_pkl"
    folder.mkdir()
    np.savez(folder / "motion.npz", **motion)
    (folder / "z_model.pkl").write_bytes(pickle.dumps(model, protocol=2))
    seeds["smpl_pkl"] = folder
    return seeds


# (seed, reader the worker runs, mutations that apply besides the byte-level ones)
TARGETS = {
    "panel_obj": ("panel_obj", "panel_obj", ("text",)),
    "panel_ply": ("panel_ply", "panel_ply", ()),
    "panel_ascii_ply": ("panel_ascii_ply", "panel_ply", ("text",)),
    "garmentcode": ("garmentcode", "garmentcode", ("text", "json")),
    "patches": ("patches", "patches", ("text", "json")),
    "garment_patches": ("patches", "garment", ("json",)),
    "garment_pattern": ("garmentcode", "garment", ("json",)),
    "scene": ("scene", "scene", ("text",)),
    "body_npz": ("body_npz", "body_npz", ("npz",)),
    "body_dir": ("body_dir", "body_dir", ("text",)),
    "obstacle": ("obstacle", "obstacle", ("text",)),
    "rrd": ("rrd", "rrd", ()),
    "checkpoint": ("checkpoint", "checkpoint", ("npz",)),
    "skin_mesh": ("skin_mesh", "skin", ("text",)),
    "skin_rig": ("skin_rig", "skin", ("text", "json")),
    "skin_weights": ("skin_weights", "skin", ("text", "json")),
    "skin_motion": ("skin_motion", "skin", ("text",)),
    "smpl_model": ("smpl_model", "smpl", ("npz",)),
    "smpl_motion": ("smpl_motion", "smpl", ("npz",)),
    "smpl_pkl": ("smpl_pkl", "smpl", ()),
}


# ----------------------------------------------------------------------- mutations

NUMBER = re.compile(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")
VALUES = [b"nan", b"-nan", b"inf", b"-inf", b"NaN", b"1e308", b"1e999", b"-1", b"0", b"-0", b"3",
          b"99999999999999999999", b"2147483648", b"-2147483649", b"1e-320", b'"x"', b"[]", b"{}",
          b"null", b"true", b"", b"\x00", b"\x1b[31m", b"\xff\xfe"]
JSON_VALUES = [None, True, "x", "\x1b[2J", [], {}, [[]], float("nan"), float("inf"), -1, 0, 2**63, 1e308,
               -1e308, [1, 2, 3], {"a": 1}, [float("nan")] * 3, "nan"]


@st.composite
def byte_mutation(draw, raw: bytes) -> bytes:
    n = len(raw)
    kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete", "duplicate", "zero"]))
    at = draw(st.integers(0, max(n - 1, 0)))
    if kind == "truncate":
        return raw[:at]
    if kind == "flip":
        out = bytearray(raw)
        for _ in range(draw(st.integers(1, 16))):
            p = draw(st.integers(0, max(n - 1, 0)))
            if out:
                out[p] ^= draw(st.integers(1, 255))
        return bytes(out)
    if kind == "insert":
        return raw[:at] + draw(st.binary(min_size=1, max_size=256)) + raw[at:]
    length = draw(st.integers(1, 4096))
    if kind == "delete":
        return raw[:at] + raw[at + length:]
    if kind == "zero":
        return raw[:at] + bytes(len(raw[at:at + length])) + raw[at + length:]
    return raw[:at + length] + raw[at:at + length] * draw(st.integers(1, 20)) + raw[at + length:]


@st.composite
def text_mutation(draw, raw: bytes) -> bytes:
    """Numbers swapped for NaN, inf, huge, negative or non-numbers; lines dropped or repeated."""
    numbers = list(NUMBER.finditer(raw))
    lines = raw.split(b"\n")
    kind = draw(st.sampled_from(["number", "number", "numbers", "drop_line", "repeat_line"]))
    if kind in ("number", "numbers") and numbers:
        hits = draw(st.lists(st.integers(0, len(numbers) - 1), min_size=1, max_size=1 if kind == "number" else 20))
        value = draw(st.sampled_from(VALUES))
        out, last = [], 0
        for m in sorted({numbers[h] for h in hits}, key=lambda m: m.start()):
            out += [raw[last:m.start()], value]
            last = m.end()
        return b"".join(out) + raw[last:]
    k = draw(st.integers(0, len(lines) - 1))
    if kind == "drop_line":
        return b"\n".join(lines[:k] + lines[k + 1:])
    return b"\n".join(lines[:k] + [lines[k]] * draw(st.integers(2, 50)) + lines[k:])


def _nodes(doc, path=()):
    yield path
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _nodes(v, path + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:8]):
            yield from _nodes(v, path + (i,))


@st.composite
def json_mutation(draw, raw: bytes) -> bytes:
    """A value anywhere in the document replaced by one of another type, removed, or
    wrapped in a list."""
    doc = json.loads(raw)
    paths = [p for p in _nodes(doc) if p]
    path = draw(st.sampled_from(paths))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    kind = draw(st.sampled_from(["replace", "replace", "remove", "wrap"]))
    if kind == "remove":
        del parent[path[-1]]
    elif kind == "wrap":
        parent[path[-1]] = [parent[path[-1]]]
    else:
        parent[path[-1]] = draw(st.sampled_from(JSON_VALUES))
    return json.dumps(doc).encode()


def _array_variants(a: np.ndarray) -> list:
    b = np.atleast_1d(a)
    if b.dtype.kind not in "biuf":  # a string (the scene hash): numbers of its shape
        b = np.zeros(b.shape)
    nan = b.astype(float)
    nan.reshape(-1)[nan.size // 2] = np.nan
    with np.errstate(all="ignore"):
        return [nan, b.astype(float) * np.inf, b.reshape(-1), b[..., :1], b[:0], b.astype(str), b.astype(bool),
                b.astype(complex), np.asarray(b, object), -np.abs(b) - 1, b * 10**6, np.array(2**40),
                np.float64(3.5), np.repeat(b.reshape(-1)[:1], 3), b.T.copy(), b.astype(np.int8)]


@st.composite
def npz_mutation(draw, raw: bytes) -> bytes:
    """One array of the archive swapped for NaN, inf, another shape, dtype (str, bool,
    complex, Python objects) or sign, deleted, or joined by an extra one."""
    with np.load(io.BytesIO(raw), allow_pickle=False) as d:
        arrays = {k: d[k] for k in d.files}
    key = draw(st.sampled_from(sorted(arrays)))
    kind = draw(st.sampled_from(["variant", "variant", "variant", "delete", "extra"]))
    if kind == "delete":
        del arrays[key]
    elif kind == "extra":
        arrays["extra"] = np.zeros(3)
    else:
        arrays[key] = draw(st.sampled_from(_array_variants(arrays[key])))
    out = io.BytesIO()
    np.savez(out, **arrays)
    return out.getvalue()


@st.composite
def mutated(draw, raw: bytes, kinds: tuple[str, ...]) -> bytes:
    kind = draw(st.sampled_from(("bytes",) + kinds))
    strategy = {"bytes": byte_mutation, "text": text_mutation, "json": json_mutation, "npz": npz_mutation}[kind]
    out = draw(strategy(raw))
    if draw(st.integers(0, 3)) == 0:  # now and then two mutations
        out = draw(byte_mutation(out)) if out else out
    return out


# ----------------------------------------------------------------------- the worker


class Worker:
    """The fuzz worker subprocess: `read(reader, path)` -> its reply (see fuzz_worker)."""

    def __init__(self):
        env = {**os.environ, "NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR", str(ROOT / ".cache" / "numba"))}
        self.proc = subprocess.Popen([sys.executable, "-m", "tests.garment.fuzz_worker"], cwd=ROOT, env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.results: dict[str, list[dict]] = {}

    def read(self, reader: str, path: Path, out: Path) -> dict:
        self.proc.stdin.write(json.dumps({"reader": reader, "path": str(path), "out": str(out)}) + "\n")
        self.proc.stdin.flush()
        reply = json.loads(self.proc.stdout.readline())
        self.results.setdefault(reader, []).append(reply)
        return reply

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=30)


@pytest.fixture(scope="module")
def worker():
    w = Worker()
    yield w
    w.close()


def fuzz_one(worker: Worker, seeds: dict, target: str, data, tmp: Path) -> dict:
    seed_name, reader, kinds = TARGETS[target]
    seed = seeds[seed_name]
    case = tmp / f"case{sum(map(len, worker.results.values()))}"
    if case.exists():
        shutil.rmtree(case)
    case.mkdir(parents=True)
    if seed.is_dir():  # a folder of frames: one frame mutated
        path = case / seed.name
        shutil.copytree(seed, path)
        frame = sorted(path.iterdir())[-1]
        frame.write_bytes(data.draw(mutated(frame.read_bytes(), kinds)))
    else:
        path = case / seed.name
        path.write_bytes(data.draw(mutated(seed.read_bytes(), kinds)))
    r = worker.read(reader, path, case / "out")
    problem = r["problem"] = problem_of(r)
    if problem is None:
        shutil.rmtree(case)  # keep failing cases for a look
    assert problem is None, f"{target} {path}: {problem}\n{r['output'][-3000:]}"
    return r


def problem_of(r: dict) -> str | None:
    """What is wrong with a run, or None."""
    return ("traceback" if r["traceback"] else "hang" if r["hang"] else
            f"exit status {r['code']}" if r["code"] not in ALLOWED_CODES else
            f"{r['maxrss_mb']:.0f} MB" if r["maxrss_mb"] > MAX_RSS_MB else
            "unsafe output" if r["unsafe"] else None)


SETTINGS = dict(deadline=None, database=None, derandomize=False, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize("target", list(TARGETS))
@settings(max_examples=FAST_EXAMPLES, **SETTINGS)
@given(data=st.data())
def test_fuzzed_files_end_cleanly(worker, seeds, tmp_path_factory, target, data):
    fuzz_one(worker, seeds, target, data, tmp_path_factory.getbasetemp() / "fuzz" / target)


@pytest.mark.slow
def test_long_fuzz_run(worker, seeds, tmp_path_factory, capsys):
    """SLOW_EXAMPLES mutated inputs per reader; prints the totals the issue asks for."""
    worker.results.clear()
    for target in TARGETS:
        @settings(max_examples=SLOW_EXAMPLES, **SETTINGS)
        @given(data=st.data())
        def run(data):
            fuzz_one(worker, seeds, target, data, tmp_path_factory.getbasetemp() / "long-fuzz" / target)

        run()
    results = [r for rs in worker.results.values() for r in rs]
    summary = {
        "inputs": len(results),
        "tracebacks": sum(r["traceback"] for r in results),
        "hangs": sum(r["hang"] for r in results),
        "peak_rss_mb": round(max(r["maxrss_mb"] for r in results)),
        "slowest_s": round(max(r["seconds"] for r in results), 2),
        "exit_codes": {str(c): sum(r["code"] == c for r in results) for c in sorted({r["code"] for r in results})},
        "per_reader": {k: len(v) for k, v in worker.results.items()},
    }
    with capsys.disabled():
        print("\nfuzz totals:", json.dumps(summary))
    assert summary["inputs"] >= 2000
    assert summary["tracebacks"] == 0 and summary["hangs"] == 0
    assert summary["peak_rss_mb"] < MAX_RSS_MB
