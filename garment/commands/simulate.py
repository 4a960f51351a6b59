"""`garment simulate SCENE.toml [-o run.rrd] [--mesh-dir DIR --format npz|obj|ply]`."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from garment.scene import Scene, load_scene

from .console import err, progress


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
    with progress(quiet) as bar:
        task = bar.add_task(scene.name, total=tm.frames * tm.steps_per_frame, status="")

        def on_step(st):
            bar.update(task, advance=1, status=(
                f"newton {st.newton_iterations:3d}  |dC|/dt {st.residual:.1e}  {st.t_total * 1e3:6.0f} ms "
                f"(asm {st.t_assembly * 1e3:.0f} fact {st.t_factorization * 1e3:.0f} "
                f"solve {st.t_solve * 1e3:.0f} ls {st.t_line_search * 1e3:.0f})"))

        stats = sim.run(tm.frames, tm.steps_per_frame, sinks, on_step)
    if not quiet:
        print_run_summary(stats, [rrd, mesh_dir])
    return stats


def print_run_summary(stats, outputs) -> None:
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
    for path in outputs:
        if path is not None:
            err.print(f"wrote {path}")


def run(args) -> int:
    scene = load_scene(args.scene)
    out = scene.output
    rrd = args.output if args.output is not None else out.rrd
    mesh_dir = args.mesh_dir if args.mesh_dir is not None else out.mesh_dir
    if args.frames is not None:
        scene = dataclasses.replace(scene, time=dataclasses.replace(scene.time, frames=args.frames))
    simulate(scene, rrd, mesh_dir, args.format or out.mesh_format, args.quiet)
    return 0


def register(sub) -> None:
    s = sub.add_parser("simulate", help="run a scene file")
    s.add_argument("scene", type=Path)
    s.add_argument("-o", "--output", type=Path, help="Rerun recording (.rrd) to write")
    s.add_argument("--mesh-dir", type=Path, help="directory for per-frame meshes")
    s.add_argument("--format", choices=("npz", "obj", "ply"), help="per-frame mesh format")
    s.add_argument("--frames", type=int, help="override [time].frames")
    s.add_argument("-q", "--quiet", action="store_true")
    s.set_defaults(func=run)
