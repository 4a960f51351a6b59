"""The Kim 2020 cloth tests (hanging, drape, shear) and the cloth on a sphere: cost per
time step at the paper's B-spline resolutions, with Newton iterations, factorizations and
where the time goes. The hanging sheet is seeded 1 mm out of plane (its scene file), so
it wrinkles as the paper's does; unseeded it stays exactly planar and is 3x easier."""

from __future__ import annotations

import time

from garment.build import build_simulator

from .common import scene, step_summary

COLUMNS = ("resolution", "dofs", "steps", "seconds_per_step", "newton_iterations_per_step",
           "factorizations_per_step", "pcg_iterations_per_step", "seconds_per_iteration", "assembly_fraction",
           "factorization_fraction", "solve_fraction", "ccd_fraction", "line_search_fraction", "build_seconds")

DEFAULT_STEPS = 20


def runner(name: str, default_steps: int = DEFAULT_STEPS):
    def run(resolutions, steps=None, quadrature=None, progress=None) -> list[dict]:
        cases = []
        for n in resolutions:
            start = time.perf_counter()
            sim = build_simulator(scene(name, (n, n), quadrature))
            build = time.perf_counter() - start
            stats = []
            for _ in range(steps or default_steps):
                stats.append(sim.step())
                if progress is not None:
                    progress(n, stats[-1])
            cases.append({"resolution": n, "dofs": sim.n_dofs, "build_seconds": build, **step_summary(stats)})
        return cases

    run.__doc__ = f"Run the {name} scene for `steps` (default {default_steps}) steps at each resolution."
    return run
