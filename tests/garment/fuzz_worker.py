"""Runs readers on untrusted files for tests/garment/test_fuzz.py, each in a forked child
with a time limit and an address-space limit, and reports how each run ended.

    python -m tests.garment.fuzz_worker      # reads JSON requests on stdin, one per line

Request: {"reader": NAME, "path": FILE, "out": FOLDER}. Reply (one JSON line): "code"
(the exit status; 99 for an exception that escaped, -1 for a hang), "traceback",
"hang", "seconds", "maxrss_mb" (peak resident memory of the child, from wait4), and
"output" (what the child printed). The worker imports the readers once and forks per
request, so a run costs milliseconds, not an interpreter start; besides one conform that
warms numba up, it never runs a reader itself, so no child inherits state from another.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import sys
import time
import traceback

EXCEPTION = 99  # exit status of a child whose exception escaped (a traceback)
HANG = -1
LIMIT_SECONDS = 30.0
EXTRA_ADDRESS_SPACE = 2 * 2**30  # a child may map this much beyond what it inherits


def _cli(*args: str) -> int:
    from garment.cli import main

    return main(list(args))


def _call(fn) -> int:
    """0 when fn() returns, 2 (printed like the CLI) on an InputError."""
    from sim.errors import InputError, printable

    try:
        fn()
    except InputError as e:
        print(f"error: {printable(e)}", file=sys.stderr)
        return 2
    return 0


def _obstacle(path: str) -> None:
    from garment.io.obstacles import load_obstacle
    from garment.scene import ObstacleSpec

    load_obstacle(ObstacleSpec(name="body", kind="mesh", mesh=path))


def _body(path: str) -> None:
    from garment.io.bodies import load_sequence

    load_sequence(path, fps=None if path.endswith(".npz") else 25.0)


def _rigged(kind: str, path: str) -> None:
    """A rigged body from a folder of its files (tests/garment/test_fuzz.py), posed whole."""
    from pathlib import Path

    from garment.io.obstacles import load_obstacle
    from garment.scene import ObstacleSpec
    from garment.scene.specs import SkinSpec, SmplSpec

    d = Path(path)

    def one(pattern: str) -> Path:
        return next(iter(sorted(d.glob(pattern))))

    if kind == "skin":
        spec = ObstacleSpec(name="body", kind="skin", up="y", skin=SkinSpec(
            mesh=one("*.obj"), rig=one("*rig.json"), weights=one("*weights.json"), motion=one("*.bvh"), group="body"))
    else:
        spec = ObstacleSpec(name="body", kind="smpl", smpl=SmplSpec(model=one("*model.*"), motion=one("*motion.npz")))
    load_obstacle(spec)


def _garment(path: str) -> None:
    """A scene's [[garment]] source: a patch file, or a pattern conformed on the fly."""
    from pathlib import Path

    from garment.io.garments import load_garment
    from garment.scene import GarmentSpec

    load_garment(GarmentSpec(name="g", source=Path(path), knot_span=0.06))


def _reader(name: str, path: str, out: str) -> int:
    from garment.io.patchfile import load_patchset
    from garment.scene import load_scene
    from sim.checkpoint import read_checkpoint

    if name in ("panel_obj", "panel_ply", "garmentcode"):
        return _cli("conform", path, "-o", out, "-q", "--knot-span", "60")
    if name == "rrd":
        return _cli("inspect", path, "--json", "-q")
    readers = {
        "patches": lambda: load_patchset(path),
        "scene": lambda: load_scene(path),
        "body_npz": lambda: _body(path),
        "body_dir": lambda: _body(path),
        "obstacle": lambda: _obstacle(path),
        "garment": lambda: _garment(path),
        "checkpoint": lambda: read_checkpoint(path),
        "skin": lambda: _rigged("skin", path),
        "smpl": lambda: _rigged("smpl", path),
    }
    return _call(readers[name])


def _vm_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def run(request: dict) -> dict:
    log = os.path.join(request["out"], ".fuzz-output")
    os.makedirs(request["out"], exist_ok=True)
    limit = _vm_bytes() + EXTRA_ADDRESS_SPACE
    start = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # the child: run the reader, exit with its status
        code = EXCEPTION
        try:
            fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            os.dup2(fd, 1)
            os.dup2(fd, 2)
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
            code = _reader(request["reader"], request["path"], request["out"])
        except BaseException:
            traceback.print_exc()
            code = EXCEPTION
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code if 0 <= code < 256 else EXCEPTION)
    hang = False
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        if time.perf_counter() - start > LIMIT_SECONDS:
            hang = True
            os.kill(pid, signal.SIGKILL)
            _, status, usage = os.wait4(pid, 0)
            break
        time.sleep(0.005)
    seconds = time.perf_counter() - start
    with open(log, "rb") as f:
        raw = f.read(200_000)
    output = raw.decode("utf-8", "backslashreplace")
    code = HANG if hang else os.waitstatus_to_exitcode(status)
    return {"code": code, "hang": hang, "seconds": seconds, "maxrss_mb": usage.ru_maxrss / 1024,
            "traceback": "Traceback (most recent call last)" in output or code == EXCEPTION,
            "unsafe": unsafe(raw), "output": output}


def unsafe(raw: bytes) -> bool:
    """Bytes a terminal would act on or garble: not UTF-8, or control characters other
    than newline and tab (escape sequences, NUL, bell)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return True
    return any(not (c.isprintable() or c in "\n\t") for c in text)


def _warm_up(pipeline) -> None:
    """Conform one small square here, so the children inherit numba's compiled kernels
    instead of each loading them from the cache (about a second a child)."""
    import numpy as np

    from sim.patches import Panel

    t = np.linspace(0.0, 0.2, 9)[:-1]
    side = [np.column_stack([t, 0 * t]), np.column_stack([0.2 + 0 * t, t]), np.column_stack([0.2 - t, 0.2 + 0 * t]),
            np.column_stack([0 * t, 0.2 - t])]
    pipeline.conform_all([Panel(name="warm", source="warm-up", rest=np.concatenate(side))], [],
                         pipeline.ConformOptions(knot_span=0.05))


def _warm_skinning() -> None:
    """Compile the skinning kernel here (one vertex, one joint), not in every child."""
    import numpy as np

    from garment.io.skinning import Rig, skin

    rig = Rig(["a"], np.array([-1]), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3), np.int32),
              np.zeros((1, 1), np.int32), np.ones((1, 1)))
    skin(rig, np.eye(3)[None], np.zeros((1, 3)))


def main() -> None:
    # Import what the readers use once, before forking: each child starts warm.
    import garment.cli  # noqa: F401
    import garment.io.bodies  # noqa: F401
    import garment.io.rigged  # noqa: F401
    import garment.io.obstacles  # noqa: F401
    import garment.io.patchfile  # noqa: F401
    import meshio  # noqa: F401
    import trimesh  # noqa: F401
    import viz.recording  # noqa: F401
    from conform import pipeline

    garment.cli.build_parser()  # imports every command's modules (garment.bench: 1.4 s)
    _warm_up(pipeline)
    _warm_skinning()
    for line in sys.stdin:
        if line.strip():
            print(json.dumps(run(json.loads(line))), flush=True)


if __name__ == "__main__":
    main()
