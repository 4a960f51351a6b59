"""Contact-Hessian assembly cost in dense contact (docs/design.md sections 5 and 8).

The sphere scene's sheet is placed draped over the sphere and the ground, every contact
vertex within dhat/2 of an obstacle: a state with one collision per contact vertex or
more. On the same collisions we time ipctk's barrier Hessian (with the CLAMP projection
the simulator uses, and without) and three ways of mapping it to control points and into
the solver's fixed pattern:

- ours: sim.contact.hessian_map (parallel, straight into the pattern's data);
- triplets: 81 COO triplets per vertex-Hessian entry, summed by scipy, then merged with
  assembly.add_dof_matrix (the paper's baseline A);
- scipy: W3^T H W3 with scipy products, then add_dof_matrix (the simulator's current path);
- to_full_dof: ipctk's own mapping through a CollisionMesh built with the displacement
  map (not merged into the pattern, so its time is a lower bound).

It also times ipctk's per-collision Python API (local Hessian without projection), the
only way to get local Hessians to project them ourselves without reimplementing them.
"""

from __future__ import annotations

import time

import ipctk
import numpy as np
import scipy.sparse as sp

from sim.assembly import add_dof_matrix
from sim.contact.hessian_map import ContactHessianMap
from garment.build import build_simulator
from sim.simulator import Simulator

from .common import scene

COLUMNS = ("resolution", "contact_vertices", "collisions", "hessian_seconds", "ours_seconds",
           "triplet_seconds", "to_full_dof_seconds", "triplet_ratio", "to_full_dof_ratio", "max_rel_diff")

GAP = 0.5e-3  # metres above the obstacles: inside dhat = 1 mm


def draped(sim: Simulator) -> np.ndarray:
    """Control points of the sheet draped over the sphere (a cap, a 45 degree cone down
    to the ground, then flat), GAP above the obstacles. Over the convex cap the spline
    lies below its control net and the mesh's chords below the spline, so the cap radius
    is raised once by the measured vertex sag plus the chord sag L^2 / 8R."""
    C0 = sim.model.C0
    centre, R = np.array([0.0, 0.0, 0.15]), 0.15
    r = np.hypot(C0[:, 0], C0[:, 1])

    def shape(Rs):
        rt, zt = Rs * np.sin(np.pi / 4), centre[2] + Rs * np.cos(np.pi / 4)
        z = np.where(r < rt, centre[2] + np.sqrt(np.maximum(Rs**2 - r**2, 0.0)), zt - (r - rt))
        return np.c_[C0[:, :2], np.maximum(z, 0.0) + GAP]

    def clearance(C):
        x = sim.model.barrier.contact.W @ C
        return (np.linalg.norm(x - centre, axis=1) - R).min()

    faces = sim.model.barrier.contact.cloth_faces
    x = sim.model.barrier.contact.W @ C0
    L = np.linalg.norm(x[faces] - x[np.roll(faces, 1, axis=1)], axis=2).max()
    target = GAP + L**2 / (8 * R)
    C = shape(R + target)
    return shape(R + 2 * target - clearance(C))


def best(f, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def triplets(W: sp.csr_matrix, free: np.ndarray, H: sp.spmatrix, n_cloth: int) -> sp.csr_matrix:
    """W^T H W on the free DOFs from 81 triplets per scalar entry of the cloth part of H."""
    H = H.tocoo()
    keep = (H.row < 3 * n_cloth) & (H.col < 3 * n_cloth)
    R, Cc, h = H.row[keep], H.col[keep], H.data[keep]
    counts = np.diff(W.indptr)
    K = counts.max()
    sup = np.zeros((n_cloth, K), np.int64)
    w = np.zeros((n_cloth, K))
    rows = np.repeat(np.arange(n_cloth), counts)
    slot = np.arange(W.indices.size) - W.indptr[rows]
    sup[rows, slot], w[rows, slot] = free[W.indices], W.data
    u, v = R // 3, Cc // 3
    ti = 3 * sup[u][:, :, None] + (R % 3)[:, None, None]
    tj = 3 * sup[v][:, None, :] + (Cc % 3)[:, None, None]
    tv = w[u][:, :, None] * w[v][:, None, :] * h[:, None, None]
    ti, tj = np.broadcast_to(ti, tv.shape), np.broadcast_to(tj, tv.shape)
    ok = (ti >= 0) & (tj >= 0) & (tv != 0.0)  # pinned points have free index -1
    n = 3 * (int(free.max()) + 1)
    return sp.csr_matrix((tv[ok], (ti[ok], tj[ok])), shape=(n, n))


def case(n: int, repeat: int = 3) -> dict:
    sim = build_simulator(scene("sphere", (n, n)))
    e = sim.model.barrier
    mesh = e.contact
    pattern = sim.model.potential.pattern
    C = draped(sim)
    x = mesh.vertices(C)
    if ipctk.has_intersections(mesh.mesh, x):
        raise RuntimeError("draped sheet intersects an obstacle")
    e.collisions.build(mesh.mesh, x, e.dhat)
    CLAMP, NONE = ipctk.PSDProjectionMethod.CLAMP, ipctk.PSDProjectionMethod.NONE
    H = e.potential.hessian(e.collisions, mesh.mesh, x, CLAMP)
    t_hess = best(lambda: e.potential.hessian(e.collisions, mesh.mesh, x, CLAMP), repeat)
    t_hess0 = best(lambda: e.potential.hessian(e.collisions, mesh.mesh, x, NONE), repeat)

    t_local = _local_api_seconds(e, x)

    cmap = ContactHessianMap(mesh.W, pattern)
    data = np.zeros(pattern.nnz)
    cmap.add(H, data)  # compile / warm up

    def ours():
        data[:] = 0.0
        cmap.add(H, data)

    t_ours = best(ours, 2 * repeat + 1)

    ref = np.zeros(pattern.nnz)
    sel = _selector(pattern.free)

    def scipy_path():
        ref[:] = 0.0
        HC = mesh.W3.T @ H[: 3 * mesh.n_cloth, : 3 * mesh.n_cloth] @ mesh.W3
        add_dof_matrix(pattern, sel @ HC @ sel.T, ref)

    t_scipy = best(scipy_path, repeat)
    trip = np.zeros(pattern.nnz)

    def triplet_path():
        trip[:] = 0.0
        add_dof_matrix(pattern, triplets(mesh.W, pattern.free, H, mesh.n_cloth), trip)

    t_trip = best(triplet_path, repeat)

    # ipctk's mapping: full DOFs = control points, then the (static) obstacle vertices.
    n_obs = mesh.obstacle_vertices.shape[0]
    Wfull = sp.block_diag([mesh.W, sp.identity(n_obs)], format="csc")
    full_mesh = ipctk.CollisionMesh(np.asfortranarray(x), mesh.mesh.edges, mesh.mesh.faces, Wfull)
    full_mesh.to_full_dof(H)
    t_full = best(lambda: full_mesh.to_full_dof(H), repeat)

    scale = np.abs(ref).max()
    return {
        "resolution": n, "dofs": pattern.n_dofs, "contact_vertices": mesh.n_cloth,
        "collisions": len(e.collisions), "colors": cmap.n_colors,
        "hessian_seconds": t_hess, "hessian_noproj_seconds": t_hess0,
        "local_api_us_per_collision": 1e6 * t_local,
        "ours_seconds": t_ours, "triplet_seconds": t_trip, "scipy_seconds": t_scipy,
        "to_full_dof_seconds": t_full,
        "triplet_ratio": t_trip / t_ours, "scipy_ratio": t_scipy / t_ours, "to_full_dof_ratio": t_full / t_ours,
        "max_rel_diff": float(max(np.abs(data - ref).max(), np.abs(trip - ref).max()) / scale),
        "moved_entries": cmap.moved_entries,
    }


def _local_api_seconds(e, x, sample: int = 1000) -> float:
    """Seconds per collision to fetch one unprojected local Hessian and its vertex ids
    through ipctk's per-collision Python API (the route to projecting them ourselves)."""
    E, F = e.contact.mesh.edges, e.contact.mesh.faces
    c = e.collisions
    items = [k for group in (c.fv_collisions, c.ee_collisions, c.ev_collisions, c.vv_collisions, c.pv_collisions)
             for k in group][:sample]
    t = time.perf_counter()
    for k in items:
        k.vertex_ids(E, F)
        e.potential.hessian(k, k.dof(x, E, F), ipctk.PSDProjectionMethod.NONE)
    return (time.perf_counter() - t) / max(len(items), 1)


def _selector(free: np.ndarray) -> sp.csr_matrix:
    """Rows of the free DOFs among all 3 n_cp DOFs (as sim.model.potential does)."""
    pts = np.flatnonzero(free >= 0)
    dofs = (3 * pts[:, None] + np.arange(3)).ravel()
    return sp.csr_matrix((np.ones(dofs.size), (np.arange(dofs.size), dofs)), shape=(dofs.size, 3 * free.size))


def run(resolutions, steps=None, quadrature=None) -> list[dict]:
    return [case(n) for n in resolutions]
