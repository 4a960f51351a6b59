"""Triangle meshes read through other libraries (trimesh, then meshio), guarded.

Those readers were written for good files: on a damaged one meshio's PLY header loop
spins forever at the end of the file (a PLY cut short in its header hung `garment
conform` for minutes), and both print to stdout and raise any exception type. `read_mesh`
runs them under a time limit (SIGALRM, main thread only), with their printing captured,
turns whatever they raise into an InputError naming the file (terminal-safe text), and
checks what they return: triangles, finite coordinates, indices in range.
"""

from __future__ import annotations

import contextlib
import io
import signal
import threading
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from sim.errors import InputError, printable
from sim.files import input_file

# Seconds a reader may take: generous for a sound file of that size, short of a hang.
READ_SECONDS = 20.0
READ_SECONDS_PER_MB = 1.0
PLY_HEADER_BYTES = 65536


class _Expired(BaseException):
    """Raised by the alarm; a BaseException so a library's `except Exception` cannot
    swallow it and carry on looping."""


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise _Expired in the block after `seconds` (only in the main thread, where
    signals are delivered; elsewhere no limit)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(_signum, _frame):
        raise _Expired

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@contextlib.contextmanager
def guarded(path: Path, what: str) -> Iterator[None]:
    """Run another library's reader on `path`: time limit, output and warnings captured,
    any failure an InputError "{path}: cannot read {what} (...)"."""
    seconds = READ_SECONDS + READ_SECONDS_PER_MB * path.stat().st_size / 1e6
    sink = io.StringIO()
    try:
        with time_limit(seconds), contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink), \
                warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            yield
    except _Expired:
        raise InputError(f"{path}: cannot read {what}: reading took more than {seconds:.0f} s "
                         "(a damaged or truncated file)") from None
    except InputError:
        raise
    except (Exception, SystemExit) as e:  # anything on a bad file; meshio even calls sys.exit(1)
        said = [line for line in sink.getvalue().splitlines() if line.strip()]
        detail = str(e).strip() if not isinstance(e, SystemExit) and str(e).strip() else (
            said[-1] if said else type(e).__name__)
        raise InputError(f"{path}: cannot read {what} ({printable(detail.splitlines()[0], 200)})") from None


def read_mesh(path: str | Path, what: str = "a triangle mesh") -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) float64 and triangles (F, 3) int64 of any mesh file trimesh or
    meshio reads; 2D points get z = 0. InputError naming the file on any problem."""
    path = input_file(path)
    with guarded(path, what):
        vertices, faces = _load(path)
    if vertices.ndim != 2 or vertices.shape[1] not in (2, 3) or faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"{path}: cannot read {what} (vertices {vertices.shape}, faces {faces.shape})")
    if faces.shape[0] == 0:
        raise InputError(f"{path}: no triangles")
    if vertices.shape[1] == 2:
        vertices = np.concatenate([vertices, np.zeros((vertices.shape[0], 1))], axis=1)
    check_mesh(path, vertices, faces)
    return vertices, faces


def check_mesh(path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Finite vertices and face indices in range, or InputError naming the file."""
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise InputError(f"{path}: vertex {int(np.flatnonzero(bad)[0])} has a non-finite coordinate "
                         f"(NaN or inf; {int(bad.sum())} such vertices)")
    lo, hi = (int(faces.min()), int(faces.max())) if faces.size else (0, 0)
    if lo < 0 or hi >= vertices.shape[0]:
        raise InputError(f"{path}: a face refers to vertex {hi if hi >= vertices.shape[0] else lo}, "
                         f"but the file has {vertices.shape[0]} vertices")


def _load(path: Path) -> tuple[np.ndarray, np.ndarray]:
    if path.suffix.lower() == ".ply":
        with open(path, "rb") as f:
            head = f.read(PLY_HEADER_BYTES)
        if b"end_header" not in head:  # meshio would read past the end of the file forever
            raise InputError(f"{path}: not a PLY file or its header is cut short (no end_header "
                             f"in its first {PLY_HEADER_BYTES // 1024} kB)")
    try:
        import trimesh

        mesh = trimesh.load(path, process=False, force="mesh")
        return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64).reshape(-1, 3)
    except _Expired:
        raise
    except Exception:  # trimesh does not know the format: try meshio
        import meshio

        m = meshio.read(path)
        tris = [c.data for c in m.cells if c.type == "triangle"]
        faces = np.concatenate(tris).astype(np.int64) if tris else np.zeros((0, 3), np.int64)
        return np.asarray(m.points, float), faces
