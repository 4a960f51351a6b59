"""Read a Rerun recording written by `viz.rerun_sink.RerunSink` back into arrays.

Everything goes through rerun-sdk's own loading API (`rerun.chunk.RrdReader`), never
through the file format. A truncated or corrupted file makes `RrdReader` refuse the
whole file; `load_recording` then salvages it by replaying it through rerun's own `.rrd`
data loader (`RecordingStream.log_file_from_path`, which stops at the first undecodable
message) into a fresh temporary file, reads that, and marks the result `damaged`.

A frame is *intact* when every cloth piece has positions at that frame; bodies carry
their last logged positions forward (the sink logs them only when they move).
"""

from __future__ import annotations

import gc
import os
import pickle
import signal
import re
import tempfile
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import RrdReader
from rerun.error_utils import RerunWarning

from sim.errors import InputError
from sim.files import atomic_write, input_file, output_file

from .rerun_sink import BODIES, CLOTH, STATS

_KINDS = {CLOTH: "cloth", BODIES: "body"}
_POSITIONS = rr.Mesh3D.descriptor_vertex_positions().component
_FACES = rr.Mesh3D.descriptor_triangle_indices().component
_SCALARS = rr.Scalars.descriptor_scalars().component
_NAME = "RecordingInfo:name"
_SALVAGE_APP = "garment-salvage"


@dataclass
class MeshTrack:
    """One mesh entity: static faces (F, 3) and positions per `frame` index (arrow list
    values of (V, 3) float32, converted on demand; the last row logged for a frame wins)."""

    name: str
    kind: str  # "cloth" or "body"
    faces: np.ndarray | None = None
    rows: dict[int, pa.Array] = field(default_factory=dict)

    def at(self, frame: int) -> np.ndarray:
        """(V, 3) float32 positions in m at `frame` (bodies: the last logged at or before it)."""
        if frame not in self.rows and self.kind == "body":
            earlier = [k for k in self.rows if k <= frame]
            if earlier:
                frame = max(earlier)
        return self.rows[frame].flatten().to_numpy(zero_copy_only=False).reshape(-1, 3)


@dataclass
class ScalarSeries:
    """One `stats/...` time series: values with their `frame`, `step` (or -1) and
    `sim_time` (s), sorted by step, then frame."""

    values: np.ndarray
    frames: np.ndarray
    steps: np.ndarray
    times: np.ndarray


@dataclass
class Recording:
    """The content of one recording (see the module docstring)."""

    path: Path
    recording_id: str
    application_id: str
    name: str | None
    entities: dict[str, list[str]]  # entity path -> archetypes logged there
    meshes: dict[str, MeshTrack]
    frame_times: dict[int, float]  # frame index -> sim_time in s
    scalars: dict[str, ScalarSeries]  # entity path -> series
    damaged: str | None = None  # why the file could not be read whole, if it could not

    @property
    def cloth_names(self) -> list[str]:
        return [n for n, m in self.meshes.items() if m.kind == "cloth"]

    @property
    def body_names(self) -> list[str]:
        return [n for n, m in self.meshes.items() if m.kind == "body"]

    @property
    def frames(self) -> list[int]:
        """Sorted intact frame indices: every cloth piece has positions there."""
        cloth = [set(self.meshes[n].rows) for n in self.cloth_names]
        if not cloth:
            return sorted({k for m in self.meshes.values() for k in m.rows})
        return sorted(set.intersection(*cloth))

    def faces(self, name: str) -> np.ndarray:
        """(F, 3) int64 triangle indices of mesh `name`."""
        track = self._track(name)
        if track.faces is None:
            raise InputError(f"{self.path}: mesh {name!r} has no triangle indices (static data lost)")
        return track.faces

    def positions_at(self, name: str, frame: int) -> np.ndarray:
        """(V, 3) float32 positions in m of mesh `name` at frame index `frame`."""
        track = self._track(name)
        try:
            return track.at(frame)
        except KeyError:
            raise InputError(f"{self.path}: no positions of {name!r} at frame {frame}; "
                             f"intact frames: {_ranges(self.frames)}") from None

    def positions(self, name: str) -> np.ndarray:
        """(len(frames), V, 3) float32 positions in m of mesh `name` over the intact frames."""
        track = self._track(name)
        frames = self.frames
        if not frames:
            return np.zeros((0, 0, 3), np.float32)
        return np.stack([track.at(k) for k in frames])

    def time_of(self, frame: int) -> float:
        return self.frame_times.get(frame, float("nan"))

    def _track(self, name: str) -> MeshTrack:
        try:
            return self.meshes[name]
        except KeyError:
            names = ", ".join(self.meshes) or "none"
            raise InputError(f"{self.path}: no mesh named {name!r}; meshes: {names}") from None

    def summary(self) -> dict:
        """Plain-data summary (JSON-ready): ids, entities, frames, time range, vertex and
        face counts, and min/mean/max of every scalar series."""
        frames = self.frames
        times = [self.time_of(k) for k in frames]
        meshes = {}
        for name, m in self.meshes.items():
            sample = next(iter(m.rows.values()), None)
            meshes[name] = {
                "kind": m.kind,
                "vertices": len(sample) if sample is not None else None,
                "faces": int(len(m.faces)) if m.faces is not None else None,
                "frames_logged": len(m.rows),
            }
        stats = {}
        for path, s in self.scalars.items():
            v = s.values[np.isfinite(s.values)]
            stats[path.removeprefix(f"/{STATS}/")] = {
                "count": int(len(s.values)),
                "min": float(v.min()) if v.size else None,
                "mean": float(v.mean()) if v.size else None,
                "max": float(v.max()) if v.size else None,
            }
        return {
            "path": str(self.path),
            "recording_id": self.recording_id,
            "application_id": self.application_id,
            "name": self.name,
            "damaged": self.damaged,
            "frames": len(frames),
            "frame_range": [frames[0], frames[-1]] if frames else None,
            "time_range": [min(times), max(times)] if frames else None,
            "entities": self.entities,
            "meshes": meshes,
            "stats": stats,
        }


def _ranges(ks: list[int]) -> str:
    """[0, 1, 2, 5] -> '0-2, 5'."""
    out, start = [], None
    for i, k in enumerate(ks):
        if start is None:
            start = k
        if i + 1 == len(ks) or ks[i + 1] != k + 1:
            out.append(f"{start}" if start == k else f"{start}-{k}")
            start = None
    return ", ".join(out) or "none"


def _unescape(part: str) -> str:
    """rerun backslash-escapes `/`, spaces, ... inside entity path parts."""
    return re.sub(r"\\(.)", r"\1", part)


def _mesh_entity(entity_path: str) -> tuple[str, str] | None:
    """`/cloth/<escaped name>` -> ("cloth", name); `/bodies/...` -> ("body", name)."""
    for root, kind in _KINDS.items():
        prefix = f"/{root}/"
        if entity_path.startswith(prefix):
            return kind, _unescape(entity_path[len(prefix):])
    return None


def _seconds(col: pa.Array) -> np.ndarray:
    """duration[ns] arrow column -> float64 seconds."""
    return col.cast(pa.int64()).to_numpy(zero_copy_only=False) / 1e9


def _open(path: Path) -> tuple[RrdReader, object]:
    """Reader and its first recording store; raises RuntimeError/ValueError when rerun
    cannot read the file whole."""
    with warnings.catch_warnings():
        # Files without the footer (unfinished or salvaged) are still fine to stream.
        warnings.simplefilter("ignore", RerunWarning)
        reader = RrdReader(path)
        stores = [s for s in reader.recordings() if s.application_id != _SALVAGE_APP]
    if not stores:
        raise ValueError("no recording in the file")
    return reader, stores[0]


def replay(path: str | os.PathLike, sink, application_id: str = _SALVAGE_APP, recording_id: str | None = None) -> None:
    """Replay the recording at `path` through rerun's own `.rrd` loader into `sink` (an
    `rr.FileSink`, `rr.GrpcSink`, ...), keeping every message it can decode; the original
    recording id and application id survive. Returns once everything is sent.

    The replaying stream is a recording of its own (`application_id`, `recording_id`, new
    by default) that holds nothing; given the file's ids it merges into the file's."""
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="garment-replay-") as tmp:
        # The loader is chosen by file extension: make sure it is the .rrd one (and keep the
        # user's file name, which rerun's warnings about undecodable messages print).
        src = Path(tmp) / (path.name if path.suffix == ".rrd" else f"{path.name}.rrd")
        os.symlink(path.resolve(), src)
        rec = rr.RecordingStream(application_id, recording_id=recording_id or uuid.uuid4(), send_properties=False)
        rec.set_sinks(sink)
        # This returns as soon as the loader thread starts. Dropping the last handle of the
        # stream joins the loader threads, then flushes and closes the sinks; `flush()` or
        # `disconnect()` would not wait for the loader (rerun's RecordingStream::drop).
        rec.log_file_from_path(src)
        del rec
        gc.collect()


def _salvage(path: Path, tmpdir: str) -> Path:
    """`path` replayed into a new file in `tmpdir` (see `replay`)."""
    out = Path(tmpdir) / "salvaged.rrd"
    replay(path, rr.FileSink(out))
    return out


def load_recording(path: str | os.PathLike) -> Recording:
    """Read the recording at `path`. Raises InputError if the file is missing or nothing
    can be read from it; a damaged file that still yields data gives `damaged` set.

    Read in a forked child: on some damaged files rerun's reader aborts the whole process
    (a Rust panic, SIGABRT; found by fuzzing), which is then a clean InputError here."""
    path = input_file(path, "Rerun recording (.rrd)")
    if not hasattr(os, "fork"):
        return _load(path)
    with tempfile.TemporaryFile() as out:
        pid = os.fork()
        if pid == 0:  # the child: read, hand the result (or the error) back, never return
            code = 0
            try:
                try:
                    result = ("ok", _load(path))
                except Exception as e:  # handed back and raised in the parent
                    result = ("error", e)
                pickle.dump(result, out)
                out.flush()
            except BaseException:
                code = 1
            os._exit(code)
        _, status = os.waitpid(pid, 0)
        if os.WIFSIGNALED(status) or os.WEXITSTATUS(status) != 0:
            why = (f"signal {signal.Signals(os.WTERMSIG(status)).name}" if os.WIFSIGNALED(status)
                   else f"exit status {os.WEXITSTATUS(status)}")
            raise InputError(f"{path}: not a readable Rerun recording (rerun's reader crashed on it: {why})")
        out.seek(0)
        kind, value = pickle.load(out)
    if kind == "error":
        raise value
    return value


def _load(path: Path) -> Recording:
    try:
        reader, store = _open(path)
        return _read(path, reader, store, None)
    except (RuntimeError, ValueError, OSError) as e:
        error = str(e).splitlines()[0] if str(e) else type(e).__name__
    with tempfile.TemporaryDirectory(prefix="garment-salvage-") as tmp:
        try:
            salvaged = _salvage(path, tmp)
            reader, store = _open(salvaged)
            return _read(path, reader, store, error)
        except (RuntimeError, ValueError, OSError):
            raise InputError(f"{path}: not a readable Rerun recording ({error})") from None


def _read(path: Path, reader: RrdReader, store, damaged: str | None) -> Recording:
    """One pass over the store's chunks, collecting meshes, frame times and scalars."""
    entities: dict[str, set[str]] = {}
    meshes: dict[str, MeshTrack] = {}
    frame_times: dict[int, float] = {}
    scalar_parts: dict[str, list[tuple]] = {}
    name = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RerunWarning)
        chunks = list(reader.stream(store=store))
    for chunk in chunks:
        batch = chunk.to_record_batch()
        names = batch.schema.names
        ep = chunk.entity_path
        if ep.startswith("/__properties"):
            if _NAME in names and batch.column(_NAME)[0].is_valid:
                name = batch.column(_NAME)[0].values[0].as_py()
            continue
        archetypes = {
            f.metadata[b"rerun:archetype"].decode().rsplit(".", 1)[-1]
            for f in batch.schema if f.metadata and b"rerun:archetype" in f.metadata
        }
        entities.setdefault(ep, set()).update(archetypes)

        mesh = _mesh_entity(ep)
        if mesh is not None:
            kind, mname = mesh
            track = meshes.setdefault(mname, MeshTrack(mname, kind))
            if chunk.is_static and _FACES in names:
                col = batch.column(_FACES)
                for i in range(len(col)):
                    if col[i].is_valid:
                        track.faces = col[i].values.flatten().to_numpy().reshape(-1, 3).astype(np.int64)
            if not chunk.is_static and _POSITIONS in names and "frame" in names:
                col = batch.column(_POSITIONS)
                frames = batch.column("frame").to_numpy(zero_copy_only=False)
                times = _seconds(batch.column("sim_time")) if "sim_time" in names else None
                for i in range(len(col)):
                    if col[i].is_valid:
                        track.rows[int(frames[i])] = col[i].values
                        if times is not None and kind == "cloth":
                            frame_times[int(frames[i])] = float(times[i])
        elif _SCALARS in names and not chunk.is_static:
            n = batch.num_rows

            def index(col: str, conv=lambda c: c.to_numpy(zero_copy_only=False)) -> np.ndarray:
                return conv(batch.column(col)).astype(float) if col in names else np.full(n, -1.0)

            values = np.array([v[0] if v else np.nan for v in batch.column(_SCALARS).to_pylist()], float)
            scalar_parts.setdefault(ep, []).append(
                (values, index("frame"), index("step"), index("sim_time", _seconds)))

    scalars = {}
    for ep, parts in scalar_parts.items():
        v, f, s, t = (np.concatenate(p) for p in zip(*parts))
        order = np.lexsort((f, s))
        scalars[ep] = ScalarSeries(v[order], f[order].astype(int), s[order].astype(int), t[order])
    return Recording(
        path=path, recording_id=store.recording_id, application_id=store.application_id, name=name,
        entities={e: sorted(a) for e, a in sorted(entities.items())}, meshes=meshes,
        frame_times=frame_times, scalars=dict(sorted(scalars.items())), damaged=damaged,
    )


def garment_mesh(recording: Recording, frame: int, names: list[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Meshes `names` (default: every cloth piece) at `frame` merged into one mesh:
    vertices (V, 3) float32 in m and faces (F, 3) int64."""
    names = names if names is not None else recording.cloth_names
    verts, faces, offset = [], [], 0
    for name in names:
        x = recording.positions_at(name, frame)
        verts.append(x)
        faces.append(recording.faces(name) + offset)
        offset += len(x)
    if not verts:
        raise InputError(f"{recording.path}: no cloth meshes in the recording")
    return np.concatenate(verts), np.concatenate(faces)


def export_mesh(path: str | os.PathLike, verts: np.ndarray, faces: np.ndarray) -> Path:
    """Write a triangle mesh as `.obj` (text, 9 significant digits: float32 round-trips
    exactly) or `.ply` (binary, float32 vertices). Written to a temporary name first."""
    import meshio

    path = output_file(path, (".obj", ".ply"), "the exported mesh")
    with atomic_write(path) as tmp:
        if path.suffix.lower() == ".obj":
            with open(tmp, "w") as f:
                np.savetxt(f, verts, fmt="v %.9g %.9g %.9g")
                np.savetxt(f, np.asarray(faces) + 1, fmt="f %d %d %d")
        else:
            mesh = meshio.Mesh(np.asarray(verts, np.float32), [("triangle", np.asarray(faces, np.int32))])
            meshio.write(tmp, mesh, file_format="ply", binary=True)
    return path


def read_rrd_positions(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Cloth name -> (frames, V, 3) float32 vertex positions (m), sorted by `frame` index.
    (A shortcut for `load_recording(path).positions(name)`.)"""
    rec = load_recording(path)
    return {name: rec.positions(name) for name in rec.cloth_names}


def read_rrd_faces(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Cloth name -> (F, 3) int64 static triangle indices."""
    rec = load_recording(path)
    return {name: rec.faces(name) for name in rec.cloth_names}
