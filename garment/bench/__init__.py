"""Benchmarks: `garment bench NAME` runs one and prints a table, or JSON with --json.

Each benchmark is a function (resolutions, steps, quadrature) -> list of case dicts, one
per control-net resolution, plus the columns to print. The scene files in assets/scenes/
are the single source of each setup; benchmarks only override resolution and length.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from . import cloth, compare, contact_hessian, partial_factorization, plate, wrinkle
from . import garment as garment_bench
from . import conform as conform_bench
from . import conform_garments, corpus, viz_overhead


@dataclass(frozen=True)
class Benchmark:
    name: str
    description: str
    run: Callable[..., list[dict]]
    resolutions: tuple[int, ...]
    columns: tuple[str, ...]
    reports_steps: bool = True  # run() takes a progress(resolution, StepStats) callback


BENCHMARKS = {
    b.name: b
    for b in (
        Benchmark("plate", "simply supported plate, max deflection vs analytic (Navier)",
                  plate.run, (8, 16, 32, 64), plate.COLUMNS, reports_steps=False),
        Benchmark("wrinkle", "stretched sheet wrinkling, max out-of-plane deflection (ref ~3.45 mm)",
                  wrinkle.run, (20, 30, 40, 50), wrinkle.COLUMNS),
        Benchmark("hanging", "upright hanging cloth (Kim 2020), cost per step",
                  cloth.runner("hanging", 53), (75, 100, 125), cloth.COLUMNS),
        Benchmark("drape", "drape test (Kim 2020), cost per step",
                  cloth.runner("drape"), (75, 100, 125), cloth.COLUMNS),
        Benchmark("shear", "shear test (Kim 2020), cost per step",
                  cloth.runner("shear"), (75, 100, 125), cloth.COLUMNS),
        Benchmark("sphere", "cloth falling onto a sphere on the ground (paper section 6.1), cost per step",
                  cloth.runner("sphere", 45), (75,), cloth.COLUMNS),
        Benchmark("conform", "quadrature error on conformed distorted patches (aspect, skew, bend sweep)",
                  conform_bench.run, (10, 20), conform_bench.COLUMNS, reports_steps=False),
        Benchmark("conform-garments", "conforming the bundled garments: seconds per panel vs the 2 s target "
                  "(resolution = knot span, mm)", conform_garments.run, (20,), conform_garments.COLUMNS,
                  reports_steps=False),
        Benchmark("contact-hessian", "dense-contact Hessian: ipctk evaluation and mapping to control points",
                  contact_hessian.run, (30, 50, 75), contact_hessian.COLUMNS, reports_steps=False),
        Benchmark("partial-factorization", "off-pattern contact couplings: diagonal vs CG/merge vs merge (two plates)",
                  partial_factorization.run, (10, 20, 30), partial_factorization.COLUMNS),
        Benchmark("garment", "garment sewn onto the dancing body, cost per step by knot span (resolution = mm)",
                  garment_bench.run, (40, 20), garment_bench.COLUMNS),
        Benchmark("corpus", "the GarmentCode corpus and the bundled patterns dressed with defaults "
                  "(`garment dress`), success rate", corpus.run, (), corpus.COLUMNS, reports_steps=False),
        Benchmark("viz-overhead", "Rerun logging per frame against the hanging cloth's simulation (target < 5 %)",
                  viz_overhead.run, (100,), viz_overhead.COLUMNS, reports_steps=False),
        Benchmark("compare", "B-spline vs linear FEM (pairs, plate, locking, ablation; --case, --out)",
                  compare.run, (), compare.COLUMNS),
    )
}
