"""The linear FEM baseline model: cloth as a flat triangle mesh.

Same incremental potential, projected Newton, CHOLMOD solver, assembly and contact as the
B-spline model (a sim.model.Model, stepped the same way), with the energies discretised
on linear triangles: FBW / StVK membrane with one point per
triangle (sim/linear/membrane.py), Bergou bending on interior edges, lumped masses
rho h A / 3 per vertex. Vertices are the unknowns, so W is the identity.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np
import scipy.sparse as sp

from ..materials import Material

from ..energies import membrane_params
from ..model import ContactOptions, Elastic, Model
from ..newton import NewtonOptions
from ..pins import PinGroup
from ..sinks import MeshTopology
from .bending_bergou import hinge_points
from .membrane import lumped_areas, triangle_points
from .mesh import TriangleMesh, equilateral_mesh, grid_mesh

LAYOUTS = ("grid", "equilateral")


@dataclass
class LinearPiece:
    """One cloth as a triangle mesh; W = identity (vertices are the unknowns)."""

    name: str
    mesh: TriangleMesh
    material: Material
    offset: int
    W: sp.csr_matrix
    topology: MeshTopology

    @property
    def slice(self) -> slice:
        return slice(self.offset, self.offset + self.mesh.n_vertices)

    def control_points(self, C: np.ndarray) -> np.ndarray:
        """(V, 3) this piece's vertices in C."""
        return C[self.slice]


def select_vertices(mesh: TriangleMesh, corners=(), sides=(), box=None, depth: int = 1) -> np.ndarray:
    """Vertices picked like sim.pins.select picks control points, by rest position:
    corners -> the corner vertex, sides -> the `depth` outermost vertex rows (distinct
    coordinates) of that side, box -> vertices inside ((s0, t0), (s1, t1)) in [0, 1]^2."""
    st = mesh.normalized
    eps = 1e-9
    mask = np.zeros(mesh.n_vertices, bool)
    for c in corners:
        target = np.array([float(c[1] == "1"), float(c[3] == "1")])
        mask[np.argmin(np.sum((st - target) ** 2, axis=1))] = True
    for s in sides:
        axis = 0 if s[0] == "u" else 1
        x = st[:, axis] if s[1] == "0" else 1.0 - st[:, axis]
        levels = np.unique(np.round(x, 12))
        mask |= x <= levels[min(depth, levels.size) - 1] + eps
    if box is not None:
        (s0, t0), (s1, t1) = box
        mask |= ((st[:, 0] >= s0 - eps) & (st[:, 0] <= s1 + eps) & (st[:, 1] >= t0 - eps) & (st[:, 1] <= t1 + eps))
    return np.flatnonzero(mask)


def cloth_mesh(size: tuple[float, float], resolution, layout: str = "grid") -> TriangleMesh:
    """resolution: vertices per side (int: along the width, the height in proportion)."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown mesh layout {layout!r}; choose from {', '.join(LAYOUTS)}")
    if layout == "equilateral":
        n = resolution if np.isscalar(resolution) else resolution[0]
        return equilateral_mesh(size, int(n))
    if np.isscalar(resolution):
        a = int(resolution)
        resolution = (a, max(2, int(round((a - 1) * size[1] / size[0])) + 1))
    return grid_mesh(size, tuple(int(r) for r in resolution))


def linear_model(meshes: list[TriangleMesh], worlds: list[np.ndarray], materials: list[Material],
                 pins: Iterable[PinGroup] = (), gravity=(0.0, 0.0, -9.81), pressure: float = 0.0,
                 pressure_directions: list[np.ndarray] | None = None, dt: float = 0.01, mode: str = "dynamic",
                 newton: NewtonOptions | None = None, contact: ContactOptions | None = None, obstacles=(),
                 names: list[str] | None = None) -> Model:
    """meshes / worlds / materials: one flat rest mesh, its initial world vertices (V, 3) and
    material per cloth; pins: groups of global vertex indices; the rest as
    sim.model.bspline_model. No seams between linear cloths."""
    offsets = np.cumsum([0] + [m.n_vertices for m in meshes])
    n = int(offsets[-1])
    names = names or [f"cloth{k}" for k in range(len(meshes))]
    pieces = []
    for name, mesh, material, off in zip(names, meshes, materials, offsets):
        V = mesh.n_vertices
        W = sp.csr_matrix((np.ones(V), (np.arange(V), off + np.arange(V))), shape=(V, n))
        topo = MeshTopology(name, mesh.faces.astype(np.int32), mesh.normalized, mesh.rest)
        pieces.append(LinearPiece(name, mesh, material, int(off), W, topo))

    areas = np.zeros(n)
    mass = np.zeros(n)
    forces = np.zeros((n, 3))
    membranes: dict[str, list] = {}
    bend_parts, bend_D = [], []
    for k, piece in enumerate(pieces):
        mat, sl = piece.material, piece.slice
        areas[sl] = lumped_areas(piece.mesh)
        mass[sl] = mat.areal_density * areas[sl]
        pts = triangle_points(piece.mesh)
        pts.idx += piece.offset
        if mat.membrane != "none":
            membranes.setdefault(mat.membrane, []).append((pts, membrane_params(mat)))
        hinges = hinge_points(piece.mesh)
        hinges.idx += piece.offset
        bend_parts.append(hinges)
        bend_D.append(np.full(hinges.n_points, mat.bending_stiffness))
        d = pressure_directions[k] if pressure_directions is not None else np.array([0.0, 0.0, 1.0])
        forces[sl] += pressure * areas[sl, None] * np.asarray(d, float)[None, :]
    forces += mass[:, None] * np.asarray(gravity, float)[None, :]

    C0 = np.concatenate([np.asarray(w, float) for w in worlds])
    return Model(pieces, Elastic(mass, areas, forces, bend_parts, bend_D, membranes), C0, gravity=gravity, dt=dt,
                 mode=mode, newton=newton, pins=pins, contact=contact, obstacles=obstacles, materials=materials)
