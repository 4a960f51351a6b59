"""A small off-screen picture of each finished garment, OUTDIR/<id>/thumbnail.png, drawn
from its final mesh (garment.obj or garment.ply) by viz.render's renderer (PyVista,
OSMesa: no display). Drawn in the driver as results arrive, while the jobs run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from sim.files import atomic_write

NAME = "thumbnail.png"
MESHES = ("garment.obj", "garment.ply")
SIZE = (256, 256)
REPORT = "report.json"


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


def render(folder: Path) -> Path | None:
    """Draw `folder`/thumbnail.png from the job's mesh; None when it has no mesh. Raises
    whatever the reader or renderer raises (the caller notes it and goes on)."""
    from garment.io.meshfile import read_mesh
    from sim.sinks import MeshTopology
    from viz.render import RenderOptions, SceneRenderer

    mesh = mesh_of(folder)
    if mesh is None:
        return None
    vertices, faces = read_mesh(mesh, "the garment's final mesh")
    empty = np.zeros((0, 2))
    topology = MeshTopology("garment", faces.astype(np.int32), empty, empty, "cloth")
    bounds = np.array([vertices.min(axis=0), vertices.max(axis=0)])
    # Seen from the front (+z of a Y-up GarmentCode body, -y of the simulator's Z-up frame),
    # a little from above.
    options = RenderOptions(size=SIZE, azimuth=-90.0, elevation=10.0, up=up_axis(folder))
    renderer = SceneRenderer([topology], bounds, options, first={"garment": vertices})
    try:
        image = renderer.image({"garment": vertices})
    finally:
        renderer.close()
    import imageio.v2 as iio

    out = folder / NAME
    with atomic_write(out, keep_suffix=True) as tmp:
        iio.imwrite(tmp, image)
    return out
