"""A small off-screen picture of each finished garment, OUTDIR/<id>/thumbnail.png, drawn
from its final mesh (garment.obj or garment.ply) on its body by viz.render's renderer
(PyVista, OSMesa: no display). Drawn in the driver as results arrive, while the jobs run."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np

from sim.files import atomic_write

NAME = "thumbnail.png"
MESHES = ("garment.obj", "garment.ply")
SIZE = (256, 256)
REPORT = "report.json"
BODY_SUFFIXES = (".obj", ".ply", ".stl", ".off")  # static meshes; motions are drawn without the body


def mesh_of(folder: Path) -> Path | None:
    return next((folder / m for m in MESHES if (folder / m).is_file()), None)


def up_axis(folder: Path) -> tuple[float, float, float]:
    """The mesh's vertical: +y when the job's report says the body file is Y-up
    (garment.dress writes the mesh in the body file's axes, `body_frame`: "cm, Y-up"),
    else +z, the simulator's frame."""
    try:
        frame = str(json.loads((folder / REPORT).read_text()).get("body_frame", ""))
    except (OSError, ValueError, AttributeError):
        frame = ""
    return (0.0, 1.0, 0.0) if "y-up" in frame.lower() else (0.0, 0.0, 1.0)


def render(folder: Path, body: Path | None = None) -> Path | None:
    """Draw `folder`/thumbnail.png from the job's mesh, over the body (grey) when `body`
    is a static mesh file (the job writes the garment in the body file's units and axes,
    so a garment that fell off or drifted away shows); None when the job left no mesh.
    Raises whatever the reader or renderer raises (the caller notes it and goes on)."""
    from sim.sinks import MeshTopology
    from viz.render import RenderOptions, SceneRenderer

    mesh = mesh_of(folder)
    if mesh is None:
        return None
    meshes = {"garment": (*_read(mesh, "the garment's final mesh"), "cloth")}
    if body is not None and body.is_file() and body.suffix.lower() in BODY_SUFFIXES:
        meshes["body"] = (*_body(body), "body")
    empty = np.zeros((0, 2))
    topologies = [MeshTopology(name, f.astype(np.int32), empty, empty, kind) for name, (_, f, kind) in meshes.items()]
    positions = {name: v for name, (v, _, _) in meshes.items()}
    every = np.concatenate(list(positions.values()))
    bounds = np.array([every.min(axis=0), every.max(axis=0)])
    # Seen from the front (+z of a Y-up GarmentCode body, -y of the simulator's Z-up frame),
    # a little from above.
    options = RenderOptions(size=SIZE, azimuth=-90.0, elevation=10.0, up=up_axis(folder))
    renderer = SceneRenderer(topologies, bounds, options, first=positions)
    try:
        image = renderer.image(positions)
    finally:
        renderer.close()
    import imageio.v2 as iio

    out = folder / NAME
    with atomic_write(out, keep_suffix=True) as tmp:
        iio.imwrite(tmp, image)
    return out


def _read(path: Path, what: str) -> tuple[np.ndarray, np.ndarray]:
    from garment.io.meshfile import read_mesh

    return read_mesh(path, what)


@functools.lru_cache(maxsize=4)
def _body(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A body mesh, read once for all the garments dressed on it."""
    return _read(path, "the body mesh")
