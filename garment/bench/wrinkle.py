"""Wrinkling of a clamped, stretched sheet (Wang et al. 2019; docs/design.md section 7).

Quasi-static: the clamped short edges move apart in load steps to 1.1x the length, then
the sheet settles. Reports the maximum out-of-plane deflection of the surface (the sheet
lies in the xy-plane, so |z|) against the reference of about 3.45 mm.
"""

from __future__ import annotations

import time

import numpy as np

from garment.build import build_simulator

from .common import scene, step_summary

COLUMNS = ("resolution", "control_net", "dofs", "max_deflection_mm", "steps",
           "newton_iterations_per_step", "seconds")
REFERENCE_MM = 3.45


def solve(n: int, steps: int | None = None, quadrature: str | None = None, progress=None) -> dict:
    base = scene("wrinkle")
    width, length = base.cloths[0].size
    m = int(round(length / width * (n - 2))) + 2  # square knot spans
    sc = scene("wrinkle", (n, m), quadrature)
    start = time.perf_counter()
    sim = build_simulator(sc)
    stats = []
    for _ in range(steps or sc.time.frames):
        stats.append(sim.step())
        if progress is not None:
            progress(n, stats[-1])
    z = sim.positions("sheet")[:, 2]
    summary = step_summary(stats)
    return {
        "resolution": n, "control_net": f"{n}x{m}", "dofs": sim.n_dofs,
        "max_deflection_mm": float(np.abs(z).max() * 1e3), "reference_mm": REFERENCE_MM,
        "steps": len(stats), "newton_iterations_per_step": summary["newton_iterations_per_step"],
        "seconds": time.perf_counter() - start,
    }


def run(resolutions, steps=None, quadrature=None, progress=None) -> list[dict]:
    return [solve(n, steps, quadrature, progress) for n in resolutions]
