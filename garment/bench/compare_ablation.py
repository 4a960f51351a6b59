"""The paper's time breakdown per Newton iteration (section 6.5, figure "Timing
breakdown"): the 100^2 hanging cloth with the B-spline optimisations added one by one,
and linear FEM at the same resolution.

(A) 2x2 Gauss points for membrane and bending on every span, bending Hessian rebuilt
    every iteration, assembly on one thread;
(B) the reduced rules (membrane: the paper's scheme, bending: span centres);
(C) plus the constant bending Hessian assembled once (the simulator's default);
(D) plus parallel assembly (numba on all cores; the simulator's default);
(E) linear FEM on the same number of vertices, with everything of (D).

"Rebuilt every iteration" wraps the simulator's bending energy so its Hessian is formed
from the per-point data at each assembly, as an implementation without precomputation
would; "one thread" sets numba's thread count to 1 for the run (CHOLMOD and BLAS are
unaffected, as in the paper where the solver is the same in all variants).
"""

from __future__ import annotations


import numba
import scipy.sparse as sp

from sim.assembly import add_scalar_matrix
from sim.energies import BendingEnergy
from garment.build import build_linear_simulator
from sim.potential import IncrementalPotential
from garment.build import build_simulator
from sim.simulator import Simulator

from .common import scene

RESOLUTION = 100
STEPS = 10
VARIANTS = ("A", "B", "C", "D", "E")


class RebuiltBending(BendingEnergy):
    """Laplacian bending whose constant Hessian is rebuilt at every assembly."""

    constant_hessian = False

    def __init__(self, points, stiffness, n_cp):
        super().__init__(points, stiffness, n_cp)
        self._stiffness = stiffness
        self._n_cp = n_cp

    def add_hessian(self, C, data, project=True):
        pts = self.points
        Q, K = pts.idx.shape
        rows = pts.idx.repeat(K, axis=1).ravel()
        cols = pts.idx[:, None, :].repeat(K, axis=1).reshape(Q, K * K).ravel()
        coef = (pts.w * self._stiffness)[:, None, None] * pts.lap[:, :, None] * pts.lap[:, None, :]
        ok = (rows >= 0) & (cols >= 0)
        H = sp.coo_matrix((coef.ravel()[ok], (rows[ok], cols[ok])), shape=(self._n_cp, self._n_cp)).tocsr()
        add_scalar_matrix(self._pattern, H, data)


def _rebuild_bending(sim: Simulator, D: float) -> None:
    for k, e in enumerate(sim.model.energies):
        if type(e) is BendingEnergy:
            sim.model.energies[k] = RebuiltBending(e.points, D + 0.0 * e.points.w, sim.model.n_cp)
    sim.model.potential = IncrementalPotential(sim.model.energies, ~sim.model.pinned)


def build(variant: str, n: int):
    if variant == "E":
        return build_linear_simulator(scene("hanging"), n)
    sim = build_simulator(scene("hanging", (n, n), "gauss2" if variant == "A" else "reduced"))
    if variant in ("A", "B"):
        _rebuild_bending(sim, sim.model.pieces[0].material.bending_stiffness)
    return sim


def case(variant: str, n: int = RESOLUTION, steps: int = STEPS, progress=None) -> dict:
    sim = build(variant, n)
    threads = numba.get_num_threads()
    if variant in ("A", "B", "C"):
        numba.set_num_threads(1)
    try:
        stats = []
        for _ in range(steps):
            stats.append(sim.step())
            if progress is not None:
                progress(n, stats[-1])
    finally:
        numba.set_num_threads(threads)
    iters = sum(s.newton_iterations for s in stats)
    split = {k: sum(getattr(s, f"t_{k}") for s in stats) / iters
             for k in ("assembly", "factorization", "solve", "line_search")}
    total = sum(s.t_total for s in stats) / iters
    return {"case": "ablation", "variant": variant, "resolution": n, "dofs": sim.n_dofs,
            "newton_iterations": iters, "seconds_per_iteration": total,
            **{f"{k}_seconds": v for k, v in split.items()},
            "other_seconds": total - sum(split.values())}


def run(n: int = RESOLUTION, steps: int = STEPS, variants=VARIANTS, progress=None) -> list[dict]:
    return [case(v, n, steps, progress) for v in variants]
