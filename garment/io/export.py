"""Per-frame mesh export: one file per frame and cloth piece, written atomically.

Files are `<directory>/<name>_<frame:05d>.<fmt>`:

* `npz`  arrays `verts` (V, 3) float64 m, `faces` (F, 3) int32, `uv` (V, 2) float64,
         `time` (s) and `frame` (int) -- lossless.
* `ply`  binary little/big-endian PLY via meshio: double x y z, uv as vertex properties
         `s t`, int32 faces -- lossless.
* `obj`  text, written by hand: `v`, `vt` (uv) and `f v/vt` lines with 17 significant
         digits, so float64 positions round-trip exactly.

Each file is first written to `.<file name>.<pid>.tmp` in the same directory and then
`os.replace`d, so an interrupted run never leaves a half-written frame.
"""

from __future__ import annotations

import os
from pathlib import Path

import meshio
import numpy as np

from sim.files import atomic_write
from sim.sinks import Frame, MeshTopology

FORMATS = ("npz", "obj", "ply")


def _write_npz(path: Path, verts, faces, uv, time: float, frame: int) -> None:
    # Through a file object: np.savez would append ".npz" to a bare ".tmp" path.
    with open(path, "wb") as f:
        np.savez(f, verts=verts, faces=faces, uv=uv, time=np.float64(time), frame=np.int64(frame))


def _write_obj(path: Path, verts, faces, uv, time: float, frame: int) -> None:
    with open(path, "w") as f:
        f.write(f"# frame {frame} time {time!r} s\n")
        np.savetxt(f, verts, fmt="v %.17g %.17g %.17g")
        if len(uv):
            np.savetxt(f, uv, fmt="vt %.17g %.17g")
            np.savetxt(f, np.repeat(faces + 1, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
        else:  # bodies carry no parameters
            np.savetxt(f, faces + 1, fmt="f %d %d %d")


def _write_ply(path: Path, verts, faces, uv, time: float, frame: int) -> None:
    point_data = {"s": uv[:, 0].copy(), "t": uv[:, 1].copy()} if len(uv) else {}
    mesh = meshio.Mesh(verts, [("triangle", faces)], point_data=point_data)
    meshio.write(path, mesh, file_format="ply", binary=True)


_WRITERS = {"npz": _write_npz, "obj": _write_obj, "ply": _write_ply}


class MeshExportSink:
    """Sink writing every mesh (cloth pieces and bodies) of every frame to `directory` in
    format `fmt` (`npz`, `obj` or `ply`; see the module docstring for the file contents)."""

    def __init__(self, directory: str | os.PathLike, fmt: str = "npz"):
        if fmt not in _WRITERS:
            raise ValueError(f"unknown mesh format {fmt!r}, expected one of {FORMATS}")
        self.directory = Path(directory)
        self.fmt = fmt
        self._meshes: dict[str, MeshTopology] = {}

    def open(self, meshes: list[MeshTopology]) -> None:
        """Remember the static topology (faces, uv) of each piece; create the directory."""
        self.directory.mkdir(parents=True, exist_ok=True)
        self._meshes = {m.name: m for m in meshes}

    def path(self, name: str, frame: int) -> Path:
        """Final file path of piece `name` at frame index `frame`."""
        return self.directory / f"{name}_{frame:05d}.{self.fmt}"

    def write(self, frame: Frame) -> None:
        """Write one file per piece: positions (V, 3) m as float64 plus faces and uv."""
        for name, x in frame.positions.items():
            m = self._meshes[name]
            with atomic_write(self.path(name, frame.index)) as tmp:
                _WRITERS[self.fmt](
                    tmp,
                    np.asarray(x, dtype=np.float64),
                    np.asarray(m.faces, dtype=np.int32),
                    np.asarray(m.uv, dtype=np.float64),
                    float(frame.time),
                    int(frame.index),
                )

    def close(self) -> None:
        """Nothing is buffered: every frame is complete on disk once `write` returns."""


def read_frame(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a file written by `MeshExportSink`: (verts (V, 3) float64 m, faces (F, 3) int32)."""
    path = Path(path)
    if path.suffix == ".npz":
        with np.load(path) as data:
            return data["verts"], data["faces"].astype(np.int32)
    mesh = meshio.read(path)
    faces = np.concatenate([c.data for c in mesh.cells if c.type == "triangle"])
    return np.asarray(mesh.points, dtype=np.float64), faces.astype(np.int32)
