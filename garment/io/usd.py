"""USD export of a recording: every cloth piece and body as a time-sampled mesh.

Written with Pixar's `usd-core` (`pxr`), for usdview, Blender, Isaac and anything else
that reads USD. The layout:

* stage metadata  metersPerUnit 1 (positions are metres), upAxis Z (or Y), time codes
                  = frame indices, timeCodesPerSecond = the recording's frame rate,
                  startTimeCode / endTimeCode = the first and last intact frame.
* `/World`        the default prim (Xform); under it the scopes `cloth` and `bodies`,
                  one `UsdGeom.Mesh` per piece in them: triangles (faceVertexCounts,
                  faceVertexIndices) once, `points` (float32, m) and `extent` per time
                  code, no subdivision, the Rerun recording's colours, cloth double-sided.
* names           prim names are `Tf.MakeValidIdentifier(name)` (`shirt.left_sleeve_f` ->
                  `shirt_left_sleeve_f`); the piece's own name is the prim's displayName.

Cloth has a sample at every intact frame. A body has one where it moves and at the
frame before each move, so the linear interpolation between samples keeps still
stretches still; a body that never moves has a single sample.

The file is written to `.<stem>.<pid>.tmp<suffix>` beside the target and renamed, so an
error or a signal never leaves a half-written file under the final name.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sim.errors import InputError
from sim.files import atomic_write
from viz.rerun_sink import COLORS, ROOTS

SUFFIXES = (".usd", ".usda", ".usdc")  # .usd is binary (crate), .usda text
UP_AXES = ("z", "y")


def write_usd(recording, path: str | os.PathLike, names: list[str] | None = None, up: str = "z") -> Path:
    """Write the meshes `names` (default: every cloth piece and body) of a
    `viz.recording.Recording` at all its intact frames to `path` (.usd, .usda or .usdc),
    declaring `up` ("z" or "y") as the up axis. Returns the path."""
    from pxr import Usd, UsdGeom

    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise InputError(f"{path}: USD export needs a {', '.join(SUFFIXES)} file name")
    if up not in UP_AXES:
        raise ValueError(f"up axis must be one of {UP_AXES}, got {up!r}")
    frames = recording.frames
    if not frames:
        raise InputError(f"{recording.path}: no intact frames to export")
    names = list(recording.meshes) if names is None else names
    faces = {name: recording.faces(name) for name in names}  # InputError for unknown names, first

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "z" else UsdGeom.Tokens.y)
    stage.SetStartTimeCode(frames[0])
    stage.SetEndTimeCode(frames[-1])
    stage.SetTimeCodesPerSecond(_frame_rate(recording, frames))
    world = UsdGeom.Xform.Define(stage, "/World").GetPrim()
    stage.SetDefaultPrim(world)
    for root in dict.fromkeys(ROOTS[recording.meshes[name].kind] for name in names):
        UsdGeom.Scope.Define(stage, f"/World/{root}")
    taken: set[str] = set()
    for name in names:
        kind = recording.meshes[name].kind
        prim_path = f"/World/{ROOTS[kind]}/{_identifier(name, taken)}"
        _define_mesh(stage, prim_path, name, kind, faces[name], recording, frames)

    with atomic_write(path, keep_suffix=True) as tmp:
        if not stage.GetRootLayer().Export(str(tmp)):  # the format follows the suffix
            raise OSError(f"{path}: USD could not write the file")
    return path


def _define_mesh(stage, prim_path: str, name: str, kind: str, faces: np.ndarray, recording, frames) -> None:
    """One UsdGeom.Mesh: topology once, points and extent at every sampled frame."""
    from pxr import Gf, Usd, UsdGeom, Vt

    mesh = UsdGeom.Mesh.Define(stage, prim_path)
    mesh.GetPrim().SetDisplayName(name)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # triangles as they are, not a limit surface
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    mesh.CreateDoubleSidedAttr(kind == "cloth")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces, np.int32).ravel()))
    mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*(c / 255 for c in COLORS[kind][:3]))]))
    points, extent = mesh.CreatePointsAttr(), mesh.CreateExtentAttr()
    for k, x in _samples(recording, name, kind, frames):
        x = np.ascontiguousarray(x, np.float32)
        points.Set(Vt.Vec3fArray.FromNumpy(x), Usd.TimeCode(k))
        extent.Set(Vt.Vec3fArray.FromNumpy(np.stack([x.min(axis=0), x.max(axis=0)])), Usd.TimeCode(k))


def _samples(recording, name: str, kind: str, frames: list[int]):
    """(frame, (V, 3) float32 positions) to write: every frame for cloth; for a body the
    frames where it moves and the frame before each move."""
    if kind == "cloth":
        for k in frames:
            yield k, recording.positions_at(name, k)
        return
    xs = [recording.positions_at(name, k) for k in frames]
    for i, k in enumerate(frames):
        moved = i == 0 or not np.array_equal(xs[i], xs[i - 1])
        moves_next = i + 1 < len(xs) and not np.array_equal(xs[i + 1], xs[i])
        if moved or moves_next:
            yield k, xs[i]


def _frame_rate(recording, frames: list[int]) -> float:
    """Time codes per second: frames per second of sim_time (24, USD's default, when the
    recording has one frame or no times)."""
    t0, t1 = recording.time_of(frames[0]), recording.time_of(frames[-1])
    if len(frames) < 2 or not np.isfinite(t1 - t0) or t1 <= t0:
        return 24.0
    return (frames[-1] - frames[0]) / (t1 - t0)


def _identifier(name: str, taken: set[str]) -> str:
    """A valid, unused prim name for piece `name`."""
    from pxr import Tf

    base = Tf.MakeValidIdentifier(name)
    ident, n = base, 1
    while ident in taken:
        n += 1
        ident = f"{base}_{n}"
    taken.add(ident)
    return ident
