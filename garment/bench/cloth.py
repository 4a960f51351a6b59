"""The Kim 2020 cloth tests (hanging, drape, shear): cost per time step at the paper's
B-spline resolutions, with Newton iterations and where the time goes."""

from __future__ import annotations

import time

from garment.build import build_simulator

from .common import scene, step_summary

COLUMNS = ("resolution", "dofs", "steps", "seconds_per_step", "newton_iterations_per_step",
           "seconds_per_iteration", "assembly_fraction", "factorization_fraction",
           "solve_fraction", "line_search_fraction", "build_seconds")

DEFAULT_STEPS = 20


def runner(name: str):
    def run(resolutions, steps=None, quadrature=None, progress=None) -> list[dict]:
        cases = []
        for n in resolutions:
            start = time.perf_counter()
            sim = build_simulator(scene(name, (n, n), quadrature))
            build = time.perf_counter() - start
            stats = []
            for _ in range(steps or DEFAULT_STEPS):
                stats.append(sim.step())
                if progress is not None:
                    progress(n, stats[-1])
            cases.append({"resolution": n, "dofs": sim.n_dofs, "build_seconds": build, **step_summary(stats)})
        return cases

    run.__doc__ = f"Run the {name} scene for `steps` steps at each resolution."
    return run
