"""Plate bending, error against runtime: B-spline (1-point "reduced" and 2x2 bending
quadrature) against linear FEM with Bergou bending on equilateral meshes and on right
triangles with alternating diagonals (paper section 6.2, "Convergence under refinement").

Runtime is build + one quasi-static Newton solve, the best of `REPEATS` runs (single
solves take milliseconds, so one run is mostly noise).
"""

from __future__ import annotations

import time

import numpy as np

from garment.build import build_linear_simulator

from . import plate
from .common import scene

BSPLINE = {"reduced": (8, 12, 16, 24, 32), "gauss2": (8, 12, 16, 24, 32)}
LINEAR = {"equilateral": (9, 17, 33, 65, 129), "grid": (9, 17, 33, 65, 129)}
REPEATS = 3


def linear_solve(n: int, layout: str) -> dict:
    sc = scene("plate")
    cloth = sc.cloths[0]
    best = np.inf
    for _ in range(REPEATS):
        start = time.perf_counter()
        sim = build_linear_simulator(sc, n, layout)
        sim.step()
        best = min(best, time.perf_counter() - start)
    mesh = sim.model.pieces[0].mesh
    k, bary = mesh.locate((0.5 * cloth.size[0], 0.5 * cloth.size[1]))
    w = abs(float(bary @ (sim.C - sim.model.C0)[mesh.faces[k]] @ np.asarray(sc.load.pressure_direction)))
    analytic = plate.navier_coefficient() * sc.load.pressure * cloth.size[0] ** 4 / cloth.material.bending_stiffness
    return {"case": "plate", "method": f"linear-{layout}", "resolution": n, "dofs": sim.n_dofs,
            "elements": int(mesh.faces.shape[0]), "rel_error": abs(w - analytic) / analytic, "seconds": best}


def bspline_solve(n: int, quadrature: str) -> dict:
    best, case = np.inf, None
    for _ in range(REPEATS):
        case = plate.solve(n, quadrature)
        best = min(best, case["seconds"])
    return {"case": "plate", "method": f"bspline-{quadrature}", "resolution": n, "dofs": case["dofs"],
            "elements": (n - 2) ** 2, "rel_error": case["rel_error"], "seconds": best}


def equal_accuracy(rows: list[dict], target: str = "linear-equilateral", method: str = "bspline-reduced") -> list[dict]:
    """For each `target` run, the cheapest `method` run at least as accurate."""
    out = []
    for lin in (r for r in rows if r["method"] == target):
        ok = [r for r in rows if r["method"] == method and r["rel_error"] <= lin["rel_error"]]
        if not ok:
            continue
        bs = min(ok, key=lambda r: r["seconds"])
        out.append({"case": "plate", "method": "equal-accuracy", "resolution": bs["resolution"],
                    "linear_resolution": lin["resolution"], "rel_error_bspline": bs["rel_error"],
                    "rel_error_linear": lin["rel_error"], "seconds_per_step_bspline": bs["seconds"],
                    "seconds_per_step_linear": lin["seconds"], "speedup": lin["seconds"] / bs["seconds"]})
    return out


def run(bspline=BSPLINE, linear=LINEAR) -> list[dict]:
    rows = [bspline_solve(n, q) for q, ns in bspline.items() for n in ns]
    rows += [linear_solve(n, layout) for layout, ns in linear.items() for n in ns]
    return rows + equal_accuracy(rows)
