"""`garment bench NAME [--resolution N] [--steps K] [--quadrature Q] [--json]`."""

from __future__ import annotations

import json

from sim.budget import require_memory, simulation_bytes
from sim.errors import InputError

from .console import print_table, progress
from .options import number_option


def run(args) -> int:
    from garment.bench import BENCHMARKS

    bench = BENCHMARKS[args.name]
    if args.resolution is not None:
        number_option("--resolution", args.resolution, ge=3)
        require_memory(simulation_bytes(args.resolution**2), f"--resolution {args.resolution} "
                       f"({args.resolution}^2 control points)", "use a smaller --resolution")
    if args.steps is not None:
        number_option("--steps", args.steps, ge=1)
    resolutions = (args.resolution,) if args.resolution else bench.resolutions
    kwargs = {"steps": args.steps}
    if args.quadrature:
        kwargs["quadrature"] = args.quadrature
    if args.out and args.name not in ("compare", "corpus"):
        raise InputError("--out applies to `garment bench compare` and `corpus` only")
    if args.case and args.name not in ("compare", "garment", "conform-garments", "corpus"):
        raise InputError("--case applies to `garment bench compare`, `garment`, `conform-garments` and `corpus` "
                         "only")
    if args.jobs != 1:
        number_option("--jobs", args.jobs, ge=1, le=64)
        if args.name != "corpus":
            raise InputError("--jobs applies to `garment bench corpus` only")
        kwargs["jobs"] = args.jobs
    kwargs.update({k: v for k, v in (("case", args.case), ("out", args.out)) if v})
    if args.refine:
        number_option("--refine", args.refine, ge=0, le=4)
        if args.name != "garment":
            raise InputError("--refine applies to `garment bench garment` only")
        kwargs["refine"] = args.refine
    with progress(args.quiet or args.json) as bar:
        task = bar.add_task(args.name, total=None, status="")

        def on_step(n, st):
            bar.update(task, advance=1, status=f"{n}^2 step {st.step}: newton {st.newton_iterations}, "
                                               f"{st.t_total:.2f} s")

        if bench.reports_steps:
            kwargs["progress"] = on_step
        cases = bench.run(resolutions, **kwargs)
    if args.json:
        print(json.dumps({"benchmark": args.name, "cases": cases}, indent=1))
    elif args.name == "compare":
        from garment.bench.compare import tables

        for case, columns, rows in tables(cases):
            print_table(f"garment bench compare --case {case}", columns, rows)
    else:
        print_table(f"garment bench {args.name}: {bench.description}", bench.columns, cases)
    return 0


def register(sub) -> None:
    from garment.bench import BENCHMARKS
    from sim.materials import QUADRATURES

    b = sub.add_parser("bench", help="run a benchmark and print its table")
    b.add_argument("name", choices=sorted(BENCHMARKS))
    b.add_argument("--resolution", type=int, help="run one case: an N x N control net")
    b.add_argument("--steps", type=int, help="time steps per case")
    b.add_argument("--quadrature", choices=QUADRATURES)
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--case", help="compare: comma-separated cases (hanging, drape, shear, sphere, plate, "
                                  "locking, ablation); garment: poncho (default), dress, dress-hiphop "
                                  "(the paper's Hiphop cloth and contact), dress-frictionless or dress-band (contact off "
                                  "near the seams); conform-garments: "
                                  "dress_knife, shirt_mean, dress_pencil; corpus: "
                                  "designs or types, e.g. skirt_00,pants")
    b.add_argument("--refine", type=int, default=0, metavar="K",
                   help="garment only: sew at 2^K x the span, then refine exactly K times to it")
    b.add_argument("--out", help="compare: folder for compare.json, compare.md and PNG plots; corpus: folder "
                                 "for each design's outputs (out/bench-corpus)")
    b.add_argument("--jobs", type=int, default=1, metavar="N", help="corpus only: designs dressed at once (1)")
    b.add_argument("-q", "--quiet", action="store_true")
    b.set_defaults(func=run)
