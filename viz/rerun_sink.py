"""Rerun sink: stream simulated cloth frames into an `.rrd` recording (rerun-sdk 0.41).

Layout of the recording:

* `cloth/<name>`  `Mesh3D`: triangle indices are static (logged once in `open`), vertex
  positions (m, float32) and area-weighted unit vertex normals are temporal.
* `stats/...`     `Scalars` per frame, from the last `StepStats` of the frame (see `STATS`).
* timelines       `frame` (sequence = `Frame.index`), `sim_time` (duration = `Frame.time`, s).

Read back with `read_rrd_positions` / `read_rrd_faces`, which go through rerun's own chunk
reader (`rerun.chunk.RrdReader`), never through the file format itself.
"""

from __future__ import annotations

import os
import re
import uuid
from collections.abc import Callable
from pathlib import Path

import numpy as np
import rerun as rr
from rerun.chunk import RrdReader

from sim.sinks import Frame, MeshTopology
from sim.stats import StepStats

CLOTH = "cloth"

# Scalar time series: entity path -> value extracted from (last step, all steps of the frame).
STATS: dict[str, Callable[[StepStats, list[StepStats]], float]] = {
    "stats/newton_iterations": lambda last, steps: sum(s.newton_iterations for s in steps),
    "stats/residual": lambda last, steps: last.residual,  # m/s
    "stats/energy": lambda last, steps: last.energy,  # J
    "stats/time/assembly": lambda last, steps: last.t_assembly,  # wall-clock s
    "stats/time/factorization": lambda last, steps: last.t_factorization,
    "stats/time/solve": lambda last, steps: last.t_solve,
    "stats/time/line_search": lambda last, steps: last.t_line_search,
    "stats/time/step": lambda last, steps: last.t_total,
}


def vertex_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (V, 3) float32 of a triangle mesh.

    positions (V, 3) in m, faces (F, 3) int. Vertices touched by no (or only degenerate)
    triangles get a zero normal.
    """
    p = np.asarray(positions, dtype=np.float64)
    tri = p[faces]
    # The cross product has length 2 * area, so summing it weights faces by area.
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = np.zeros_like(p)
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0).astype(np.float32)


class RerunSink:
    """Write frames to the Rerun recording file `path` (see module docstring for the layout).

    Data goes to `<dir>/.<name>.<pid>.tmp` and is renamed to `path` in `close()`, so a
    crashed run never leaves a truncated file under the final name. Uses its own
    `rr.RecordingStream` (never the global one), so several sinks can coexist.
    """

    def __init__(self, path: str | os.PathLike, application_id: str = "garment", recording_name: str | None = None):
        self.path = Path(path)
        self.application_id = application_id
        self.recording_name = recording_name
        self._tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        self._rec: rr.RecordingStream | None = None
        self._faces: dict[str, np.ndarray] = {}

    def open(self, meshes: list[MeshTopology]) -> None:
        """Start the recording and log the static triangle indices (F, 3) of every mesh."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # Explicit random id: the default id is shared by every stream of the process.
        self._rec = rec = rr.RecordingStream(self.application_id, recording_id=uuid.uuid4())
        rec.save(self._tmp)  # must come before any logging
        if self.recording_name:
            rec.send_recording_name(self.recording_name)
        for m in meshes:
            self._faces[m.name] = faces = np.ascontiguousarray(m.faces, dtype=np.uint32)
            # Partial update: only the topology is static; positions/normals are temporal.
            # (Never log one component both static and temporal: static always wins.)
            rec.log([CLOTH, m.name], rr.Mesh3D.from_fields(triangle_indices=faces), static=True)

    def write(self, frame: Frame) -> None:
        """Log positions (V, 3) m as float32, vertex normals, and the frame's solver stats."""
        rec = self._rec
        if rec is None:
            raise RuntimeError("RerunSink.write() called before open()")
        rec.set_time("frame", sequence=frame.index)
        rec.set_time("sim_time", duration=frame.time)
        for name, x in frame.positions.items():
            pos = np.ascontiguousarray(x, dtype=np.float32)
            fields = {"vertex_positions": pos}
            if name in self._faces:
                fields["vertex_normals"] = vertex_normals(x, self._faces[name])
            rec.log([CLOTH, name], rr.Mesh3D.from_fields(**fields))
        if frame.steps:
            last = frame.steps[-1]
            for path, value in STATS.items():
                rec.log(path, rr.Scalars(float(value(last, frame.steps))))

    def close(self) -> None:
        """Flush everything to disk and move the finished file to `path`. Idempotent."""
        if self._rec is None:
            return
        self._rec.flush()
        self._rec.disconnect()  # drops the file sink, which closes the file
        self._rec = None
        os.replace(self._tmp, self.path)


def _mesh_name(entity_path: str) -> str | None:
    """`/cloth/<escaped name>` -> name (rerun backslash-escapes `/`, spaces, ...)."""
    prefix = f"/{CLOTH}/"
    if not entity_path.startswith(prefix):
        return None
    return re.sub(r"\\(.)", r"\1", entity_path[len(prefix) :])


def _read_component(path: str | os.PathLike, component: str, static: bool):
    """Yield (mesh name, frame index or None, (N, 3) array) for every logged row of a
    `Mesh3D` component under `cloth/`, using rerun's chunk reader."""
    for chunk in RrdReader(path).stream():
        name = _mesh_name(chunk.entity_path)
        if name is None or chunk.is_static != static:
            continue
        batch = chunk.to_record_batch()
        if component not in batch.schema.names:
            continue
        col = batch.column(component)  # list<fixed_size_list<T>[3]>, one list per row
        frames = [None] * len(col) if static else batch.column("frame").to_numpy()
        for i in range(len(col)):
            if col[i].is_valid:
                yield name, frames[i], col[i].values.flatten().to_numpy().reshape(-1, 3)


def read_rrd_positions(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Mesh name -> (frames, V, 3) float32 vertex positions (m), sorted by `frame` index."""
    rows: dict[str, list] = {}
    comp = rr.Mesh3D.descriptor_vertex_positions().component
    for name, frame, pos in _read_component(path, comp, static=False):
        rows.setdefault(name, []).append((int(frame), pos))
    return {
        name: np.stack([p for _, p in sorted(r, key=lambda t: t[0])]).astype(np.float32)
        for name, r in rows.items()
    }


def read_rrd_faces(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Mesh name -> (F, 3) int64 static triangle indices (the last one logged wins)."""
    comp = rr.Mesh3D.descriptor_triangle_indices().component
    return {name: f.astype(np.int64) for name, _, f in _read_component(path, comp, static=True)}
