"""What a simulation is, built once: pieces and their embedded meshes, lumped masses,
energies over one Hessian pattern, pins, seams and contact (Newton's Model in
shared/STYLE.md). What evolves lives in a State (sim/state.py); the stepper
(sim/stepper.py) advances a state on a model.

Components that keep part of the state between steps (the barrier's kappa, the seam
multipliers, the contact mesh's body vertices and sewn seam pairs) are loaded from a state
by `apply` and write it back by `record`, so a State always holds all of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence

import ipctk
import numpy as np
import scipy.sparse as sp

from . import quadrature
from .contact.drive import BodyDrive
from .contact.mesh import ContactMesh, crossing_parts, crossings_at, touching_parts, touching_vertices
from .contact.stiffness import AdaptiveStiffness
from .drag import Drag
from .embedding import default_resolution, grid_faces, interpolation_matrix, sample_grid
from .energies import MEMBRANES, BendingEnergy, ExternalForceEnergy, InertiaEnergy, membrane_params
from .energies.barrier import BarrierEnergy
from .energies.drawstring import DrawstringEnergy
from .energies.friction import FrictionEnergy
from .errors import InputError
from .materials import Material
from .newton import NewtonOptions
from .patches import Patch
from .pins import PinGroup
from .potential import IncrementalPotential
from .rest import PointData, point_data
from .seams.contact import OPEN, SEWN, SeamContact
from .seams.energy import SeamEnergy
from .seams.mesh import seam_meshes
from .seams.samples import excluded_pairs, nearest_pairs, seam_samples
from .seams.sewing import Sewing, SewingOptions
from .seams.spec import SeamSpec
from .sinks import MeshTopology
from .state import State

# Contact-mesh vertices per control point when a model is built without contact settings.
MESH_DENSITY = 2.0
# A start closer than this (in d_hat) is a contact no step can move cloth off: CCD allows
# none (dress_06's cut skirt front, its pieces 2.2e-17 m apart beside a dart tip, never moved).
TOUCH = 1e-6
# Open seam pairs closer than this (in d_hat) at the start may be sewn there to undo a
# crossing: two pieces of one cut panel whose fitted boundaries part by 1.35 mm.
NEAR_CUT = 4.0


@dataclass
class ContactOptions:
    """IPC contact: activation distance dhat (m), stiffness kappa (Pa; adaptive_kappa:
    chosen per step, sim/contact/stiffness.py), friction mu and eps_v (m/s), cloth
    self-contact; seams "merge" (closed seams share contact vertices) or "band" (contact
    off near every seam sample); mesh_density: contact-mesh vertices per control point."""

    enabled: bool = True
    dhat: float = 1e-3
    kappa: float = 1e5
    adaptive_kappa: bool = False
    mu: float = 0.0
    eps_v: float = 1e-3
    self_contact: bool = True
    seams: str = "merge"
    mesh_density: float = MESH_DENSITY


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

    def control_points(self, C: np.ndarray) -> np.ndarray:
        """(n, m, 3) this piece's control net in C."""
        return C[self.slice].reshape(*self.patch.shape, 3)


@dataclass
class Elastic:
    """Per-point data of the elastic energies and the loads, from either discretisation
    (B-spline patches here, linear triangles in sim/linear/model.py)."""

    mass: np.ndarray  # (n_cp,) kg, lumped
    areas: np.ndarray  # (n_cp,) m^2, lumped
    forces: np.ndarray  # (n_cp, 3) N, gravity and pressure
    bending: list[PointData]
    bending_D: list[np.ndarray]
    membranes: dict  # model name -> [(PointData, params)]


@dataclass
class SeamSetup:
    """The seams of a model: specs, their energy and each sample's nearest matched
    contact-vertex pair; vertex_pairs (P, 2) and excluded: see sim/seams/contact.py."""

    specs: list[SeamSpec]
    energy: SeamEnergy | None
    sample_pair: np.ndarray | None
    stiffness: float  # N/m^2, the ramp's end
    vertex_pairs: np.ndarray
    excluded: set


class Model:
    """pieces (offsets into one control-point array), elastic data, initial control
    points C0 (n_cp, 3); pins: groups of global indices; mode "dynamic" (implicit Euler)
    or "quasistatic" (static equilibrium per step); contact: ContactOptions or None;
    obstacles: garment bodies (anything with name, faces, vertices, at(t), animated);
    keep_crossings: exclude cloth crossings of the initial state from contact, only for
    states handed over from a coarser run (garment/bench/garment.py)."""

    def __init__(self, pieces, elastic: Elastic, C0: np.ndarray, *, gravity=(0.0, 0.0, -9.81),
                 dt: float = 0.01, mode: str = "dynamic", newton: NewtonOptions | None = None,
                 pins: Iterable[PinGroup] = (), contact: ContactOptions | None = None, obstacles=(),
                 seams: SeamSetup | None = None, sewing: SewingOptions | None = None,
                 keep_crossings: bool = False, materials: Sequence[Material] = (), drag: Drag = Drag()):
        self.pieces = list(pieces)
        self.n_cp = int(C0.shape[0])
        self.mass, self.areas = elastic.mass, elastic.areas
        self.dt = float(dt)
        self.mode = mode
        self.drag = drag  # the settling drag on the cloth's velocity (sim/drag.py)
        self.newton = newton or NewtonOptions()
        self.newton.dt = self.dt
        self.pins = list(pins)
        self.C0 = C0
        self.keep_crossings = keep_crossings
        self._elastic_energies(elastic)

        self.seams = seams.specs if seams is not None else []
        self.seam = seams.energy if seams is not None else None
        self.sewing = None
        if self.seam is not None:
            self.energies.append(self.seam)
            self.sewing = Sewing(self.seams, self.seam, seams.sample_pair, seams.stiffness, sewing or SewingOptions(),
                                 self.dt, self.C0)

        # An elastic band along an opening, drawn in by the caller (garment/dress/drawstring.py).
        self.drawstring = DrawstringEnergy(self.n_cp)
        self.energies.append(self.drawstring)

        self.obstacles = list(obstacles)
        self.seam_contact = self.barrier = self.drive = self.stiffness = self.friction = None
        self.cloth_motion = 0.0  # m: the last step's largest cloth-vertex motion (sets the contact reach)
        if contact is not None and contact.enabled:
            pairs = seams.vertex_pairs if seams is not None else np.zeros((0, 2), np.int64)
            excluded = seams.excluded if seams is not None else set()
            self.barrier = self._contact_energy(contact, pairs, excluded)
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

    def _elastic_energies(self, e: Elastic) -> None:
        """Inertia (dynamic mode), loads, bending and membranes."""
        self.energies = []
        self.inertia = None
        if self.mode == "dynamic":
            self.inertia = InertiaEnergy(self.mass, self.dt)
            self.energies.append(self.inertia)
        self.loads = ExternalForceEnergy(e.forces)
        self.energies.append(self.loads)
        self.energies.append(BendingEnergy(PointData.concatenate(e.bending), np.concatenate(e.bending_D), self.n_cp))
        for model, parts in e.membranes.items():
            pts = PointData.concatenate([p for p, _ in parts])
            params = np.concatenate([np.tile(prm, (p.n_points, 1)) for p, prm in parts])
            self.energies.append(MEMBRANES[model](pts, params, self.n_cp))

    def _contact_energy(self, contact: ContactOptions, seam_vertex_pairs, seam_excluded) -> BarrierEnergy:
        """IPC barrier on the pieces' embedded meshes and the obstacles, their seams
        merged as they close (sim/seams/contact.py)."""
        seams = self.seam_contact = SeamContact(self.pieces, seam_vertex_pairs, seam_excluded, self.obstacles,
                                                contact.self_contact, self.keep_crossings)
        # Seams closed from the start (panels laid out edge to edge) start sewn.
        seams.state[seams.gaps(self.C0) < contact.dhat] = SEWN
        mesh, seams.labels = seams.mesh(self.C0, seams.state)
        self._set_piece_rows(mesh)
        x0 = mesh.vertices(self.C0)
        if ipctk.has_intersections(mesh.mesh, x0):
            mesh = self._sew_crossing(seams, mesh, x0, contact.dhat)
            x0 = mesh.vertices(self.C0)
        barrier = BarrierEnergy(mesh, contact.dhat, contact.kappa)
        if len(seams.pairs):
            sewn, _ = seams.mesh(self.C0, np.full(len(seams.pairs), SEWN, np.int8))
            barrier.stencil_meshes = ((sewn.W, sewn.cloth_faces),)
        d = barrier.min_distance(self.C0)
        if 0.0 < d < TOUCH * contact.dhat and self._sew_touching(seams, barrier, x0, d):
            d = barrier.min_distance(self.C0)
        if d <= 0.0:
            raise InputError(f"the initial cloth touches an obstacle or itself (distance {d:g} m)")
        if d < TOUCH * contact.dhat:
            raise InputError(self._touching_report(barrier.contact, barrier.contact.vertices(self.C0), contact.dhat))
        return barrier

    def _sew_crossing(self, seams: SeamContact, mesh: ContactMesh, x: np.ndarray, dhat: float) -> ContactMesh:
        """The start mesh with the open seam pairs on crossing elements sewn, when that
        leaves nothing crossing; else the crossing error. The same start as in
        _sew_touching: the unsewn vertex lies in the other piece's plane, and round-off
        reads it as touching or as crossing (dress_06 on numpy 2.4: four coplanar
        crossings, 1e-17 m off the plane). Only pairs within NEAR_CUT d_hat: pieces
        of one panel, not a seam still to be closed."""
        near = crossings_at(mesh.mesh, x, mesh.n_cloth, np.arange(mesh.n_cloth))
        tried = self._sewn_at(seams, mesh, near, seams.gaps(self.C0) < NEAR_CUT * dhat)
        if tried is None:
            raise InputError(self._crossing_report(mesh, x))
        sewn, state, labels = tried
        seams.state, seams.labels = state, labels
        self._set_piece_rows(sewn)
        return sewn

    def _sewn_at(self, seams: SeamContact, mesh: ContactMesh, vertices: np.ndarray, allowed: np.ndarray):
        """(mesh, state, labels) with the open, `allowed` seam pairs that have a side among
        `vertices` (of `mesh`) sewn, or None when there are none or the result crosses."""
        fix = (seams.state == OPEN) & allowed & np.isin(seams.labels[seams.pairs], vertices).any(axis=1)
        if not fix.any():
            return None
        state = seams.state.copy()
        state[fix] = SEWN
        sewn, labels = seams.mesh(self.C0, state, like=mesh)
        if ipctk.has_intersections(sewn.mesh, sewn.vertices(self.C0)):
            return None
        return sewn, state, labels

    def _sew_touching(self, seams: SeamContact, barrier: BarrierEnergy, x: np.ndarray, before: float) -> bool:
        """Start sewn the open seam pairs that touch other cloth at round-off: pieces cut
        from one panel lie edge to edge, and where their fitted boundaries part by a
        little more than d_hat (dress_06's skirt front, 1.35 mm beside a dart tip) the
        unsewn vertex lies on the other piece's boundary, in its plane (2e-17 m). Sewn
        shut, the two sides share one vertex. Returns whether the mesh changed (kept only
        when nothing crosses and nothing touches closer than before). x: the contact
        mesh's vertices at the start; before: its closest distance."""
        mesh = barrier.contact
        near = touching_vertices(mesh, x, barrier.dhat, TOUCH * barrier.dhat)
        tried = self._sewn_at(seams, mesh, near, True)
        if tried is None:
            return False
        sewn, state, labels = tried
        barrier.contact = sewn
        barrier.forget()
        if barrier.min_distance(self.C0) <= before:
            barrier.contact = mesh
            barrier.forget()
            return False
        seams.state, seams.labels = state, labels
        self._set_piece_rows(sewn)
        return True

    def _part_name(self, k: int) -> str:
        """Cloth piece k >= 0 or obstacle -1 - k (crossing_parts, touching_parts)."""
        return self.pieces[k].name if k >= 0 else f"obstacle {self.obstacles[-1 - k].name!r}"

    def _touching_report(self, mesh: ContactMesh, x: np.ndarray, dhat: float, most: int = 3) -> str:
        """The error for a start closer than round-off, naming the parts and where."""
        name = self._part_name
        found = sorted(touching_parts(mesh, x, dhat, TOUCH * dhat).items(), key=lambda kv: kv[1][1])
        parts = [f"{name(a)} {'itself' if a == b else 'and ' + name(b)} ({n} pairs, {d:.2g} m at "
                 f"({w[0]:.3f}, {w[1]:.3f}, {w[2]:.3f}) m)" for (b, a), (n, d, w) in found[:most]]
        return ("the initial cloth touches itself or an obstacle at a distance of round-off, where no step can "
                "move it off: " + ", ".join(parts) + ". Move them apart before starting (two pieces of one "
                "panel cut at conform time: their outlines overlap at the cut's end)")

    def _crossing_report(self, mesh: ContactMesh, x: np.ndarray, most: int = 5) -> str:
        """The initial-intersection error, naming the parts that cross and how much."""
        name = self._part_name

        counts = sorted(crossing_parts(mesh, x).items(), key=lambda kv: -kv[1])
        if not counts:
            return "the initial cloth intersects itself or an obstacle: move it apart before starting"
        parts = [f"{name(a)} through itself ({n} edges)" if a == b else
                 f"{name(max(a, b))} and {name(min(a, b))} ({n} edges)" if a < 0 else f"{name(a)} and {name(b)} ({n} edges)"
                 for (a, b), n in counts[:most]]
        more = f", and {len(counts) - most} more pairs" if len(counts) > most else ""
        return ("the initial cloth intersects itself or an obstacle: " + ", ".join(parts) + more
                + ". Move them apart before starting (a garment: check its panels' placement or the body's "
                  "scale, up axis and translate)")

    # ------------------------------------------------------------------ state
    def initial_state(self, V0: np.ndarray | None = None) -> State:
        """The state at t = 0: C0 at rest (or moving with V0), the components' start."""
        V = np.zeros_like(self.C0) if V0 is None else np.asarray(V0, float).copy()
        state = State(self.C0.copy(), V, 0.0, 0, self.dt)
        self.record(state)
        return state

    def record(self, state: State) -> None:
        """Write the components' part of the state into `state`."""
        state.projection_backoff = tuple(int(x) for x in self.potential.projection_backoff)
        if self.barrier is not None:
            state.obstacle_vertices = self.barrier.contact.obstacle_vertices.copy()
            state.kappa = float(self.barrier.kappa)
        if self.drive is not None:
            state.drive_target = self.drive.target.copy()
        if self.stiffness is not None:
            state.stiffness_floor = float(self.stiffness.floor)
            state.stiffness_prev_d = float(self.stiffness.prev_d)
        if self.seam is not None:
            state.seam_multipliers = self.seam.multipliers.copy()
            state.seam_gaps = self.seam.last_gaps.copy()
            state.seam_level_pushes = self.seam.level_pushes.copy()
            state.seam_pushed_gaps = self.seam.pushed_gaps.copy()
            state.seam_low_gaps = self.seam.low_gaps.copy()
            if self.seam_contact is not None:
                state.seam_pairs = self.seam_contact.state.copy()
            if state.pleat_faces is None:
                state.pleat_faces = np.zeros(len(self.sewing.faces), bool)

    def apply(self, state: State) -> None:
        """Load the components' part of `state` (a state of this model)."""
        if state.C.shape != self.C0.shape:
            raise ValueError(f"state has {state.C.shape[0]} control points, the model {self.n_cp}")
        if self.dt != state.dt:
            self.set_dt(state.dt)
        self.potential.projection_backoff = tuple(state.projection_backoff)
        if self.barrier is not None and state.obstacle_vertices is not None:
            # Bodies moved elsewhere bump the mesh version, so cached contact sets expire
            # (left where they are, the sets still hold: they are keyed by C).
            self.barrier.contact.move_obstacles(np.array(state.obstacle_vertices, float))
            self.barrier.kappa = state.kappa
        if self.drive is not None and state.drive_target is not None:
            self.drive.target = np.array(state.drive_target, float)
        if self.stiffness is not None and state.stiffness_floor is not None:
            self.stiffness.floor = state.stiffness_floor
            self.stiffness.prev_d = state.stiffness_prev_d
        if self.seam is not None and state.seam_multipliers is not None:
            self.seam.multipliers = np.array(state.seam_multipliers, float)
            if state.seam_gaps is not None:
                self.seam.last_gaps = np.array(state.seam_gaps, float)
            if state.seam_level_pushes is not None:
                self.seam.level_pushes = np.array(state.seam_level_pushes, np.int64)
            if state.seam_pushed_gaps is not None:
                self.seam.pushed_gaps = np.array(state.seam_pushed_gaps, float)
            if state.seam_low_gaps is not None:
                self.seam.low_gaps = np.array(state.seam_low_gaps, float)
        if self.sewing is not None and state.pleat_faces is None:
            state.pleat_faces = np.zeros(len(self.sewing.faces), bool)
        if state.seam_pairs is not None:  # also back to fewer merged pairs (a retried step)
            self.merge_seams(state.C, restore=state.seam_pairs)

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

    # ------------------------------------------------------------------ seams in contact
    def merge_seams(self, C: np.ndarray, restore: np.ndarray | None = None) -> int:
        """Sew the contact mesh shut where the seams have closed (SeamContact.sew);
        `restore`: the pair states to put back (a state). Returns the pairs newly sewn."""
        if self.barrier is None or len(self.seam_contact.pairs) == 0:
            return 0
        fresh = self.seam_contact.sew(C, self.barrier, self._use_contact_mesh, restore)
        if fresh:
            self._set_piece_rows(self.barrier.contact)
        return fresh

    def blocked_pairs(self, C: np.ndarray) -> np.ndarray | None:
        """(P,) matched pairs that cannot be sewn now (SeamContact.update_blocked), or
        None without contact seams."""
        if self.barrier is None or len(self.seam_contact.pairs) == 0:
            return None
        return self.seam_contact.update_blocked(C, self.barrier.contact, self._block_reach())

    def held_pairs(self, C: np.ndarray) -> np.ndarray | None:
        """(P,) blocked pairs the seams pull only weakly (SeamContact.to_hold), or None
        without contact seams; after blocked_pairs."""
        if self.barrier is None or len(self.seam_contact.pairs) == 0:
            return None
        return self.seam_contact.to_hold(C, self.barrier.contact, self._block_reach())

    def _block_reach(self) -> float:
        return self.sewing.options.block_reach * self.barrier.dhat

    def screened_samples(self, C: np.ndarray) -> np.ndarray | None:
        """(S,) seam samples whose path passes through other cloth during the ramp
        (Sewing.screened), or None without contact or at full stiffness."""
        if self.barrier is None or self.sewing is None or self.sewing.energy.scale >= 1.0:
            return None  # Sewing.screened would say so; this skips building its inputs
        mesh = self.barrier.contact
        if mesh.piece_ids is None:
            return None
        face_piece = mesh.piece_ids[mesh.cloth_faces[:, 0]]
        index = {p.name: k for k, p in enumerate(self.pieces)}
        return self.sewing.screened(C, mesh.vertices(C)[:mesh.n_cloth], mesh.cloth_faces, face_piece, index)

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

    # ------------------------------------------------------------------ queries
    @property
    def n_dofs(self) -> int:
        return 3 * int((~self.pinned).sum())

    def pin_targets(self, C: np.ndarray, t: float) -> np.ndarray:
        """(n_cp, 3) C with every pinned point moved to its place at time t."""
        C = C.copy()
        for group in self.pins:
            C[group.indices] = self.C0[group.indices] + group.displacement(t)
        return C

    def piece(self, name: str) -> Piece:
        for p in self.pieces:
            if p.name == name:
                return p
        raise KeyError(f"no cloth named {name!r}")

    def topologies(self) -> list[MeshTopology]:
        """Static mesh data for sinks: cloth pieces, then obstacles (kind "body")."""
        empty = np.zeros((0, 2))
        return [p.topology for p in self.pieces] + [
            MeshTopology(o.name, o.faces, empty, empty, kind="body") for o in self.obstacles]


def bspline_model(patches: list[Patch], materials: list[Material], pins: Iterable[PinGroup] = (),
                  gravity=(0.0, 0.0, -9.81), pressure: float = 0.0, pressure_directions=None,
                  dt: float = 0.01, mode: str = "dynamic", newton: NewtonOptions | None = None,
                  mesh_resolution: tuple[int, int] | None = None, contact: ContactOptions | None = None,
                  obstacles=(), seams: Sequence[SeamSpec] = (), seam_stiffness: float | Sequence[float] = 1e6,
                  sewing: SewingOptions | None = None, keep_crossings: bool = False, drag: Drag = Drag()) -> Model:
    """The paper's B-spline cloth: one material per patch; pressure in Pa along
    pressure_directions[k] for patch k; seams held with seam_stiffness (N/m^2, one per
    seam or one for all). With contact, sewn pieces' meshes carry matched seam vertices
    that merge into one contact vertex as each stretch of seam closes
    (sim/seams/contact.py), or with contact.seams = "band", contact is off near every
    seam sample."""
    offsets = np.cumsum([0] + [p.n_control_points for p in patches])
    n_cp = int(offsets[-1])
    seams = list(seams)
    with_contact = contact is not None and contact.enabled
    density = contact.mesh_density if contact is not None else MESH_DENSITY
    resolutions = {p.name: mesh_resolution or default_resolution(*p.shape, density) for p in patches}
    if with_contact and contact.seams == "band":
        sewn_meshes, matched, unmatched = {}, [], list(seams)  # all kept out of contact
    else:
        sewn_meshes, matched = seam_meshes({p.name: p.shape for p in patches}, resolutions, seams,
                                           {p.name: p.rest for p in patches})
        unmatched = []
    pieces, vertex_offset, n_vertices = [], {}, 0
    for patch, material, off in zip(patches, materials, offsets):
        if patch.name in sewn_meshes:
            uv, faces = sewn_meshes[patch.name]
            u, v = uv[:, 0], uv[:, 1]
        else:
            u, v = sample_grid(*patch.shape, resolutions[patch.name])
            faces = grid_faces(*resolutions[patch.name])
        W = interpolation_matrix(u, v, *patch.shape, int(off), n_cp)
        rest = W[:, off:off + patch.n_control_points] @ patch.rest.reshape(-1, 2)
        pieces.append(Piece(patch.name, patch, material, int(off), W, MeshTopology(patch.name, faces, np.c_[u, v], rest)))
        vertex_offset[patch.name] = n_vertices
        n_vertices += len(u)
    rest_points = np.concatenate([p.patch.rest.reshape(-1, 2) for p in pieces])
    # Matched seam vertices (global cloth-vertex indices), merged once the seams close;
    # seams without them (band mode) keep contact off near each sample instead.
    seam_vertex_pairs = np.concatenate(
        [np.c_[va + vertex_offset[a], vb + vertex_offset[b]] for a, va, b, vb in matched]
        + [np.zeros((0, 2), np.int64)])
    seam_excluded = set()
    if with_contact and unmatched:
        seam_excluded = excluded_pairs(unmatched, {p.name: p for p in pieces}, vertex_offset,
                                       {p.name: p.topology.rest for p in pieces}, n_cp, rest_points)

    # Per-point rest data, concatenated over patches.
    membranes: dict[str, list] = {}
    bend_parts, bend_D, mass_parts, mass_rho = [], [], [], []
    for piece in pieces:
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
    areas = np.bincount(pg.idx[ok], wN, minlength=n_cp)
    mass = np.bincount(pg.idx[ok], (wN * np.broadcast_to(rho_h[:, None], pg.idx.shape)[ok]), minlength=n_cp)

    forces = mass[:, None] * np.asarray(gravity, float)[None, :]
    if pressure != 0.0:
        for k, piece in enumerate(pieces):
            d = pressure_directions[k] if pressure_directions is not None else np.array([0.0, 0.0, 1.0])
            forces[piece.slice] += pressure * areas[piece.slice, None] * np.asarray(d, float)[None, :]
    elastic = Elastic(mass, areas, forces, bend_parts, bend_D, membranes)

    setup = None
    if seams:
        sewing = sewing or SewingOptions()
        samples = seam_samples(seams, {p.name: p for p in pieces}, n_cp, rest_points)
        # One stiffness per seam (a scalar: all alike), spread over its samples.
        k = np.broadcast_to(np.asarray(seam_stiffness, float), (len(seams),))
        counts = [len(s.uv_a) for s in seams]
        by_name = {p.name: p.material for p in pieces}
        max_step = [sewing.multiplier_step * by_name[s.piece_a].E_st * by_name[s.piece_a].h for s in seams]
        energy = SeamEnergy(samples, np.repeat(k, counts), np.repeat(max_step, counts), sewing.held_fraction)
        # Each sample pulls weakly while its nearest matched vertex pair is blocked (Sewing.hold).
        rest_vertices = np.concatenate([p.topology.rest for p in pieces])
        sample_pair = nearest_pairs(
            samples.Na @ rest_points, np.repeat(np.arange(len(seams)), counts),
            rest_vertices[seam_vertex_pairs[:, 0]], np.repeat(np.arange(len(matched)), [len(m[1]) for m in matched]))
        setup = SeamSetup(seams, energy, sample_pair, float(np.max(seam_stiffness)), seam_vertex_pairs, seam_excluded)

    # Initial control points: the contact check starts here and pins move relative to them.
    C0 = np.concatenate([p.patch.world.reshape(-1, 3) for p in pieces])
    return Model(pieces, elastic, C0, gravity=gravity, dt=dt, mode=mode, newton=newton, pins=pins,
                 contact=contact, obstacles=obstacles, seams=setup, sewing=sewing,
                 keep_crossings=keep_crossings, materials=materials, drag=drag)
