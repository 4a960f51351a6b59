"""The linear FEM baseline simulator: a scene's cloth as a flat triangle mesh.

Same incremental potential, projected Newton, CHOLMOD solver, assembly and contact as
sim/simulator.py (it subclasses Simulator and reuses its stepping, pins and contact), with
the energies discretised on linear triangles: FBW / StVK membrane with one point per
triangle (sim/linear/membrane.py), Bergou bending on interior edges, lumped masses
rho h A / 3 per vertex. Vertices are the unknowns, so W is the identity.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np
import scipy.sparse as sp

from garment.materials import Material

from ..energies import membrane_params
from ..newton import NewtonOptions
from ..pins import PinGroup
from ..simulator import Simulator
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


class LinearSimulator(Simulator):
    """Linear triangle FEM cloth; the stepping interface of Simulator.

    meshes / worlds / materials: one flat rest mesh, its initial world vertices (V, 3) and
    material per cloth; pins: groups of global vertex indices; the rest as Simulator.
    """

    def __init__(
        self,
        meshes: list[TriangleMesh],
        worlds: list[np.ndarray],
        materials: list[Material],
        pins: Iterable[PinGroup] = (),
        gravity=(0.0, 0.0, -9.81),
        pressure: float = 0.0,
        pressure_directions: list[np.ndarray] | None = None,
        dt: float = 0.01,
        mode: str = "dynamic",
        newton: NewtonOptions | None = None,
        contact=None,
        obstacles=(),
        names: list[str] | None = None,
    ):
        self.dt = float(dt)
        self.mode = mode
        self.newton = newton or NewtonOptions()
        self.newton.dt = self.dt
        self.pins = list(pins)
        offsets = np.cumsum([0] + [m.n_vertices for m in meshes])
        self.n_cp = int(offsets[-1])
        names = names or [f"cloth{k}" for k in range(len(meshes))]
        self.pieces = []
        for name, mesh, material, off in zip(names, meshes, materials, offsets):
            V = mesh.n_vertices
            W = sp.csr_matrix((np.ones(V), (np.arange(V), off + np.arange(V))), shape=(V, self.n_cp))
            topo = MeshTopology(name, mesh.faces.astype(np.int32), mesh.normalized, mesh.rest)
            self.pieces.append(LinearPiece(name, mesh, material, int(off), W, topo))

        self.areas = np.zeros(self.n_cp)
        self.mass = np.zeros(self.n_cp)
        forces = np.zeros((self.n_cp, 3))
        membranes: dict[str, list] = {}
        bend_parts, bend_D = [], []
        for k, piece in enumerate(self.pieces):
            mat, sl = piece.material, piece.slice
            self.areas[sl] = lumped_areas(piece.mesh)
            self.mass[sl] = mat.areal_density * self.areas[sl]
            pts = triangle_points(piece.mesh)
            pts.idx += piece.offset
            if mat.membrane != "none":
                membranes.setdefault(mat.membrane, []).append((pts, membrane_params(mat)))
            hinges = hinge_points(piece.mesh)
            hinges.idx += piece.offset
            bend_parts.append(hinges)
            bend_D.append(np.full(hinges.n_points, mat.bending_stiffness))
            d = pressure_directions[k] if pressure_directions is not None else np.array([0.0, 0.0, 1.0])
            forces[sl] += pressure * self.areas[sl, None] * np.asarray(d, float)[None, :]
        forces += self.mass[:, None] * np.asarray(gravity, float)[None, :]

        self._elastic_energies(mode, forces, bend_parts, bend_D, membranes)

        # No seams between linear cloths (Simulator's seam attributes, switched off).
        self.seams, self.seam, self.seam_ramp, self.seam_stiffness = [], None, 0.0, 0.0
        self.quasistatic_sewing, self.seam_multipliers = False, False

        self.C0 = np.concatenate([np.asarray(w, float) for w in worlds])
        self._finish(contact, obstacles, materials, gravity)

    @classmethod
    def from_scene(cls, scene, resolution=None, layout: str = "grid",
                   newton: NewtonOptions | None = None) -> "LinearSimulator":
        """Build from a garment.scene.Scene; each cloth becomes a `layout` mesh with
        `resolution` vertices per side (default: its control-point count), pins mapped
        to vertices by position."""
        from garment.io.obstacles import load_obstacle

        meshes, worlds = [], []
        for c in scene.cloths:
            mesh = cloth_mesh(c.size, resolution or c.control_points, layout)
            meshes.append(mesh)
            worlds.append(_world(c, mesh))
        offsets = np.cumsum([0] + [m.n_vertices for m in meshes])
        by_name = {c.name: k for k, c in enumerate(scene.cloths)}
        groups = []
        for pin in scene.pins:
            k = by_name[pin.cloth]
            local = select_vertices(meshes[k], pin.corners, pin.sides, pin.box, pin.depth)
            groups.append(PinGroup(local + offsets[k], np.asarray(pin.velocity, float), pin.start, pin.duration))
        load = scene.load
        directions = [np.asarray(load.pressure_direction, float) if load.pressure_direction is not None else c.normal
                      for c in scene.cloths]
        tm = scene.time
        opts = NewtonOptions.for_time(tm, newton)
        return cls(meshes, worlds, [c.material for c in scene.cloths], groups, load.gravity, load.pressure,
                   directions, tm.dt, tm.mode, opts, scene.contact, [load_obstacle(o) for o in scene.obstacles],
                   [c.name for c in scene.cloths])

    def control_points(self, name: str) -> np.ndarray:
        return self.C[self._piece(name).slice]


def _world(cloth, mesh: TriangleMesh) -> np.ndarray:
    """Initial world vertices of a scene cloth (garment.scene.ClothSpec) on `mesh`."""
    au = np.asarray(cloth.axis_u, float)
    av = np.asarray(cloth.axis_v, float)
    au, av = au / np.linalg.norm(au), av / np.linalg.norm(av)
    X = mesh.rest
    world = np.asarray(cloth.origin, float) + X[:, :1] * au + X[:, 1:] * av
    if cloth.perturbation is not None:
        st = mesh.normalized
        wu, wv = cloth.perturbation.waves
        wave = [np.sin(np.pi * w * x) if w else np.ones_like(x) for w, x in ((wu, st[:, 0]), (wv, st[:, 1]))]
        world += (cloth.perturbation.amplitude * wave[0] * wave[1])[:, None] * cloth.normal
    return world
