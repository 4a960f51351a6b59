"""IPC log-barrier contact energy on the embedded meshes, mapped to control points.

B(C) = kappa sum_k w_k b(d_k(x)), x = W C (area-weighted, ipctk's convergent formulation),
with b the normalised clamped log barrier of activation distance dhat. ipctk supplies collisions,
distances and per-vertex derivatives; we map them to control points: grad_C = W^T grad_x,
H_C = W3^T H_x W3 (x is linear in C, so no second term). The collision set depends on x
and is rebuilt for every new C.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass

import ipctk
import numpy as np

from ..contact.hessian_map import ContactHessianMap
from ..contact.mesh import ContactMesh
from .contact import ContactEnergy

# Additive CCD warns on stderr about every pair it meets with a tiny gap (a seam's two sides
# touching at a corner); the line search handles what that costs, and the crossing check
# is the guard. Errors still print.
ipctk.set_logger_level(ipctk.LoggerLevel.error)

# A moving body stops this far (in d_hat) short of anything (ipctk then returns no step
# while a pair is closer still). A body's motion is prescribed, without the energy test,
# so against cloth that cannot give way (a strap tensioned by its seam) CCD let it close
# 90 % of the gap every step: 7e-9 m down to 1e-17 m in 8 sewing steps (jumpsuit_02), where
# the distance's round-off misleads CCD and the crossing check found cloth through the body.
# Stopped short, the body lags (reported as body_lag) and catches up once the cloth moves.
DRIVE_FLOOR = 1e-6

# m: how far a held-back body looks for cloth through ipctk's broad phase, which finds
# every pair within that reach (at the whole lag of a body held back, arms lowered onto
# trapped cloth while the body grew: 0.17 m behind, 41 s a step, dress_777_04, stop 68).
# Farther out a lower bound from the nearest cloth vertex serves (`_far_clearance`).
CLEARANCE_REACH = 0.01

# How far off the last CCD segment (in d_hat, and in its parameter) a point may lie and
# still use its broad phase: round-off of the line search's C + alpha p is ~1e-16 m.
ON_SEGMENT = 1e-6


# GARMENT_REPRODUCIBLE=1: the same run gives the same garment, bit for bit. ipctk builds
# collision sets and sums its potentials over them in parallel, in an order that changes
# from run to run, and the round-off grows into different garments: upper_garment_06's
# control points differ after its first step, jumpsuit_04 ended with its widest seam at
# 0.86 mm in one run and 1.003 mm in another. On one thread the order is fixed; CCD (a
# minimum over pairs) stays parallel. It costs dress_04 (20K DOFs) 13 % a Newton
# iteration (734 -> 828 ms, collision builds 7.1 -> 13.6 s over 72 iterations).
REPRODUCIBLE = os.environ.get("GARMENT_REPRODUCIBLE", "0") not in ("", "0")


@contextmanager
def in_order():
    """ipctk on one thread while inside, when GARMENT_REPRODUCIBLE is set."""
    if not REPRODUCIBLE:
        yield
        return
    threads = ipctk.get_num_threads()
    ipctk.set_num_threads(1)
    try:
        yield
    finally:
        ipctk.set_num_threads(threads)


class BarrierEnergy(ContactEnergy):

    def __init__(self, contact: ContactMesh, dhat: float, kappa: float, ccd_max_iterations: int = 1000):
        self.contact = contact
        self.dhat = float(dhat)
        # The normalised barrier -(d/dhat - 1)^2 ln(d/dhat) of Li et al. 2023 is
        # dimensionless, so kappa is a stress (Pa) as in the paper's table (1e5 Pa); the
        # plain clamped log barrier on squared distances scales with dhat^4 instead.
        # Unit stiffness inside ipctk and kappa applied here, so kappa can adapt per step.
        self.barrier = ipctk.NormalizedClampedLogBarrier()
        self.potential = ipctk.BarrierPotential(self.barrier, self.dhat, 1.0)
        self.kappa = float(kappa)
        self.collisions = self._new_collisions()
        # Additive CCD (Li et al. 2021): steps each pair forward by 0.9 of a lower bound on
        # its time of impact, so it needs a fixed few bytes a query and stays exact at the
        # 1e-7..1e-9 m gaps cloth reaches on a body. Tight Inclusion, conservative to its
        # 1e-6 m tolerance, returned far smaller steps there, and one of its interval
        # searches grew to 22.7 GB on a dress (docs/contact.md). ACCD is not provably
        # conservative under rounding; the independent crossing check guards every frame.
        # A bounded iteration count returns the time reached so far (a lower bound).
        self.ccd = ipctk.AdditiveCCD(ccd_max_iterations)
        # The collision sets at the last two points evaluated, newest first: [C, x,
        # collisions]. Two, because after a rejected trial (an extrapolated step, the
        # line search's last halving) Newton goes on from the point before it, whose
        # collision set would otherwise be rebuilt (the broad phase dominates the build).
        self._slots = []
        self._version = -1
        # The broad phase of the last CCD segment [C0, C0 + D] (max_step), its boxes
        # inflated as a build's: its candidates hold every pair within d_hat anywhere on
        # the segment, so the line search's trial points on it need only the narrow phase. A full build
        # (LBVH broad phase) took 31 ms on dress_04 (22K vertices), the narrow phase over
        # the segment's candidates 8 ms (same collisions, same potential to 13 digits).
        # Built at the second point tried on the segment: the first is often the only one
        # (a sewing step's CCD-shortened step, taken at once), and a plain build costs
        # no more than the segment's broad phase.
        self._segment: _Segment | None = None

    @staticmethod
    def _new_collisions():
        collisions = ipctk.NormalCollisions()
        collisions.use_area_weighting = True
        return collisions

    def forget(self) -> None:
        """Drop the cached collision sets (the contact mesh was replaced)."""
        self._slots = []
        self._segment = None

    def _update(self, C):
        """Collision-mesh vertices at C; `collisions` becomes the collision set there,
        rebuilt unless C is one of the last two points (and the obstacles have not moved)."""
        if self._version != self.contact.version:
            self._slots, self._version = [], self.contact.version
        for k, slot in enumerate(self._slots):
            if np.array_equal(slot[0], C):
                if k:
                    self._slots.reverse()
                    self.collisions, self._H_cb = slot[2], None
                return slot[1]
        collisions = self._slots.pop()[2] if len(self._slots) == 2 else self._new_collisions()
        x = self.contact.vertices(C)
        candidates = self._candidates_at(C)
        with in_order():  # the collisions' order is the order of the sums (REPRODUCIBLE)
            if candidates is None:
                collisions.build(self.contact.mesh, x, self.dhat)
            else:
                collisions.build(candidates, self.contact.mesh, x, self.dhat)
        self._slots.insert(0, [C.copy(), x, collisions])
        self.collisions, self._H_cb = collisions, None
        return x

    # More (W, cloth faces) whose triangles the Hessian pattern must hold: the contact
    # mesh the seams will sew shut (sim/simulator.py), whose seam vertices couple both
    # panels' control points.
    stencil_meshes: tuple = ()

    def stencils(self):
        """Control points under each cloth triangle: contacts against obstacles couple only
        these, so the Hessian pattern holds them (distant self-contact still falls outside
        and is moved onto the diagonal, see assembly.add_dof_matrix)."""
        return [_face_stencils(W, F) for W, F in ((self.contact.W, self.contact.cloth_faces), *self.stencil_meshes)]

    def bind(self, pattern):
        self.hmap = ContactHessianMap(self.contact.W, pattern)

    @property
    def n_collisions(self) -> int:
        return len(self.collisions)

    def n_collisions_at(self, C) -> int:
        self._update(C)
        return len(self.collisions)

    def value(self, C):
        x = self._update(C)
        with in_order():
            return self.kappa * float(self.potential(self.collisions, self.contact.mesh, x))

    def add_gradient(self, C, out):
        x = self._update(C)
        if len(self.collisions) == 0:
            return
        with in_order():
            g = self.contact.cloth_part(self.potential.gradient(self.collisions, self.contact.mesh, x))
        out += self.kappa * (self.contact.W3.T @ g).reshape(-1, 3)

    def _ipctk_hessian(self, C, method):
        x = self._update(C)
        if len(self.collisions) == 0:
            return None
        with in_order():
            return self.kappa * self.potential.hessian(self.collisions, self.contact.mesh, x, method)

    def _prepare(self, C):
        self._update(C)

    def max_step(self, C0, C1, B1=None, driven: bool = False) -> float:
        """Largest alpha in [0, 1] such that C0 -> C0 + alpha (C1 - C0) is collision free,
        with the obstacles moving linearly from where they are to B1 (if given) meanwhile;
        driven (the bodies' prescribed motion): and no pair closer than DRIVE_FLOOR d_hat."""
        x0, x1 = self.contact.vertices(C0), self.contact.vertices(C1, B1)
        floor = DRIVE_FLOOR * self.dhat if driven else 0.0
        # With the bodies moving too, trial points are off the cloth's segment.
        self._segment = None if B1 is not None else _Segment(C0.copy(), C1 - C0, x0, x1, self.contact.version)
        # CCD keeps its own broad phase: ACCD stops any candidate pair at a tenth of its
        # starting distance, so a set inflated by d_hat would shorten steps.
        return float(ipctk.compute_collision_free_stepsize(self.contact.mesh, x0, x1, floor, None, self.ccd))

    def _candidates_at(self, C):
        """The last CCD segment's candidates when C lies on that segment (to round-off),
        else None. A build inflates each box by d_hat / 2 (a pair's two boxes then meet
        within d_hat); the segment's carry the margin of a point off it by ON_SEGMENT d_hat."""
        seg = self._segment
        if seg is None or seg.version != self.contact.version:
            return None
        DD = float(np.vdot(seg.D, seg.D))
        if DD == 0.0:
            return None
        R = C - seg.C0
        t = float(np.vdot(R, seg.D)) / DD
        if not -ON_SEGMENT <= t <= 1.0 + ON_SEGMENT:
            return None
        R -= t * seg.D
        if float(np.abs(R).max(initial=0.0)) > ON_SEGMENT * self.dhat:
            return None
        seg.points += 1
        if seg.points == 1:  # the first point tried: a plain build
            return None
        if seg.candidates is None:
            seg.candidates = ipctk.Candidates()
            seg.candidates.build(self.contact.mesh, seg.x0, seg.x1, (0.5 + 2.0 * ON_SEGMENT) * self.dhat)
        return seg.candidates

    def body_clearance(self, C, reach: float) -> np.ndarray:
        """(Vo,) how far each obstacle vertex may move with the cloth held at C, keeping
        every pair DRIVE_FLOOR d_hat apart: its distance to the nearest cloth primitive
        within reach, less the floor (ipctk's per-vertex safe distances: a primitive moves
        no farther than its farthest-moving vertex, so a pair at distance d stays apart
        while each of its vertices moves less than d). Obstacle vertices outside the
        focused mesh (ContactMesh.focus) are beyond reach of the cloth."""
        floor = DRIVE_FLOOR * self.dhat
        reach = max(float(reach), 2.0 * floor)
        near = min(reach, CLEARANCE_REACH)
        x = self.contact.vertices(C)
        candidates = ipctk.Candidates()
        candidates.build(self.contact.mesh, x, near)
        safe = candidates.compute_per_vertex_safe_distances(self.contact.mesh, x, near, floor)
        body = np.ravel(safe)[self.contact.n_cloth:]
        if reach > near:  # farther out, a lower bound from the nearest cloth vertex will do
            body = np.minimum(np.maximum(body, self._far_clearance(x) - floor), reach - floor)
        out = np.full(len(self.contact.obstacle_vertices), reach - floor)
        if self.contact.body_ids is None:
            out[:] = body
        else:
            out[self.contact.body_ids] = body
        return np.maximum(out, 0.0)

    def _far_clearance(self, x: np.ndarray) -> np.ndarray:
        """(Vb,) a lower bound on the distance from each body vertex's triangles to the
        cloth at x: the distance to the nearest cloth vertex, less the longest cloth edge
        (a triangle lies within its longest edge of each of its vertices) and the vertex's
        longest edge (its own triangles reach no farther from it)."""
        from scipy.spatial import cKDTree

        n = self.contact.n_cloth
        edges = self.contact.mesh.edges
        length = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
        cloth = (edges < n).all(axis=1)
        own = np.zeros(len(x))
        np.maximum.at(own, edges[~cloth].ravel(), np.repeat(length[~cloth], 2))
        d, _ = cKDTree(x[:n]).query(x[n:])
        return d - length[cloth].max(initial=0.0) - own[n:]

    def min_distance(self, C) -> float:
        x = self._update(C)
        if len(self.collisions) == 0:
            return float("inf")
        return float(np.sqrt(self.collisions.compute_minimum_distance(self.contact.mesh, x)))


@dataclass
class _Segment:
    """The last CCD segment C0 -> C0 + D (contact vertices x0 -> x1) and its broad phase,
    built once a second point on it is tried (BarrierEnergy._candidates_at)."""

    C0: np.ndarray
    D: np.ndarray
    x0: np.ndarray
    x1: np.ndarray
    version: int  # the contact mesh's, when it was set
    candidates: ipctk.Candidates | None = None
    points: int = 0  # tried on it so far


def _face_stencils(W, faces) -> np.ndarray:
    """(F, 3 k) control points under each triangle (k: the most per vertex, -1 padded)."""
    W = W.tocsr()
    counts = np.diff(W.indptr)
    per_vertex = -np.ones((W.shape[0], max(int(counts.max(initial=0)), 1)), np.int64)
    rows = np.repeat(np.arange(W.shape[0]), counts)
    per_vertex[rows, np.arange(W.indices.size) - W.indptr[rows]] = W.indices
    return per_vertex[faces].reshape(len(faces), -1)
