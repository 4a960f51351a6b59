"""The `garment` command: a thin layer over the Python API.

    garment simulate SCENE.toml [-o run.rrd] [--mesh-dir DIR --format npz|obj|ply]
    garment bench NAME [--resolution N] [--steps K] [--quadrature Q] [--json]
    garment demo [-o out/demo.rrd]

Everything here is available from Python: `garment.scene.load_scene`,
`sim.simulator.Simulator.from_scene`, `Simulator.step/run/positions`.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table

from garment.scene import Scene, SceneError, load_scene

err = Console(stderr=True)


def _progress(quiet: bool) -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(), TimeRemainingColumn(), TextColumn("{task.fields[status]}"),
        console=err, disable=quiet, transient=False,
    )


def simulate(scene: Scene, rrd: Path | None = None, mesh_dir: Path | None = None,
             mesh_format: str = "npz", quiet: bool = False) -> list:
    """Run a scene to the end, writing the requested outputs. Returns the step stats."""
    from garment.io import MeshExportSink
    from sim.simulator import Simulator
    from viz.rerun_sink import RerunSink

    start = time.perf_counter()
    sim = Simulator.from_scene(scene)
    if not quiet:
        err.print(f"[dim]{scene.name}: {sim.n_dofs} DOFs, built in {time.perf_counter() - start:.2f} s")
    sinks = []
    if rrd is not None:
        sinks.append(RerunSink(rrd, recording_name=scene.name))
    if mesh_dir is not None:
        sinks.append(MeshExportSink(mesh_dir, mesh_format))
    tm = scene.time
    with _progress(quiet) as progress:
        task = progress.add_task(scene.name, total=tm.frames * tm.steps_per_frame, status="")

        def on_step(st):
            progress.update(task, advance=1, status=(
                f"newton {st.newton_iterations:3d}  |dC|/dt {st.residual:.1e}  {st.t_total * 1e3:6.0f} ms "
                f"(asm {st.t_assembly * 1e3:.0f} fact {st.t_factorization * 1e3:.0f} "
                f"solve {st.t_solve * 1e3:.0f} ls {st.t_line_search * 1e3:.0f})"))

        stats = sim.run(tm.frames, tm.steps_per_frame, sinks, on_step)
    if not quiet:
        _print_run_summary(stats, rrd, mesh_dir)
    return stats


def _print_run_summary(stats, rrd, mesh_dir):
    from garment.bench.common import step_summary

    s = step_summary(stats)
    unconverged = sum(not st.converged for st in stats)
    err.print(
        f"{s['steps']} steps, {s['seconds_per_step']:.3f} s/step, {s['newton_iterations_per_step']:.1f} "
        f"Newton iterations/step; time in assembly {s['assembly_fraction']:.0%}, factorization "
        f"{s['factorization_fraction']:.0%}, solve {s['solve_fraction']:.0%}, line search "
        f"{s['line_search_fraction']:.0%}"
        + (f"; [yellow]{unconverged} steps hit the iteration cap" if unconverged else "")
    )
    for path in (rrd, mesh_dir):
        if path is not None:
            err.print(f"wrote {path}")


def _cmd_simulate(args) -> int:
    scene = load_scene(args.scene)
    out = scene.output
    rrd = args.output if args.output is not None else out.rrd
    mesh_dir = args.mesh_dir if args.mesh_dir is not None else out.mesh_dir
    if args.frames is not None:
        scene = dataclasses.replace(scene, time=dataclasses.replace(scene.time, frames=args.frames))
    simulate(scene, rrd, mesh_dir, args.format or out.mesh_format, args.quiet)
    return 0


def _cmd_demo(args) -> int:
    from garment.bench.common import scene as bundled

    n = args.resolution
    sc = bundled("hanging", (n, n), frames=args.frames)
    simulate(sc, args.output, None, quiet=args.quiet)
    return 0


def _cmd_bench(args) -> int:
    from garment.bench import BENCHMARKS

    bench = BENCHMARKS[args.name]
    resolutions = (args.resolution,) if args.resolution else bench.resolutions
    kwargs = {"steps": args.steps}
    if args.quadrature:
        kwargs["quadrature"] = args.quadrature
    with _progress(args.quiet or args.json) as progress:
        task = progress.add_task(args.name, total=None, status="")

        def on_step(n, st):
            progress.update(task, advance=1, status=f"{n}^2 step {st.step}: newton {st.newton_iterations}, "
                                                    f"{st.t_total:.2f} s")

        if args.name not in ("plate",):
            kwargs["progress"] = on_step
        cases = bench.run(resolutions, **kwargs)
    if args.json:
        print(json.dumps({"benchmark": args.name, "cases": cases}, indent=1))
    else:
        table = Table(title=f"garment bench {args.name}: {bench.description}")
        cols = [c for c in bench.columns if any(c in case for case in cases)]
        for c in cols:
            table.add_column(c, justify="right")
        for case in cases:
            table.add_row(*[_fmt(c, case.get(c, "")) for c in cols])
        out = Console()
        if not out.is_terminal:
            out = Console(width=240)  # keep full column names when piped
        out.print(table)
    return 0


def _fmt(column: str, v) -> str:
    if isinstance(v, float):
        return f"{v:.0%}" if column.endswith("fraction") else f"{v:.4g}"
    return str(v)


def build_parser() -> argparse.ArgumentParser:
    from garment.materials import QUADRATURES

    p = argparse.ArgumentParser(prog="garment", description="B-spline garment simulation toolkit")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="run a scene file")
    s.add_argument("scene", type=Path)
    s.add_argument("-o", "--output", type=Path, help="Rerun recording (.rrd) to write")
    s.add_argument("--mesh-dir", type=Path, help="directory for per-frame meshes")
    s.add_argument("--format", choices=("npz", "obj", "ply"), help="per-frame mesh format")
    s.add_argument("--frames", type=int, help="override [time].frames")
    s.add_argument("-q", "--quiet", action="store_true")
    s.set_defaults(func=_cmd_simulate)

    d = sub.add_parser("demo", help="the bundled default: upright hanging cloth for 1 s")
    d.add_argument("-o", "--output", type=Path, default=Path("out/demo.rrd"))
    d.add_argument("--resolution", type=int, default=40, help="control points per side")
    d.add_argument("--frames", type=int, default=100, help="frames of 0.01 s")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=_cmd_demo)

    from garment.bench import BENCHMARKS

    b = sub.add_parser("bench", help="run a benchmark and print its table")
    b.add_argument("name", choices=sorted(BENCHMARKS))
    b.add_argument("--resolution", type=int, help="run one case: an N x N control net")
    b.add_argument("--steps", type=int, help="time steps per case")
    b.add_argument("--quadrature", choices=QUADRATURES)
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("-q", "--quiet", action="store_true")
    b.set_defaults(func=_cmd_bench)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except SceneError as e:
        print(f"error: {e}", file=sys.stderr)  # plain: no markup, no wrapping
        return 2
    except KeyboardInterrupt:
        err.print("[yellow]interrupted[/yellow]")
        return 130


if __name__ == "__main__":
    sys.exit(main())
