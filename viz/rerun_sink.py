"""Rerun sink: stream simulated frames into an `.rrd` recording and/or a live viewer
(rerun-sdk 0.41).

Layout of the recording (read back by `viz.recording`):

* `cloth/<name>`        `Mesh3D` of a cloth piece: triangle indices, colour and double-sided
                        rendering are static (logged once in `open`); vertex positions (m,
                        float32) and area-weighted unit vertex normals are temporal.
* `bodies/<name>`       the same for bodies and obstacles (`MeshTopology.kind == "body"`);
                        positions are logged again only when they change.
* `control_net/<name>`  optional `LineStrips3D` of the control net (rows and columns), per frame.
* `stats/...`           `Scalars`, one row per time step (see `STEP_SCALARS`), plus every
                        number in `StepStats.extra` (`t_*` keys under `stats/time/`).
* timelines             `frame` (sequence = `Frame.index`), `sim_time` (duration, s); the
                        step scalars also carry `step` (sequence = `StepStats.step`).

A default blueprint (3D view plus one plot per statistic) is sent with the first frame
that carries steps, when the statistics present are known, and again if new ones appear.
"""

from __future__ import annotations

import os
import socket
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from urllib.parse import urlparse

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
import scipy.sparse as sp

from sim.files import temporary_name, track_partial, untrack_partial
from sim.sinks import Frame, MeshTopology
from sim.stats import StepStats

CLOTH = "cloth"
BODIES = "bodies"
CONTROL_NET = "control_net"
STATS = "stats"

# Entity root per MeshTopology.kind.
ROOTS = {"cloth": CLOTH, "body": BODIES}
COLORS = {"cloth": (70, 130, 200, 255), "body": (190, 190, 185, 255)}  # RGBA

# Per-step scalar time series: entity path -> value (unit in the comment).
STEP_SCALARS: dict[str, Callable[[StepStats], float]] = {
    "stats/newton_iterations": lambda s: s.newton_iterations,
    "stats/residual": lambda s: s.residual,  # ||dC||_inf / dt, m/s
    "stats/energy": lambda s: s.energy,  # incremental potential, J
    "stats/time/assembly": lambda s: s.t_assembly,  # wall-clock s
    "stats/time/factorization": lambda s: s.t_factorization,
    "stats/time/solve": lambda s: s.t_solve,
    "stats/time/line_search": lambda s: s.t_line_search,
    "stats/time/ccd": lambda s: s.t_ccd,
    "stats/time/step": lambda s: s.t_total,
}


def extra_scalar_path(key: str) -> str:
    """Entity path of a `StepStats.extra` number: wall-clock times `t_x` join the time
    split as `stats/time/x`; anything else (contact_count, min_distance, ...) is `stats/<key>`."""
    return f"{STATS}/time/{key[2:]}" if key.startswith("t_") else f"{STATS}/{key}"


def _is_number(v) -> bool:
    # bool is an int, but a flag is not a time series.
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def step_scalars(steps: list[StepStats]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Entity path -> (indices into `steps`, float64 values) for the fixed statistics (every
    step) and every number found in `extra` (only the steps that have that key)."""
    every = np.arange(len(steps))
    out = {path: (every, np.array([f(s) for s in steps], dtype=np.float64)) for path, f in STEP_SCALARS.items()}
    for key in dict.fromkeys(k for s in steps for k, v in s.extra.items() if _is_number(v)):
        have = np.array([i for i, s in enumerate(steps) if _is_number(s.extra.get(key))])
        out[extra_scalar_path(key)] = have, np.array([float(steps[i].extra[key]) for i in have])
    return out


def normals_operator(faces: np.ndarray, n_vertices: int) -> sp.csr_matrix:
    """(V, F) vertex-face incidence: `A @ face_vectors` sums each vertex's face vectors."""
    faces = np.asarray(faces)
    rows = faces.ravel()
    cols = np.repeat(np.arange(len(faces)), 3)
    return sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n_vertices, len(faces)))


def vertex_normals(positions: np.ndarray, faces: np.ndarray, incidence: sp.csr_matrix | None = None) -> np.ndarray:
    """Area-weighted unit vertex normals (V, 3) float32 of a triangle mesh.

    positions (V, 3) in m, faces (F, 3) int; `incidence` from `normals_operator` saves
    rebuilding it every frame. Vertices touched by no (or only degenerate) triangles get
    a zero normal.
    """
    p = np.asarray(positions, dtype=np.float64)
    if incidence is None:
        incidence = normals_operator(faces, len(p))
    tri = p[faces]
    # The cross product has length 2 * area, so summing it weights faces by area.
    n = incidence @ np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0).astype(np.float32)


def control_net_strips(C: np.ndarray) -> list[np.ndarray]:
    """Control net (n, m, 3) -> n + m line strips: its rows (m, 3) and columns (n, 3)."""
    C = np.asarray(C, dtype=np.float32)
    return [*C, *C.transpose(1, 0, 2)]


def blueprint(scalar_paths: list[str]) -> rrb.Blueprint:
    """3D view of the scene on the left, one time-series plot per statistic on the right
    (all `stats/time/...` series share one plot: the time split of a step)."""
    plots, seen = [], set()
    for path in scalar_paths:
        origin = f"/{STATS}/time" if path.startswith(f"{STATS}/time/") else f"/{path}"
        if origin not in seen:
            seen.add(origin)
            plots.append(rrb.TimeSeriesView(origin=origin, name=origin.removeprefix(f"/{STATS}/")))
    scene = rrb.Spatial3DView(
        origin="/", name="scene", contents=[f"+ /{CLOTH}/**", f"+ /{BODIES}/**", f"+ /{CONTROL_NET}/**"])
    return rrb.Blueprint(rrb.Horizontal(scene, rrb.Vertical(*plots), column_shares=[2, 1]), collapse_panels=True)


def check_viewer_reachable(url: str, timeout: float = 1.0) -> None:
    """Raise ConnectionError unless something listens at the host/port of a gRPC `url`.

    rerun's gRPC client blocks logging for seconds and then drops data when nobody
    listens, so fail up front with a clear message instead."""
    u = urlparse(url.replace("rerun://", "rerun+http://", 1))
    host, port = u.hostname or "127.0.0.1", u.port or 9876
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as e:
        raise ConnectionError(f"no Rerun viewer listening at {url} ({e.strerror or e}); start one with `rerun`") from e


class RerunSink:
    """Write frames to a Rerun recording file and/or a viewer (see the module docstring).

    path: `.rrd` file. Data goes to `<dir>/.<name>.<pid>.tmp`, renamed to `path` in
    `close()`, so a crashed run never leaves a truncated file under the final name.
    connect: URL of a running viewer to stream to (`DEFAULT_VIEWER_URL` for a local `rerun`).
    serve: port of a gRPC server hosted by this process that viewers can connect to
    (`rerun rerun+http://HOST:PORT/proxy`); it lives until `shutdown()`, not `close()`.
    normals: also log vertex normals (more data, nicer shading in the viewer).
    control_nets: called at every frame, returns cloth name -> control net (n, m, 3) in m,
    logged as line strips (the sink only sees frames, so the caller supplies these).
    flush_interval: wall-clock seconds between forced flushes, so a killed run's file
    holds all but the last moments (rerun otherwise batches for up to 0.2 s or 2 MiB);
    0 flushes every frame.

    Uses its own `rr.RecordingStream` (never the global one), so several sinks coexist.
    `seconds` accumulates the wall-clock time spent inside `open`/`write`/`close`.
    """

    def __init__(
        self,
        path: str | os.PathLike | None = None,
        *,
        connect: str | None = None,
        serve: int | None = None,
        application_id: str = "garment",
        recording_name: str | None = None,
        normals: bool = True,
        control_nets: Callable[[], dict[str, np.ndarray]] | None = None,
        flush_interval: float = 1.0,
    ):
        if path is None and connect is None and serve is None:
            raise ValueError("RerunSink needs a path, a viewer URL to connect to, or a port to serve on")
        self.path = Path(path) if path is not None else None
        self.connect, self.serve = connect, serve
        self.application_id = application_id
        self.recording_name = recording_name
        self.normals = normals
        self.control_nets = control_nets
        self.flush_interval = flush_interval
        self._last_flush = 0.0
        self.seconds = 0.0
        self.server_uri: str | None = None
        self._tmp = temporary_name(self.path) if self.path else None
        self._rec: rr.RecordingStream | None = None
        self._meshes: dict[str, MeshTopology] = {}
        self._incidence: dict[str, sp.csr_matrix] = {}
        self._last_body: dict[str, np.ndarray] = {}
        self._plotted: dict[str, None] = {}  # scalar paths the blueprint plots, in order

    @property
    def recording_id(self) -> str | None:
        return self._rec.get_recording_id() if self._rec is not None else None

    def open(self, meshes: list[MeshTopology]) -> None:
        """Start the recording and log the static part of every mesh: triangle indices
        (F, 3), colour, double-sided rendering."""
        start = time.perf_counter()
        if self.connect is not None:
            check_viewer_reachable(self.connect)
        # Explicit random id: the default id is shared by every stream of the process.
        self._rec = rec = rr.RecordingStream(self.application_id, recording_id=uuid.uuid4())
        sinks = []
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            track_partial(self._tmp, self.path)  # a hard exit keeps what was flushed
            sinks.append(rr.FileSink(self._tmp))
        if self.connect is not None:
            sinks.append(rr.GrpcSink(self.connect))
        if self.serve is not None:
            server = rr.GrpcServerSink(port=self.serve)
            self.server_uri = server.uri
            sinks.append(server)
        rec.set_sinks(*sinks)  # must come before any logging
        if self.recording_name:
            rec.send_recording_name(self.recording_name)
        for m in meshes:
            if m.kind not in ROOTS:
                raise ValueError(f"mesh {m.name!r}: unknown kind {m.kind!r}, expected one of {sorted(ROOTS)}")
            faces = np.ascontiguousarray(m.faces, dtype=np.uint32)
            self._meshes[m.name] = m
            # Partial update: only the topology is static; positions/normals are temporal.
            # (Never log one component both static and temporal: static always wins.)
            rec.log([ROOTS[m.kind], m.name], rr.Mesh3D.from_fields(
                triangle_indices=faces, albedo_factor=COLORS[m.kind],
                face_rendering=rr.components.MeshFaceRendering.DoubleSided), static=True)
            if m.kind == "cloth" and self.control_nets is not None:
                rec.log([CONTROL_NET, m.name], rr.LineStrips3D.from_fields(
                    radii=rr.components.Radius.ui_points(1.0), colors=(230, 120, 40, 255)), static=True)
        rec.flush()  # topology first on disk: a truncated file still knows its meshes
        self._last_flush = time.perf_counter()
        self.seconds += self._last_flush - start

    def write(self, frame: Frame) -> None:
        """Log positions (V, 3) m as float32 and vertex normals of every mesh, the control
        nets if asked for, and one row per step of the frame's solver statistics."""
        rec = self._rec
        if rec is None:
            raise RuntimeError("RerunSink.write() called before open()")
        start = time.perf_counter()
        rec.set_time("frame", sequence=frame.index)
        rec.set_time("sim_time", duration=frame.time)
        for name, x in frame.positions.items():
            m = self._meshes.get(name)
            kind = m.kind if m is not None else "cloth"
            if kind == "body":
                # Static obstacles would repeat identical data every frame; the viewer and
                # our reader carry the last value forward.
                last = self._last_body.get(name)
                if last is not None and np.array_equal(last, x):
                    continue
                self._last_body[name] = np.array(x, copy=True)
            fields = {"vertex_positions": np.ascontiguousarray(x, dtype=np.float32)}
            if self.normals and m is not None:
                A = self._incidence.get(name)
                if A is None or A.shape[0] != len(x):  # built once, when V is known
                    A = self._incidence[name] = normals_operator(m.faces, len(x))
                fields["vertex_normals"] = vertex_normals(x, m.faces, A)
            rec.log([ROOTS[kind], name], rr.Mesh3D.from_fields(**fields))
        if self.control_nets is not None:
            for name, C in self.control_nets().items():
                rec.log([CONTROL_NET, name], rr.LineStrips3D.from_fields(strips=control_net_strips(C)))
        if frame.steps:
            self._write_steps(frame)
        now = time.perf_counter()
        if now - self._last_flush >= self.flush_interval:
            rec.flush()
            now = self._last_flush = time.perf_counter()
        self.seconds += now - start

    def _write_steps(self, frame: Frame) -> None:
        """One row per step, batched: a single `send_columns` per statistic and frame."""
        steps = frame.steps
        scalars = step_scalars(steps)
        if not self._plotted.keys() >= scalars.keys():
            # First steps, or a statistic that appeared later (contact starting): re-layout.
            self._plotted.update(dict.fromkeys(scalars))
            self._rec.send_blueprint(blueprint(list(self._plotted)), make_active=True, make_default=True)
        step_index = np.array([s.step for s in steps])
        step_time = np.array([s.time for s in steps])  # s
        for path, (rows, values) in scalars.items():
            self._rec.send_columns(
                path,
                indexes=[
                    rr.TimeColumn("frame", sequence=np.full(len(rows), frame.index)),
                    rr.TimeColumn("step", sequence=step_index[rows]),
                    rr.TimeColumn("sim_time", duration=step_time[rows]),
                ],
                columns=rr.Scalars.columns(scalars=values),
            )

    def close(self) -> None:
        """Flush everything; finish the file and move it to `path`. Idempotent.

        With `serve`, the server keeps running (and the file stays open) until `shutdown()`."""
        if self._rec is None:
            return
        start = time.perf_counter()
        self._rec.flush()
        if self.serve is None:
            self._finish()
        self.seconds += time.perf_counter() - start

    def shutdown(self) -> None:
        """Stop serving (if serving) and finish the file. Idempotent."""
        if self._rec is not None:
            self._finish()

    def _finish(self) -> None:
        self._rec.disconnect()  # drops the sinks: closes the file, stops a server
        self._rec = None
        if self._tmp is not None:
            untrack_partial(self._tmp)
            if self._tmp.exists():
                os.replace(self._tmp, self.path)
