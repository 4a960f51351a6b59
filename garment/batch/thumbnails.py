"""A small off-screen picture of each finished garment, OUTDIR/<id>/thumbnail.png, drawn
from its final mesh (garment.obj or garment.ply) by viz.render's renderer (PyVista,
OSMesa: no display). Drawn in the driver as results arrive, while the jobs run."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.files import atomic_write

NAME = "thumbnail.png"
MESHES = ("garment.obj", "garment.ply")
SIZE = (256, 256)


def mesh_of(folder: Path) -> Path | None:
    return next((folder / m for m in MESHES if (folder / m).is_file()), None)


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
    # Scene frame: z up (garment.io.bodies turns Y-up bodies); seen from the front, a little above.
    renderer = SceneRenderer([topology], bounds, RenderOptions(size=SIZE, azimuth=-90.0, elevation=10.0),
                             first={"garment": vertices})
    try:
        image = renderer.image({"garment": vertices})
    finally:
        renderer.close()
    import imageio.v2 as iio

    out = folder / NAME
    with atomic_write(out, keep_suffix=True) as tmp:
        iio.imwrite(tmp, image)
    return out
