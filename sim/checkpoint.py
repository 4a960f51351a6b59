"""Simulator state snapshots: in memory (step splitting, discarding a partial frame) and
on disk (checkpoints to resume a run bit-for-bit).

A Simulator's model is rebuilt from its scene; what changes over a run is small:
control points C and velocities V, time t, the step counter, the current time step, the
obstacle vertices (bodies lag behind their targets when cloth blocks them), the barrier
stiffness kappa and the adaptive-stiffness memory (floor, last distance), the seams'
multipliers and which of their contact vertices are sewn yet, and Newton's projection
back-off. Everything else is rebuilt at every step start (inertia target,
friction's lagged contacts from C, body targets from t), so restoring these fields makes
the following steps identical to an uninterrupted run (same thread count).

On disk: one NPZ, written to a temporary name in the same folder and `os.replace`d, so a
crash never leaves a half-written checkpoint under the final name.
"""

from __future__ import annotations

import hashlib
import os
import zipfile
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path

import numpy as np

from garment.errors import InputError

FORMAT = 2  # bump when the set of fields changes


@dataclass
class SimState:
    """A copy of everything that evolves in a Simulator (see the module docstring)."""

    C: np.ndarray
    V: np.ndarray
    t: float
    step_count: int
    dt: float
    obstacle_vertices: np.ndarray | None = None  # (Vo, 3) m, with contact only
    drive_target: np.ndarray | None = None
    kappa: float | None = None
    stiffness_floor: float | None = None
    stiffness_prev_d: float | None = None
    projection_backoff: tuple[int, int] = (0, 1)
    seam_multipliers: np.ndarray | None = None  # (S, 3) N/m, with seams only
    seam_gaps: np.ndarray | None = None  # (S,) m, at the multipliers' last update
    seam_pairs: np.ndarray | None = None  # (P,) seam vertex pairs: 0 open, 1 merged, 2 apart for good, 3 blocked
    pleat_faces: np.ndarray | None = None  # (F,) 1 where a seam onto a pleat no longer waits


# SimState fields that are None in scenes without contact, bodies or seams: stored only
# when set.
_OPTIONAL_ARRAYS = ("obstacle_vertices", "drive_target", "seam_multipliers", "seam_gaps", "seam_pairs",
                    "pleat_faces")
_OPTIONAL_NUMBERS = ("kappa", "stiffness_floor", "stiffness_prev_d")


def capture(sim) -> SimState:
    """Copy the evolving state of `sim` (cheap: a few arrays)."""
    s = SimState(sim.C.copy(), sim.V.copy(), float(sim.t), int(sim.step_count), float(sim.dt),
                 projection_backoff=tuple(int(x) for x in sim.potential.projection_backoff))
    if sim.barrier is not None:
        s.obstacle_vertices = sim.barrier.contact.obstacle_vertices.copy()
        s.kappa = float(sim.barrier.kappa)
    if sim.drive is not None:
        s.drive_target = sim.drive.target.copy()
    if sim.stiffness is not None:
        s.stiffness_floor = float(sim.stiffness.floor)
        s.stiffness_prev_d = float(sim.stiffness._prev_d)
    if sim.seam is not None:
        s.seam_multipliers = sim.seam.multipliers.copy()
        s.seam_gaps = sim.seam.last_gaps.copy()
        if sim.seam_contact is not None:
            s.seam_pairs = sim.seam_contact.state.copy()
        if len(sim.faces_released):
            s.pleat_faces = sim.faces_released.astype(np.float64)
    return s


def restore(sim, s: SimState) -> None:
    """Put `s` back into `sim` (built from the same scene)."""
    if s.C.shape != sim.C.shape:
        raise ValueError(f"state has {s.C.shape[0]} control points, the simulator {sim.C.shape[0]}")
    sim.C = s.C.copy()
    sim.V = s.V.copy()
    sim.t = s.t
    sim.step_count = s.step_count
    if sim.dt != s.dt:
        sim.set_dt(s.dt)
    sim.potential.projection_backoff = tuple(s.projection_backoff)
    if sim.barrier is not None and s.obstacle_vertices is not None:
        # move_obstacles also bumps the mesh version, so cached contact sets expire.
        sim.barrier.contact.move_obstacles(s.obstacle_vertices.copy())
        sim.barrier.kappa = s.kappa
    if sim.drive is not None and s.drive_target is not None:
        sim.drive.target = s.drive_target.copy()
    if sim.stiffness is not None and s.stiffness_floor is not None:
        sim.stiffness.floor = s.stiffness_floor
        sim.stiffness._prev_d = s.stiffness_prev_d
    if sim.seam is not None and s.seam_multipliers is not None:
        sim.seam.multipliers = s.seam_multipliers.copy()
        if s.seam_gaps is not None:
            sim.seam.last_gaps = s.seam_gaps.copy()
    if s.pleat_faces is not None:
        sim.faces_released = s.pleat_faces.astype(bool)
    if s.seam_pairs is not None:  # also back to fewer merged pairs (a retried step)
        sim._merge_seams(restore=s.seam_pairs)


# --------------------------------------------------------------------------- on disk


@dataclass
class Checkpoint:
    state: SimState
    frame: int  # last completed frame index
    scene_hash: str
    threads: tuple[int, int]  # (numba, ipctk) threads of the writing run (results depend on them)


def thread_count() -> tuple[int, int]:
    """(numba, ipctk) thread counts. Numba's reductions are fixed per thread count;
    ipctk's TBB reductions are not (two identical runs differ by ~1e-13 in contact
    scenes) unless ipctk runs on one thread (`garment simulate --deterministic`)."""
    import ipctk
    import numba

    return int(numba.get_num_threads()), int(ipctk.get_num_threads())


def write_checkpoint(path: str | os.PathLike, sim, frame: int, scene_hash: str,
                     state: SimState | None = None) -> Path:
    """Write `state` (default: sim's current state) as the checkpoint after `frame`."""
    path = Path(path)
    s = state if state is not None else capture(sim)
    arrays = {
        "format": np.int64(FORMAT), "frame": np.int64(frame), "scene_hash": np.str_(scene_hash),
        "threads": np.asarray(thread_count(), np.int64),
        "C": s.C, "V": s.V, "t": np.float64(s.t), "step_count": np.int64(s.step_count), "dt": np.float64(s.dt),
        "projection_backoff": np.asarray(s.projection_backoff, np.int64),
    }
    for name in _OPTIONAL_ARRAYS + _OPTIONAL_NUMBERS:
        value = getattr(s, name)
        if value is not None:
            arrays[name] = np.asarray(value, np.float64)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:  # a file object: np.savez would append ".npz" to a path
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())  # the rename must never expose a file whose data is still in flight
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def read_checkpoint(path: str | os.PathLike) -> Checkpoint:
    """Read a checkpoint; InputError naming the file when it is missing or unreadable."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no checkpoint to resume from (run without --resume first)")
    try:
        with np.load(path, allow_pickle=False) as d:
            if int(d["format"]) != FORMAT:
                raise InputError(f"{path}: checkpoint format {int(d['format'])}, this version reads {FORMAT}")
            opt = {k: d[k] for k in _OPTIONAL_ARRAYS if k in d.files}
            num = {k: float(d[k]) for k in _OPTIONAL_NUMBERS if k in d.files}
            state = SimState(d["C"].copy(), d["V"].copy(), float(d["t"]), int(d["step_count"]), float(d["dt"]),
                             projection_backoff=tuple(int(x) for x in d["projection_backoff"]),
                             **{k: v.copy() for k, v in opt.items()}, **num)
            return Checkpoint(state, int(d["frame"]), str(d["scene_hash"]), tuple(int(x) for x in d["threads"]))
    except (OSError, KeyError, ValueError, TypeError, zipfile.BadZipFile) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(f"{path}: not a readable checkpoint ({e})") from None


# --------------------------------------------------------------------------- scene identity


def scene_hash(scene) -> str:
    """SHA-256 over what determines the simulation: the validated scene (frame count and
    outputs excluded, so a resumed run may go further or write elsewhere) and the bytes
    of every mesh or body file it reads."""
    import dataclasses

    h = hashlib.sha256()
    spec = dataclasses.replace(scene, path=None, output=dataclasses.replace(scene.output, rrd=None, mesh_dir=None),
                               time=dataclasses.replace(scene.time, frames=0))
    h.update(_canonical(spec).encode())
    for o in scene.obstacles:
        for p in (o.mesh, o.animation):
            if p is not None:
                for f in sorted(Path(p).rglob("*")) if Path(p).is_dir() else [Path(p)]:
                    if f.is_file():
                        h.update(f.name.encode())
                        h.update(f.read_bytes())
    return h.hexdigest()


def _canonical(x) -> str:
    """A repr that does not abbreviate arrays and names every field."""
    if is_dataclass(x):
        return f"{type(x).__name__}(" + ",".join(f"{f.name}={_canonical(getattr(x, f.name))}" for f in fields(x)) + ")"
    if isinstance(x, (list, tuple)):
        return "[" + ",".join(_canonical(v) for v in x) + "]"
    if isinstance(x, dict):
        return "{" + ",".join(f"{k!r}:{_canonical(v)}" for k, v in sorted(x.items())) + "}"
    if isinstance(x, np.ndarray):
        return f"array({x.dtype},{x.shape},{x.tobytes().hex()})"
    if isinstance(x, Path):
        return repr(str(x))
    return repr(x)
