"""Animated bodies: one vertex array per frame on a fixed triangle topology.

Two sources, as character pipelines export them: an NPZ with `verts` (T, V, 3) and
`faces` (F, 3) (optionally `frame_dt` in s), or a directory of OBJ files, one per frame,
in natural order (`shell2.obj` before `shell10.obj`). Positions are converted to metres
(`scale`) and to the simulator's Z-up frame (`up = "y"` rotates +90 degrees about X).
"""

from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.errors import InputError
from sim.files import read_npz

from ..units import LARGEST_M, scale_hint
from .meshfile import read_mesh

_TALL_M = 1.0  # bodies this long along Y (m) are checked for a Y-up export


@dataclass
class BodySequence:
    """frames (T, V, 3) float64 in m (Z-up), faces (F, 3) int32, frame_dt in s. lead_in:
    seconds of frames before the motion proper (a rigged body's blend from its bind pose,
    garment/io/skinning.py), played at the end of the pre-roll; notes: what the reader
    changed or assumed (garment/io/rigged.py)."""

    frames: np.ndarray
    faces: np.ndarray
    frame_dt: float
    lead_in: float = 0.0
    notes: list[str] = field(default_factory=list)

    def at(self, t: float) -> np.ndarray:
        """(V, 3) positions at time t: linear between frames, held after the last."""
        s = max(t, 0.0) / self.frame_dt
        k = min(int(np.floor(s)), len(self.frames) - 1)
        if k >= len(self.frames) - 1:
            return self.frames[-1].copy()
        w = s - k
        return (1.0 - w) * self.frames[k] + w * self.frames[k + 1]

    @property
    def duration(self) -> float:
        return (len(self.frames) - 1) * self.frame_dt


def to_scene_frame(points: np.ndarray, scale: float = 1.0, up: str = "z", translate=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Points (..., 3) of a file scaled, turned Z-up when the file is Y-up (+90 degrees
    about X) and moved: the one convention of bodies, obstacle meshes and placements."""
    points = points * scale
    if up == "y":
        points = points[..., [0, 2, 1]] * np.array([1.0, -1.0, 1.0])
    return points + np.asarray(translate, float)


def from_scene_frame(points: np.ndarray, scale: float = 1.0, up: str = "z") -> np.ndarray:
    """The inverse of to_scene_frame (no translate): scene points in the file's units and axes."""
    if up == "y":
        points = points[..., [0, 2, 1]] * np.array([1.0, 1.0, -1.0])
    return points / scale


def load_sequence(path: Path, scale: float = 1.0, up: str = "z", translate=(0.0, 0.0, 0.0),
                  fps: float | None = None) -> BodySequence:
    """Read an NPZ or OBJ-directory body sequence and check it is usable."""
    path = Path(path)
    if path.is_dir():
        frames, faces = _read_obj_dir(path)
        file_dt = None
    elif path.is_file():
        frames, faces, file_dt = _read_npz(path)
    else:
        raise InputError(f"{path}: no such body sequence (expected an .npz file or a directory of .obj frames)")
    if fps is not None:
        frame_dt = 1.0 / fps
    elif file_dt is not None:
        frame_dt = file_dt
    else:
        raise InputError(f"{path}: the sequence does not store its frame time; give `fps` in the scene")
    frames = to_scene_frame(frames.astype(float), scale, up, translate)
    _check(path, frames, faces, scale)
    return BodySequence(np.ascontiguousarray(frames), faces, float(frame_dt))


def _read_npz(path: Path):
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path}: not an NPZ archive (a body sequence needs arrays verts (T, V, 3), "
                         "faces (F, 3) and frame_dt)")
    data = read_npz(path, "body sequence")
    missing = [k for k in ("verts", "faces") if k not in data]
    if missing:
        raise InputError(f"{path}: body sequence lacks {', '.join(missing)} (needs verts (T, V, 3) and faces (F, 3))")
    verts, faces = data["verts"], data["faces"]
    if verts.ndim != 3 or verts.shape[2] != 3 or verts.dtype.kind not in "fiu" or verts.size == 0:
        raise InputError(f"{path}: verts has shape {verts.shape} ({verts.dtype}), expected (frames, vertices, 3) "
                         "numbers")
    dt = None
    if "frame_dt" in data:
        if data["frame_dt"].size != 1 or data["frame_dt"].dtype.kind not in "fiu":
            raise InputError(f"{path}: frame_dt must be one number (s), got {data['frame_dt'].dtype} "
                             f"{data['frame_dt'].shape}")
        dt = float(data["frame_dt"].reshape(-1)[0])
        if not (dt > 0 and np.isfinite(dt)):
            raise InputError(f"{path}: frame_dt must be a positive number of seconds, got {dt}")
    return verts, _faces(path, faces), dt


def _natural_key(p: Path):
    return [int(s) if s.isdigit() else s for s in re.split(r"(\d+)", p.name)]


def _read_obj_dir(path: Path):
    files = sorted(path.glob("*.obj"), key=_natural_key)
    if not files:
        raise InputError(f"{path}: directory holds no .obj frames")
    frames, faces = [], None
    for f in files:
        V, F = read_mesh(f, "body frame")
        if faces is None:
            faces = F
        elif F.shape != faces.shape or not np.array_equal(F, faces):
            raise InputError(f"{f}: frame topology differs from {files[0].name} (every frame needs the same faces)")
        if frames and V.shape != frames[0].shape:
            raise InputError(f"{f}: {len(V)} vertices, but {files[0].name} has {len(frames[0])}")
        frames.append(V)
    return np.stack(frames), _faces(path, faces)


def _faces(path: Path, faces: np.ndarray) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0 or not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"{path}: faces has shape {faces.shape} ({faces.dtype}), expected (triangles, 3) integers")
    if faces.min() < 0 or faces.max() >= 2**31:
        raise InputError(f"{path}: faces index vertex {faces.min() if faces.min() < 0 else faces.max()}, "
                         "out of range")
    return faces.astype(np.int32)


def _check(path: Path, frames: np.ndarray, faces: np.ndarray, scale: float) -> None:
    if not np.all(np.isfinite(frames)):
        t = int(np.flatnonzero(~np.isfinite(frames).all(axis=(1, 2)))[0])
        raise InputError(f"{path}: frame {t} has non-finite vertex positions")
    if faces.max() >= frames.shape[1] or faces.min() < 0:
        raise InputError(f"{path}: faces index vertex {faces.max()} but frames have {frames.shape[1]} vertices")
    check_extent(path, frames[0], scale, "the body")


def check_extent(path: Path, points: np.ndarray, scale: float, what: str) -> None:
    """InputError when `points` (m, after `scale`) span more than a person or garment could:
    the file is in other units; says which and the scale to set."""
    extent = float(np.ptp(points, axis=0).max())
    if extent > LARGEST_M:
        raise InputError(f"{path}: {what} is {extent:.3g} m across after scaling; the file is probably "
                         f"not in metres ({scale_hint(extent, scale)})")


def check_up_axis(path: Path, verts: np.ndarray) -> None:
    """A person-sized body much longer along Y than along Z was most likely exported Y-up
    (the default of most animation tools); the simulator is Z-up. Only run when the scene
    does not state `up`, so `up = "z"` accepts a body that really lies along Y."""
    ext = np.ptp(verts, axis=0)
    if ext[1] > _TALL_M and ext[1] > 2.5 * ext[2]:
        raise InputError(f"{path}: the body is {ext[1]:.3g} m long along Y but {ext[2]:.3g} m along Z (up): "
                         'it looks Y-up; set `up = "y"` on the obstacle (or `up = "z"` if it really lies along Y)')
