"""`garment simulate SCENE.toml [-o run.rrd] [--connect [URL] | --serve [PORT]]
[--control-net] [--render out.mp4|out.gif|DIR [--render-size WxH] [--orbit] [--fps F]]
[--mesh-dir DIR --format npz|obj|ply] [--frames N] [-q]`."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from garment.errors import InputError
from garment.scene import Scene, load_scene

from .console import err, progress

DEFAULT_PORT = 9876  # rerun's default gRPC port


def simulate(scene: Scene, rrd: Path | None = None, mesh_dir: Path | None = None,
             mesh_format: str = "npz", quiet: bool = False, *, connect: str | None = None,
             serve: int | None = None, control_net: bool = False, render_to: Path | None = None,
             render_options=None) -> list:
    """Run a scene to the end, writing the requested outputs. Returns the step stats.

    rrd: Rerun recording file; connect: URL of a running Rerun viewer; serve: port to host
    a gRPC server on (waits for Ctrl-C after the run so viewers can keep reading);
    control_net: also log control nets; render_to: .mp4, .gif or a PNG folder rendered
    after the run with `render_options` (a `viz.render.RenderOptions`).
    """
    from garment.io import MeshExportSink
    from sim.simulator import Simulator
    from viz.rerun_sink import RerunSink, check_viewer_reachable

    if render_to is not None:
        _check_render_target(render_to)
    if connect is not None:
        try:
            check_viewer_reachable(connect)
        except ConnectionError as e:
            raise InputError(f"--connect: {e}") from None

    start = time.perf_counter()
    sim = Simulator.from_scene(scene)
    if not quiet:
        err.print(f"[dim]{scene.name}: {sim.n_dofs} DOFs, built in {time.perf_counter() - start:.2f} s")
    sinks = []
    rerun_sink = None
    if rrd is not None or connect is not None or serve is not None:
        nets = (lambda: {p.name: sim.control_points(p.name) for p in sim.pieces}) if control_net else None
        rerun_sink = RerunSink(rrd, connect=connect, serve=serve, recording_name=scene.name, control_nets=nets)
        sinks.append(rerun_sink)
    if mesh_dir is not None:
        sinks.append(MeshExportSink(mesh_dir, mesh_format))
    frames = None
    if render_to is not None:
        from viz.render import FrameBuffer

        frames = FrameBuffer()
        sinks.append(frames)

    tm = scene.time
    try:
        with progress(quiet) as bar:
            task = bar.add_task(scene.name, total=tm.frames * tm.steps_per_frame, status="")
            stats = sim.run(tm.frames, tm.steps_per_frame, sinks,
                            lambda st: bar.update(task, advance=1, status=step_line(st)))
        if not quiet:
            print_run_summary(stats, [rrd, mesh_dir])
            if rerun_sink is not None:
                print_logging_cost(rerun_sink.seconds, sum(s.t_total for s in stats))
        if frames is not None:
            render_frames(frames.meshes, frames.frames(), render_to, render_options, quiet)
        if rerun_sink is not None and serve is not None:
            serve_until_interrupted(rerun_sink, quiet)
    finally:
        if rerun_sink is not None:
            rerun_sink.shutdown()  # a served run interrupted early still finishes its file
    return stats


def step_line(st) -> str:
    """Compact live statistics of one step for the progress bar."""
    line = (f"newton {st.newton_iterations:3d}  |dC|/dt {st.residual:.1e}  {st.t_total * 1e3:6.0f} ms "
            f"(asm {st.t_assembly * 1e3:.0f} fact {st.t_factorization * 1e3:.0f} "
            f"solve {st.t_solve * 1e3:.0f} ls {st.t_line_search * 1e3:.0f})")
    if "contact_count" in st.extra:
        line += f"  contacts {st.extra['contact_count']:.0f}"
    if "min_distance" in st.extra:
        line += f"  dmin {st.extra['min_distance']:.1e} m"
    return line


def _check_render_target(out: Path) -> None:
    from viz.render import output_kind

    try:
        output_kind(out)
    except ValueError as e:
        raise InputError(str(e)) from None


def render_frames(meshes, frames, out: Path, options, quiet: bool) -> None:
    """Render frames with PyVista off-screen, with a progress bar; prints the cost."""
    from viz.render import RenderOptions, render

    options = options or RenderOptions()
    start = time.perf_counter()
    with progress(quiet) as bar:
        task = bar.add_task(f"render {out.name}", total=len(frames), status="")
        render(meshes, frames, out, options, on_frame=lambda k: bar.update(task, advance=1))
    if not quiet:
        dt = time.perf_counter() - start
        err.print(f"rendered {len(frames)} frames ({options.size[0]}x{options.size[1]}) in {dt:.1f} s "
                  f"({dt / max(len(frames), 1):.2f} s/frame)\nwrote {out}")


def serve_until_interrupted(sink, quiet: bool) -> None:
    """Keep the in-process gRPC server up until Ctrl-C, then finish the recording file."""
    uri = (sink.server_uri or "").replace("0.0.0.0", "127.0.0.1")
    if not quiet:
        err.print(f"serving the recording at {uri}; view it with `rerun {uri}`; Ctrl-C to stop")
    try:
        wait_for_interrupt()
    except KeyboardInterrupt:
        pass
    sink.shutdown()


def wait_for_interrupt() -> None:  # a function of its own so tests can replace it
    while True:
        time.sleep(3600)


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


def print_logging_cost(log_seconds: float, sim_seconds: float) -> None:
    share = f" ({log_seconds / sim_seconds:.1%} of the simulation time)" if sim_seconds > 0 else ""
    err.print(f"[dim]Rerun logging took {log_seconds:.2f} s{share}")


def run(args) -> int:
    from viz.render import RenderOptions, parse_size

    scene = load_scene(args.scene)
    out = scene.output
    rrd = args.output if args.output is not None else out.rrd
    mesh_dir = args.mesh_dir if args.mesh_dir is not None else out.mesh_dir
    if args.frames is not None:
        scene = dataclasses.replace(scene, time=dataclasses.replace(scene.time, frames=args.frames))
    options = None
    if args.render is not None:
        try:
            size = parse_size(args.render_size)
        except ValueError as e:
            raise InputError(f"--render-size: {e}") from None
        if not args.fps > 0:
            raise InputError(f"--fps: must be > 0, got {args.fps}")
        options = RenderOptions(size=size, fps=args.fps, orbit=args.orbit)
    simulate(scene, rrd, mesh_dir, args.format or out.mesh_format, args.quiet, connect=args.connect,
             serve=args.serve, control_net=args.control_net, render_to=args.render, render_options=options)
    return 0


def add_render_options(p) -> None:
    """--render and its options; shared with `garment inspect`."""
    p.add_argument("--render", type=Path, metavar="OUT",
                   help="render the frames off-screen to OUT: .mp4, .gif, or a folder of PNG frames")
    p.add_argument("--render-size", default="640x480", metavar="WxH", help="image size in pixels (640x480)")
    p.add_argument("--orbit", action="store_true", help="orbit the camera once around the scene")
    p.add_argument("--fps", type=float, default=30.0, help="video frames per second (30)")


def register(sub) -> None:
    from viz import DEFAULT_VIEWER_URL as DEFAULT_URL

    s = sub.add_parser("simulate", help="run a scene file")
    s.add_argument("scene", type=Path)
    s.add_argument("-o", "--output", type=Path, help="Rerun recording (.rrd) to write")
    s.add_argument("--connect", nargs="?", const=DEFAULT_URL, metavar="URL",
                   help=f"stream live to a running Rerun viewer (default {DEFAULT_URL})")
    s.add_argument("--serve", nargs="?", type=int, const=DEFAULT_PORT, metavar="PORT",
                   help=f"host a gRPC server viewers can connect to (port {DEFAULT_PORT}); "
                        "keeps serving after the run until Ctrl-C")
    s.add_argument("--control-net", action="store_true", help="log the control nets as line strips")
    add_render_options(s)
    s.add_argument("--mesh-dir", type=Path, help="directory for per-frame meshes")
    s.add_argument("--format", choices=("npz", "obj", "ply"), help="per-frame mesh format")
    s.add_argument("--frames", type=int, help="override [time].frames")
    s.add_argument("-q", "--quiet", action="store_true")
    s.set_defaults(func=run)
