"""The time loop: model (what does not change) + state (what does), stepped by Newton.

Model: patches, quadrature tables, energies and the Hessian pattern, all built once.
State: control points C (n_cp, 3) in metres, velocities V (n_cp, 3) in m/s, time t in s.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np
import scipy.sparse as sp

from garment.errors import InputError
from garment.io.garments import load_garment
from garment.io.obstacles import load_obstacle
from garment.materials import Material
from garment.model import Patch
from garment.scene import ContactSpec

import ipctk

from . import quadrature
from .contact.drive import BodyDrive
from .contact.mesh import ContactMesh
from .contact.seams import SEWN, SeamContact
from .contact.stiffness import AdaptiveStiffness
from .embedding import default_resolution, grid_faces, interpolation_matrix, sample_grid
from .energies import MEMBRANES, BendingEnergy, ExternalForceEnergy, InertiaEnergy, membrane_params
from .energies.barrier import BarrierEnergy
from .energies.friction import FrictionEnergy
from .energies.seam import SeamEnergy
from .newton import NewtonOptions, minimize
from .pins import PinGroup, select
from .potential import IncrementalPotential
from .rest import PointData, point_data
from .seam_mesh import seam_meshes
from .seams import SeamSpec, excluded_pairs, nearest_pairs, seam_samples
from .sinks import Frame, MeshTopology, Sink
from .stats import StepStats

@dataclass
class Piece:
    """One simulated patch and its embedded output mesh."""

    name: str
    patch: Patch
    material: Material
    offset: int  # first global control-point index
    W: sp.csr_matrix  # (V, n_cp) vertex interpolation
    topology: MeshTopology

    @property
    def slice(self) -> slice:
        return slice(self.offset, self.offset + self.patch.n_control_points)


class Simulator:
    """B-spline cloth without contact.

    patches / materials: one material per patch. pins: groups of global control-point
    indices. gravity (3,) m/s^2; pressure in Pa along pressure_directions[k] for patch k.
    mode "dynamic" (implicit Euler) or "quasistatic" (static equilibrium per step; pins
    move by velocity * dt per step). seams: sim.seams.SeamSpec, held with seam_stiffness
    (N/m^2, one per seam or one for all), which ramps up over seam_ramp s (the sewing
    pre-roll), with velocities dropped after each of those steps if quasistatic_sewing;
    once sewn, seam_multipliers close the gaps that a penalty leaves (sim/energies/seam.py).
    With contact, sewn pieces' meshes carry matched seam vertices that merge into one
    contact vertex as each stretch of seam closes (sim/contact/seams.py), or,
    with contact.seams = "band", contact is off near every seam sample.
    """

    def __init__(
        self,
        patches: list[Patch],
        materials: list[Material],
        pins: Iterable[PinGroup] = (),
        gravity=(0.0, 0.0, -9.81),
        pressure: float = 0.0,
        pressure_directions: list[np.ndarray] | None = None,
        dt: float = 0.01,
        mode: str = "dynamic",
        newton: NewtonOptions | None = None,
        mesh_resolution: tuple[int, int] | None = None,
        contact=None,
        obstacles=(),
        seams=(),
        seam_stiffness: float | Sequence[float] = 1e6,
        seam_ramp: float = 0.0,
        quasistatic_sewing: bool = False,
        seam_multipliers: bool = True,
    ):
        self.dt = float(dt)
        self.mode = mode
        self.newton = newton or NewtonOptions()
        self.newton.dt = self.dt
        self.pins = list(pins)
        offsets = np.cumsum([0] + [p.n_control_points for p in patches])
        self.n_cp = int(offsets[-1])
        # Sewn pieces' meshes carry matched vertices along their seams (sim/seam_mesh.py).
        self.seams = list(seams)
        with_contact = contact is not None and contact.enabled
        density = (contact if contact is not None else ContactSpec()).mesh_density
        resolutions = {p.name: mesh_resolution or default_resolution(*p.shape, density) for p in patches}
        if with_contact and getattr(contact, "seams", "merge") == "band":
            sewn_meshes, matched, unmatched = {}, [], list(self.seams)  # all kept out of contact
        else:
            sewn_meshes, matched = seam_meshes({p.name: p.shape for p in patches}, resolutions, self.seams)
            unmatched = []
        self.pieces = []
        vertex_offset = {}
        n_vertices = 0
        for patch, material, off in zip(patches, materials, offsets):
            if patch.name in sewn_meshes:
                uv, faces = sewn_meshes[patch.name]
                u, v = uv[:, 0], uv[:, 1]
            else:
                u, v = sample_grid(*patch.shape, resolutions[patch.name])
                faces = grid_faces(*resolutions[patch.name])
            W = interpolation_matrix(u, v, *patch.shape, int(off), self.n_cp)
            rest = W[:, off:off + patch.n_control_points] @ patch.rest.reshape(-1, 2)
            topo = MeshTopology(patch.name, faces, np.c_[u, v], rest)
            self.pieces.append(Piece(patch.name, patch, material, int(off), W, topo))
            vertex_offset[patch.name] = n_vertices
            n_vertices += len(u)
        # Matched seam vertices (global cloth-vertex indices), merged once the seams close;
        # seams without them (band mode) keep contact off near each sample instead.
        seam_vertex_pairs = np.concatenate(
            [np.c_[va + vertex_offset[a], vb + vertex_offset[b]] for a, va, b, vb in matched]
            + [np.zeros((0, 2), np.int64)])
        seam_excluded = set()
        if with_contact and unmatched:
            seam_excluded = excluded_pairs(
                unmatched, {p.name: p for p in self.pieces}, vertex_offset,
                {p.name: p.topology.rest for p in self.pieces}, self.n_cp, self._rest_points())

        # Per-point rest data, concatenated over patches.
        membranes: dict[str, list] = {}
        bend_parts, bend_D, mass_parts, mass_rho = [], [], [], []
        for piece in self.pieces:
            n, m = piece.patch.shape
            mat = piece.material
            X = piece.patch.rest
            pm = point_data(X, quadrature.membrane_rule(mat.quadrature, n, m), piece.offset)
            if mat.membrane != "none":
                membranes.setdefault(mat.membrane, []).append((pm, membrane_params(mat)))
            pb = point_data(X, quadrature.bending_rule(mat.quadrature, n, m), piece.offset, second_order=True)
            bend_parts.append(pb)
            bend_D.append(np.full(pb.n_points, mat.bending_stiffness))
            pg = point_data(X, quadrature.gauss(n, m, 3), piece.offset)
            mass_parts.append(pg)
            mass_rho.append(np.full(pg.n_points, mat.areal_density))

        # Lumped masses m_a = int rho h N_a dX and nodal areas A_a = int N_a dX.
        pg = PointData.concatenate(mass_parts)
        rho_h = np.concatenate(mass_rho)
        ok = pg.idx >= 0
        wN = (pg.N * pg.w[:, None])[ok]
        self.areas = np.bincount(pg.idx[ok], wN, minlength=self.n_cp)
        self.mass = np.bincount(pg.idx[ok], (wN * np.broadcast_to(rho_h[:, None], pg.idx.shape)[ok]), minlength=self.n_cp)

        forces = self.mass[:, None] * np.asarray(gravity, float)[None, :]
        if pressure != 0.0:
            for k, piece in enumerate(self.pieces):
                d = pressure_directions[k] if pressure_directions is not None else np.array([0.0, 0.0, 1.0])
                forces[piece.slice] += pressure * self.areas[piece.slice, None] * np.asarray(d, float)[None, :]

        self._elastic_energies(mode, forces, bend_parts, bend_D, membranes)

        # Seams (sim/seams.py): one stiff quadratic energy over all matched samples.
        self.seam = None
        if self.seams:
            samples = seam_samples(self.seams, {p.name: p for p in self.pieces}, self.n_cp, self._rest_points())
            # One stiffness per seam (a scalar: all alike), spread over its samples.
            k = np.broadcast_to(np.asarray(seam_stiffness, float), (len(self.seams),))
            counts = [len(s.uv_a) for s in self.seams]
            self._seam_start = np.cumsum([0] + counts)  # seam k's samples: _seam_start[k]:_seam_start[k + 1]
            by_name = {p.name: p.material for p in self.pieces}
            max_step = [self.MULTIPLIER_STEP * by_name[s.piece_a].E_st * by_name[s.piece_a].h for s in self.seams]
            self.seam = SeamEnergy(samples, np.repeat(k, counts), np.repeat(max_step, counts))
            self._faces = self._pleat_faces()
            self.faces_released = np.zeros(len(self._faces), bool)  # latched: see _waiting_samples
            self.energies.append(self.seam)
            # Each sample pulls weakly while its nearest matched vertex pair is blocked (_hold_seams).
            rest_vertices = np.concatenate([p.topology.rest for p in self.pieces])
            self._sample_pair = nearest_pairs(
                samples.Na @ self._rest_points(), np.repeat(np.arange(len(self.seams)), counts),
                rest_vertices[seam_vertex_pairs[:, 0]], np.repeat(np.arange(len(matched)), [len(m[1]) for m in matched]))
        self.seam_ramp = float(seam_ramp)
        self.seam_stiffness = float(np.max(seam_stiffness))  # the ramp's end
        self.quasistatic_sewing = bool(quasistatic_sewing)
        self.seam_multipliers = bool(seam_multipliers)
        if self.seam is not None and self.seam_ramp > 0.0:
            self.seam.set_scale(self._seam_scale(self.dt))

        # Initial control points: the contact check starts here and pins move relative to them.
        self.C0 = np.concatenate([p.patch.world.reshape(-1, 3) for p in self.pieces])
        self._finish(contact, obstacles, materials, gravity, seam_vertex_pairs, seam_excluded)

    # ------------------------------------------------------------------ construction
    def _elastic_energies(self, mode, forces, bend_parts, bend_D, membranes) -> None:
        """Inertia (dynamic mode), loads, bending and membranes from per-point data
        (shared with sim.linear.LinearSimulator, whose points are triangles and hinges)."""
        self.energies = []
        self.inertia = None
        if mode == "dynamic":
            self.inertia = InertiaEnergy(self.mass, self.dt)
            self.energies.append(self.inertia)
        self.energies.append(ExternalForceEnergy(forces))
        self.energies.append(BendingEnergy(PointData.concatenate(bend_parts), np.concatenate(bend_D), self.n_cp))
        for model, parts in membranes.items():
            pts = PointData.concatenate([p for p, _ in parts])
            params = np.concatenate([np.tile(prm, (p.n_points, 1)) for p, prm in parts])
            self.energies.append(MEMBRANES[model](pts, params, self.n_cp))

    def _finish(self, contact, obstacles, materials, gravity, seam_vertex_pairs=None, seam_excluded=()) -> None:
        """Contact, pins, the incremental potential and the initial state, once the
        energies and C0 exist (shared with sim.linear.LinearSimulator). seam_vertex_pairs
        (P, 2), seam_excluded: see sim/contact/seams.py."""
        self.obstacles = list(obstacles)
        self.seam_contact = None
        self.barrier = None
        self.drive = None
        self.stiffness = None
        self.friction = None
        if contact is not None and contact.enabled:
            self.barrier = self._contact_energy(contact, seam_vertex_pairs, seam_excluded)
            self.energies.append(self.barrier)
            self.drive = BodyDrive(self.barrier.contact, self.obstacles)
            if contact.mu > 0.0:
                self.friction = FrictionEnergy(self.barrier, contact.mu, contact.eps_v, self.dt)
                self.energies.append(self.friction)
            if contact.adaptive_kappa:
                density = float(np.mean([m.areal_density for m in materials]))
                self.stiffness = AdaptiveStiffness(self.barrier, density, float(np.linalg.norm(gravity)), self.dt)

        self.pinned = np.zeros(self.n_cp, bool)
        for group in self.pins:
            self.pinned[group.indices] = True
        self.potential = IncrementalPotential(self.energies, ~self.pinned)
        self.potential.drive = self.drive
        if self.stiffness is not None:
            self.potential.on_iterate = self.stiffness.on_iterate

        # State.
        self.C = self.C0.copy()
        self.V = np.zeros_like(self.C)
        self.t = 0.0
        self.step_count = 0

    def _rest_points(self) -> np.ndarray:
        """(n_cp, 2) rest control points of all pieces, stacked."""
        return np.concatenate([p.patch.rest.reshape(-1, 2) for p in self.pieces])

    def _contact_energy(self, contact, seam_vertex_pairs, seam_excluded) -> BarrierEnergy:
        """IPC barrier on the pieces' embedded meshes and the obstacles, their seams
        merged as they close (sim/contact/seams.py)."""
        pairs = np.zeros((0, 2), np.int64) if seam_vertex_pairs is None else seam_vertex_pairs
        seams = self.seam_contact = SeamContact(self.pieces, pairs, seam_excluded, self.obstacles,
                                                contact.self_contact, self.keep_crossings)
        # Seams closed from the start (panels laid out edge to edge) start sewn.
        seams.state[seams.gaps(self.C0) < contact.dhat] = SEWN
        mesh, seams.labels = seams.mesh(self.C0, seams.state)
        self._set_piece_rows(mesh)
        x0 = mesh.vertices(self.C0)
        if ipctk.has_intersections(mesh.mesh, x0):
            raise InputError("the initial cloth intersects itself or an obstacle: move it apart before starting")
        barrier = BarrierEnergy(mesh, contact.dhat, contact.kappa)
        if len(seams.pairs):
            sewn, _ = seams.mesh(self.C0, np.full(len(seams.pairs), SEWN, np.int8))
            barrier.stencil_meshes = ((sewn.W, sewn.cloth_faces),)
        d = barrier.min_distance(self.C0)
        if d <= 0.0:
            raise InputError(f"the initial cloth touches an obstacle or itself (distance {d:g} m)")
        return barrier

    def _merge_seams(self, restore: np.ndarray | None = None) -> int:
        """Sew the contact mesh shut where the seams have closed (SeamContact.sew);
        `restore`: the pair states to put back (a checkpoint). Returns the pairs newly sewn."""
        if self.barrier is None or len(self.seam_contact.pairs) == 0:
            return 0
        fresh = self.seam_contact.sew(self.C, self.barrier, self._use_contact_mesh, restore)
        if fresh:
            self._set_piece_rows(self.barrier.contact)
        return fresh

    # Open seam pairs are tested for whether they could be sewn without a crossing once less
    # than this many d_hat apart (SeamContact.update_blocked): a pleat's blocked pairs sit
    # 0.4-1.5 mm apart.
    BLOCK_REACH = 10.0
    # A seam sewn onto a folded pleat (a waistband onto its face) pulls only once the
    # pleat's tucks are within PLEAT_WAIT of closed, or from PLEAT_WAIT_END on: pulled
    # earlier, the other panel comes down into the fold and its layers hold a tuck open
    # (README, "Folded pleats": the dress to t = 1.2 s, seam78 5.44 -> 0.80 mm; waiting
    # for 1 mm instead, panel11's last pleat never got there and held its face open).
    PLEAT_WAIT = 3e-3
    PLEAT_WAIT_END = 0.6

    def _hold_seams(self) -> int:
        """Pull weakly (SeamEnergy.HELD) the samples whose nearest matched pair is
        blocked, not at all those of seams still waiting for their pleat's tucks, fully
        the others. Returns the blocked pairs."""
        if self.seam is None:
            return 0
        held, blocked = np.zeros(self.seam.active.size, bool), 0
        if self.barrier is not None and len(self.seam_contact.pairs):
            reach = self.BLOCK_REACH * self.barrier.dhat
            pairs = self.seam_contact.update_blocked(self.C, self.barrier.contact, reach)
            held = np.append(pairs, False)[self._sample_pair]
            blocked = int(pairs.sum())
        waiting = self._waiting_samples()
        if self.seam.hold(~held & ~waiting, held & ~waiting):
            self.potential.refresh_constant()
        return blocked

    def _pleat_faces(self) -> list[tuple[np.ndarray, list[slice]]]:
        """Per seam that waits for a pleat: its samples on the pleat (within the tucks'
        span of parameters on that piece; a seam may run on past the pleat) and the
        tucks' sample ranges."""
        start = self._seam_start
        faces = []
        for k, s in enumerate(self.seams):
            if not s.after:
                continue
            piece = self.seams[s.after[0]].piece_a
            tuck_uv = np.concatenate([np.r_[self.seams[j].uv_a, self.seams[j].uv_b] for j in s.after])
            lo, hi = tuck_uv.min(axis=0) - 1e-6, tuck_uv.max(axis=0) + 1e-6
            uv = np.asarray(s.uv_a if s.piece_a == piece else s.uv_b, float)
            on = np.all((uv >= lo) & (uv <= hi), axis=1)
            faces.append((start[k] + np.flatnonzero(on), [slice(start[j], start[j + 1]) for j in s.after]))
        return faces

    def _waiting_samples(self) -> np.ndarray:
        """(S,) bool: samples on a pleat whose tucks have not yet closed to PLEAT_WAIT.
        Once they have, the seam pulls for good (faces_released, kept in checkpoints):
        without the face's pull a small pleat can spring back open and the wait restart."""
        waiting = np.zeros(self.seam.active.size, bool)
        if self.faces_released.all():
            return waiting
        gaps = self.seam.samples.gaps(self.C)
        for k, (samples, tucks) in enumerate(self._faces):
            if self.faces_released[k]:
                continue
            if self.t >= self.PLEAT_WAIT_END or all(gaps[t].max(initial=0.0) <= self.PLEAT_WAIT for t in tucks):
                self.faces_released[k] = True
            else:
                waiting[samples] = True
        return waiting

    def _set_piece_rows(self, mesh: ContactMesh) -> None:
        """Exported meshes follow the contact mesh (SeamContact.rows)."""
        rows, start = self.seam_contact.rows(mesh), 0
        for p in self.pieces:
            p.W = rows[start:start + p.W.shape[0]]
            start += p.W.shape[0]

    def _use_contact_mesh(self, mesh: ContactMesh) -> None:
        self.barrier.contact = mesh
        self.barrier.forget()
        self.barrier.bind(self.potential.pattern)
        if self.drive is not None:
            self.drive.mesh = mesh

    @classmethod
    def from_scene(cls, scene, newton: NewtonOptions | None = None) -> "Simulator":
        """Build from a validated garment.scene.Scene."""
        patches = [c.patch() for c in scene.cloths]
        offsets = np.cumsum([0] + [p.n_control_points for p in patches])
        by_name = {c.name: k for k, c in enumerate(scene.cloths)}
        groups = []
        for pin in scene.pins:
            k = by_name[pin.cloth]
            local = select(patches[k].shape, pin.corners, pin.sides, pin.box, pin.depth)
            groups.append(PinGroup(local + offsets[k], np.asarray(pin.velocity, float), pin.start, pin.duration))
        load = scene.load
        directions = [
            np.asarray(load.pressure_direction, float) if load.pressure_direction is not None else c.normal
            for c in scene.cloths
        ]
        materials = [c.material for c in scene.cloths]
        seams, stiffness = [], []
        for g in scene.garments:
            ps = load_garment(g)
            name = {p.name: f"{g.name}.{p.name}" for p in ps.patches}
            for p in ps.patches:
                patches.append(Patch(name[p.name], p.rest, p.world))
                materials.append(g.material)
                directions.append(np.array([0.0, 0.0, 1.0]))
            index = {s.name: len(seams) + k for k, s in enumerate(ps.seams)} if g.pleat_wait else {}
            seams += [SeamSpec(name[s.patch_a], s.uv_a, name[s.patch_b], s.uv_b, s.name,
                               tuple(index[a] for a in s.after if a in index)) for s in ps.seams]
            stiffness += [g.seam_stiffness] * len(ps.seams)
        tm = scene.time
        opts = NewtonOptions.for_time(tm, newton)
        obstacles = [load_obstacle(o) for o in scene.obstacles]
        # Pre-roll: bodies hold their first pose while the seams close; inset bodies grow
        # back in its second half, once the seams are sewn.
        sewn = 0.5 * tm.preroll if any(o.inset > 0.0 for o in scene.obstacles) else tm.preroll
        for o, spec in zip(obstacles, scene.obstacles):
            o.delay = tm.preroll
            o.inset, o.grow = spec.inset, (sewn, tm.preroll)
        sim = cls(
            patches, materials, groups, load.gravity, load.pressure,
            directions, tm.dt, tm.mode, opts, None if scene.garments else scene.output.mesh_resolution,
            scene.contact, obstacles, seams, stiffness or 1e6, sewn, tm.sewing == "quasistatic",
        )
        for c, piece in zip(scene.cloths, sim.pieces):
            sim.V[piece.slice] = np.asarray(c.velocity, float)
        return sim

    # ------------------------------------------------------------------ state access
    @property
    def n_dofs(self) -> int:
        return 3 * int((~self.pinned).sum())

    def pin_targets(self, t: float) -> np.ndarray:
        """(n_cp, 3) positions with every pinned point moved to its place at time t."""
        C = self.C.copy()
        for group in self.pins:
            C[group.indices] = self.C0[group.indices] + group.displacement(t)
        return C

    def seam_gaps(self) -> dict[str, float]:
        """Largest gap (m) of each seam, by name (seams without one: their index)."""
        if self.seam is None:
            return {}
        gaps, start = self.seam.samples.gaps(self.C), self._seam_start
        return {s.name or str(k): float(gaps[start[k]:start[k + 1]].max(initial=0.0)) for k, s in enumerate(self.seams)}

    def seam_pairs_held_open(self) -> int:
        """Matched seam vertex pairs that could not be sewn (SeamContact.held_open)."""
        return int(self.seam_contact.held_open().sum()) if self.seam_contact is not None else 0

    def control_points(self, name: str) -> np.ndarray:
        piece = self._piece(name)
        return self.C[piece.slice].reshape(*piece.patch.shape, 3)

    def velocities(self, name: str) -> np.ndarray:
        piece = self._piece(name)
        return self.V[piece.slice].reshape(*piece.patch.shape, 3)

    def positions(self, name: str | None = None) -> np.ndarray | dict[str, np.ndarray]:
        """Embedded mesh vertices (V, 3) of one piece, or a dict of all pieces."""
        if name is None:
            return {p.name: p.W @ self.C for p in self.pieces}
        return self._piece(name).W @ self.C

    def obstacle_positions(self) -> dict[str, np.ndarray]:
        """Current vertices (V, 3) of every obstacle, by name."""
        if self.drive is not None:
            return self.drive.positions()
        return {o.name: o.at(self.t) for o in self.obstacles}

    def _piece(self, name: str) -> Piece:
        for p in self.pieces:
            if p.name == name:
                return p
        raise KeyError(f"no cloth named {name!r}")

    # ------------------------------------------------------------------ stepping
    def set_dt(self, dt: float) -> None:
        """Change the time step (for step splitting): inertia, friction and Newton's
        step-size criterion follow; bodies and pins are functions of time already."""
        self.dt = float(dt)
        self.newton.dt = self.dt
        if self.inertia is not None:
            self.inertia.dt = self.dt
            # The inertia Hessian M / dt^2 is a constant term: rebuild the constant part.
            self.potential.refresh_constant()
        if self.friction is not None:
            self.friction.dt = self.dt

    # Seams stiffen geometrically over `seam_ramp` s from this stiffness (N/m^2): full-
    # strength springs across 26 cm gaps yank panels shut in one step (kN on grams of
    # cloth), which costs 100 Newton iterations and CCD-limited steps; weak springs close
    # them over the pre-roll, and the rising stiffness then holds them below 1 mm. The start
    # is absolute, not a fraction of k: it is what grams of cloth across open gaps can take.
    SEAM_RAMP_START = 10.0
    # A seam multiplier update (sim/energies/seam.py) adds at most this many times the
    # force per unit length the cloth carries at 100 % strain (E h; cotton 636 N/m).
    MULTIPLIER_STEP = 2.0
    # Tolerate (exclude from contact) cloth crossings in the initial state: only for states
    # handed over from a coarser run (garment/bench/garment.py), never for a scene's start.
    keep_crossings = False

    def _seam_scale(self, t: float) -> float:
        start = min(self.SEAM_RAMP_START / self.seam_stiffness, 1.0)
        return start ** max(1.0 - t / self.seam_ramp, 0.0)

    def step(self) -> StepStats:
        """Advance one time step (or one quasi-static load increment)."""
        start = _time.perf_counter()
        t_next = self.t + self.dt
        if self.seam is not None and self.seam_ramp > 0.0 and self.seam.scale < 1.0:
            self.seam.set_scale(self._seam_scale(t_next))
            self.potential.refresh_constant()
        stats = StepStats(step=self.step_count + 1, time=t_next)
        stats.extra["seam_pairs_sewn"] = float(self._merge_seams())
        stats.extra["seam_pairs_blocked"] = float(self._hold_seams())
        targets = self.pin_targets(t_next)
        # Predictor C + dt V: the inertia target in dynamics, the secant (last increment)
        # predictor in quasi-statics (wrinkle 20x47: 41 -> 33 Newton iterations per load step).
        C_hat = self.C + self.dt * self.V
        if self.inertia is not None:
            self.inertia.target = C_hat
        x0 = np.where(self.pinned[:, None], targets, C_hat)
        if self.barrier is not None:
            # The predictor must not tunnel through a barrier thinner than one step of
            # motion: move only the collision-free fraction of the way (CCD), bodies
            # included; Newton carries on with whatever body motion remains.
            if self.friction is not None:
                self.friction.lag(self.C)
            self.drive.set_time(t_next)
            C_start = np.where(self.pinned[:, None], targets, self.C)
            t_ccd = _time.perf_counter()
            alpha = self.potential.max_step(C_start, x0, self.drive.target if self.drive.pending else None)
            stats.t_ccd += _time.perf_counter() - t_ccd
            x0 = C_start + alpha * (x0 - C_start)
            self.drive.advance(alpha)
            if self.stiffness is not None:
                stats.extra["kappa"] = self.stiffness.update(self.potential, x0)
        C_new = minimize(self.potential, x0, self.newton, stats)
        if self.seam is not None:
            stats.extra["seam_gap_max"] = float(self.seam.samples.gaps(C_new).max(initial=0.0))
            if self.seam_multipliers and self.seam.scale >= 1.0:
                self.seam.update_multipliers(C_new)
        if self.barrier is not None:
            stats.extra["contact_count"] = float(self.barrier.n_collisions)
            stats.extra["min_distance"] = self.barrier.min_distance(C_new)
        self.V = (C_new - self.C) / self.dt
        if self.quasistatic_sewing and t_next < self.seam_ramp - 1e-9 * self.dt:
            # Pulled shut, not thrown: seams closing 30 cm gaps around a body would fling
            # the panels onto it, pinning them at 1e-5 m and stalling Newton (shirt_mean).
            self.V[:] = 0.0
        self.C = C_new
        self.t = t_next
        self.step_count += 1
        stats.t_total = _time.perf_counter() - start
        return stats

    def run(
        self,
        frames: int,
        steps_per_frame: int = 1,
        sinks: Iterable[Sink] = (),
        on_step: Callable[[StepStats], None] | None = None,
    ) -> list[StepStats]:
        """Write the initial frame, then `frames` frames of `steps_per_frame` steps each.

        Sinks are opened here and always closed, even when a step raises.
        """
        sinks = list(sinks)
        all_stats: list[StepStats] = []
        opened = []
        try:
            for s in sinks:
                s.open(self.topologies())
                opened.append(s)
            self._emit(sinks, 0, [])
            for k in range(1, frames + 1):
                steps = []
                for _ in range(steps_per_frame):
                    st = self.step()
                    steps.append(st)
                    if on_step is not None:
                        on_step(st)
                all_stats.extend(steps)
                self._emit(sinks, k, steps)
        finally:
            for s in opened:
                s.close()
        return all_stats

    def topologies(self) -> list[MeshTopology]:
        """Static mesh data for sinks: cloth pieces, then obstacles (kind "body")."""
        empty = np.zeros((0, 2))
        return [p.topology for p in self.pieces] + [
            MeshTopology(o.name, o.faces, empty, empty, kind="body") for o in self.obstacles]

    def _emit(self, sinks, index, steps):
        if sinks:
            positions = self.positions() | self.obstacle_positions()
            frame = Frame(index, self.t, positions, steps)
            for s in sinks:
                s.write(frame)

