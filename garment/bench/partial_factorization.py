"""Partial factorization (paper section 5.3): how the contact couplings that fall outside
the fixed Hessian pattern are solved, on the same collision (two plates meeting at
0.5 m/s each, assets/scenes/two_plates.toml, every contact between the plates outside
the pattern), per solver mode:

- diagonal: moved onto the diagonal only (one factorization, inexact Hessian);
- auto: CG preconditioned by that factor when the Gershgorin bound on ||D^-1 B|| < 1,
  otherwise merged and factored once (the paper's scheme);
- neumann: the same with the Neumann series instead of CG;
- merge: always merged and factored once (exact, a new symbolic analysis each time).

Reported per mode: Newton iterations per step, seconds per iteration and per step, the
trigger rates of CG and of merging among the iterations with moved couplings, CG
iterations per CG solve, and the momentum drift (exact modes keep it at round-off).
"""

from __future__ import annotations

import time

import numpy as np

from sim.newton import NewtonOptions
from garment.build import build_simulator

from .common import scene

MODES = ("diagonal", "auto", "neumann", "merge")
COLUMNS = ("resolution", "mode", "dofs", "steps", "newton_iterations_per_step", "seconds_per_iteration",
           "seconds_per_step", "cg_rate", "merge_rate", "cg_iterations_per_solve", "momentum_drift",
           "speedup_vs_merge")
DEFAULT_STEPS = 12


def _run_mode(n: int, mode: str, steps: int, progress=None) -> dict:
    sc = scene("two_plates", (n, n))
    sim = build_simulator(sc, NewtonOptions(off_pattern=mode))
    P0 = (sim.model.mass[:, None] * sim.V).sum(axis=0)
    scale = float((sim.model.mass * np.linalg.norm(sim.V, axis=1)).sum())
    stats = []
    start = time.perf_counter()
    for _ in range(steps):
        stats.append(sim.step())
        if progress is not None:
            progress(n, stats[-1])
    total = time.perf_counter() - start
    iters = sum(s.newton_iterations for s in stats)
    cg = sum(s.extra.get("pcg_solves", 0) for s in stats)
    merged = sum(s.extra.get("merged_solves", 0) for s in stats)
    moved = max(cg + merged, 1)
    drift = float(np.linalg.norm((sim.model.mass[:, None] * sim.V).sum(axis=0) - P0) / scale)
    return {
        "resolution": n, "mode": mode, "dofs": sim.n_dofs, "steps": steps,
        "newton_iterations_per_step": iters / steps, "seconds_per_iteration": total / max(iters, 1),
        "seconds_per_step": total / steps,
        "cg_rate": cg / moved if mode != "diagonal" else 0.0,  # CG or Neumann solves
        "merge_rate": merged / moved if mode != "diagonal" else 0.0,
        "cg_iterations_per_solve": sum(s.extra.get("pcg_iterations", 0) for s in stats) / max(cg, 1),
        "momentum_drift": drift,
    }


def run(resolutions, steps=None, quadrature=None, progress=None) -> list[dict]:
    cases = []
    for n in resolutions:
        rows = [_run_mode(n, mode, steps or DEFAULT_STEPS, progress) for mode in MODES]
        merge = rows[-1]["seconds_per_step"]
        for r in rows:
            r["speedup_vs_merge"] = merge / r["seconds_per_step"]
        cases.extend(rows)
    return cases
