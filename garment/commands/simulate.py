"""`garment simulate SCENE.toml [-o run.rrd] [--connect [URL] | --serve [PORT]]
[--control-net] [--render out.mp4|out.gif|DIR [--render-size WxH] [--orbit] [--fps F]]
[--mesh-dir DIR --format npz|obj|ply] [--frames N] [--checkpoint FILE] [--checkpoint-every K]
[--resume] [--max-splits N] [--deterministic] [-q]`.

Long runs: see sim/driver.py (checkpoints, resuming, step splitting) and `StopOnSignal`."""

from __future__ import annotations

import dataclasses
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
from rich.markup import escape

from sim.budget import BASE_BYTES, require_memory
from sim.errors import InputError, Interrupted
from sim.files import output_file, output_folder, remove_partial_files
from garment.scene import Scene, TimeSpec, parse_scene
from garment.scene.read import read_scene_data

from .console import err, progress
from .options import number_option, scene_option

DEFAULT_PORT = 9876  # rerun's default gRPC port


def simulate(scene: Scene, rrd: Path | None = None, mesh_dir: Path | None = None,
             mesh_format: str = "npz", quiet: bool = False, *, connect: str | None = None,
             serve: int | None = None, control_net: bool = False, render_to: Path | None = None,
             render_options=None, checkpoint: Path | None = None, checkpoint_every: int = 10,
             resume: bool = False, max_splits: int | None = None, deterministic: bool = False) -> list:
    """Run a scene to the end, writing the requested outputs. Returns the step stats.

    rrd: Rerun recording file; connect: URL of a running Rerun viewer; serve: port to host
    a gRPC server on (waits for Ctrl-C after the run so viewers can keep reading);
    control_net: also log control nets; render_to: .mp4, .gif or a PNG folder rendered
    after the run with `render_options` (a `viz.render.RenderOptions`).
    checkpoint: state file written every `checkpoint_every` frames, at the end, on
    SIGINT/SIGTERM and on failure; resume: continue from it (the recording goes to the
    next free `<rrd stem>.partN.rrd`, existing per-frame files are kept). max_splits: a
    failing step is retried as halves down to dt / 2^max_splits. deterministic: run ipctk
    on one thread, so reruns and resumed runs repeat an uninterrupted run bit for bit.
    Raises Interrupted (exit 130) after a signal, SimulationError (exit 3) on failure.
    """
    from garment.build import build_simulator, scene_hash
    from garment.io import MeshExportSink
    from sim.driver import CheckpointPolicy, SkipExisting, drive, segment_path
    from sim.recovery import DEFAULT_SPLITS
    from viz.rerun_sink import RerunSink, check_viewer_reachable

    check_outputs(rrd, mesh_dir, checkpoint, render_to, quiet=quiet or connect is not None or serve is not None)
    if connect is not None:
        try:
            check_viewer_reachable(connect)
        except ConnectionError as e:
            raise InputError(f"--connect: {e}") from None
    if deterministic:
        import ipctk

        ipctk.set_num_threads(1)  # TBB reductions in ipctk otherwise vary from run to run
    digest = scene_hash(scene)
    state = load_resume_state(checkpoint, digest, quiet) if resume else None
    if state is not None and state.frame >= scene.time.frames:
        if not quiet:
            err.print(f"nothing to do: {checkpoint} is at frame {state.frame} already (--frames N extends the run)")
        return []

    start = time.perf_counter()
    try:
        sim = build_simulator(scene)
    except InputError as e:
        first = str(e).split(" ", 1)[0]
        if scene.path is not None and not first.endswith(":"):  # name a file, as scene errors do
            raise InputError(f"{scene.path}: {e}") from None
        raise
    if not quiet:
        err.print(f"[dim]{scene.name}: {sim.n_dofs} DOFs, built in {time.perf_counter() - start:.2f} s")
    sinks = []
    rerun_sink = None
    if rrd is not None and state is not None:
        rrd = segment_path(rrd)  # earlier segments stay as they are
    if rrd is not None or connect is not None or serve is not None:
        nets = (lambda: {p.name: sim.control_points(p.name) for p in sim.model.pieces}) if control_net else None
        rerun_sink = RerunSink(rrd, connect=connect, serve=serve, recording_name=scene.name, control_nets=nets)
        sinks.append(rerun_sink)
    if mesh_dir is not None:
        mesh_sink = MeshExportSink(mesh_dir, mesh_format)
        sinks.append(SkipExisting(mesh_sink) if state is not None else mesh_sink)
    frames = None
    if render_to is not None:
        from viz.render import FrameBuffer

        vertices = sum(int(m.faces.max(initial=-1)) + 1 for m in sim.model.topologies())
        need = FrameBuffer.bytes_for(scene.time.frames + 1, vertices)
        require_memory(BASE_BYTES + need, f"--render: keeping {scene.time.frames + 1} frames of {vertices} "
                       "vertices for the video", "render fewer frames (--frames), or write the recording "
                       "(-o) without --render")
        frames = FrameBuffer()
        sinks.append(frames)

    tm = scene.time
    splits = DEFAULT_SPLITS if max_splits is None else max_splits
    policy = CheckpointPolicy(checkpoint, checkpoint_every, digest)
    first = state.frame if state is not None else 0
    try:
        with progress(quiet) as bar, StopOnSignal(quiet) as stop:
            task = bar.add_task(scene.name, total=max(tm.frames - first, 0) * tm.steps_per_frame, status="")
            result = drive(sim, tm.frames, tm.steps_per_frame, sinks, resume=state, checkpoint=policy,
                           should_stop=stop.requested, floor=tm.dt / 2**splits,
                           on_step=lambda st: bar.update(task, advance=1, status=step_line(st)),
                           on_warning=lambda msg: err.print(f"[yellow]warning:[/] {escape(msg)}"))
        stats = result.stats
        if not quiet:
            if stats:
                print_run_summary(stats, [rrd, mesh_dir, checkpoint if result.checkpoints else None])
                print_seam_summary(sim)
            if result.splits:
                err.print(f"[yellow]{result.splits} steps were split to converge")
            if rerun_sink is not None and stats:
                print_logging_cost(rerun_sink.seconds, sum(s.t_total for s in stats))
        if result.stopped:
            raise Interrupted(stopped_message(result.last_frame, tm.frames, checkpoint, [rrd, mesh_dir]))
        if frames is not None:
            render_frames(frames.meshes, frames.frames(), render_to, _upright(render_options, scene), quiet)
        if rerun_sink is not None and serve is not None:
            serve_until_interrupted(rerun_sink, quiet)
    finally:
        if rerun_sink is not None:
            rerun_sink.shutdown()  # a served run interrupted early still finishes its file
    return stats


def load_resume_state(path: Path | None, digest: str, quiet: bool):
    """The checkpoint to resume from, checked against the scene."""
    from sim.checkpoint import read_checkpoint, thread_count

    if path is None:
        raise InputError("--resume: no checkpoint file; give --checkpoint FILE or an output (-o, --mesh-dir)")
    state = read_checkpoint(path)
    if state.scene_hash != digest:
        raise InputError(f"{path}: this checkpoint was written for a different scene (or different mesh "
                         "files); run without --resume to start over")
    if state.threads != thread_count() and not quiet:
        err.print(f"[yellow]warning: the checkpoint was written with (numba, ipctk) threads {state.threads}, "
                  f"this run has {thread_count()}: frames will differ from an uninterrupted run by round-off "
                  "(use the same thread count, and --deterministic for both runs)")
    if not quiet:
        err.print(f"[dim]resuming after frame {state.frame} (t = {state.state.t:.4g} s) from {path}")
    return state


def stopped_message(last: int, total: int, checkpoint: Path | None, outputs) -> str:
    done = ", ".join(str(p) for p in outputs if p is not None)
    saved = (f"checkpoint written to {checkpoint}; run the same command with --resume to continue"
             if checkpoint is not None else "no checkpoint (no file output; pass --checkpoint FILE to get one)")
    return (f"stopped after frame {last} of {total}"
            + (f"; {done} hold every completed frame" if done else "") + f"; {saved}")


def default_checkpoint(rrd: Path | None, mesh_dir: Path | None) -> Path | None:
    """Next to the first file output: run.rrd -> run.ckpt.npz, frames/ -> frames.ckpt.npz."""
    if rrd is not None:
        return rrd.with_name(f"{rrd.stem}.ckpt.npz")
    if mesh_dir is not None:
        return mesh_dir.with_name(f"{mesh_dir.name}.ckpt.npz")
    return None


class StopOnSignal:
    """SIGINT/SIGTERM/SIGHUP while active: the first asks the run to stop after the current
    step (`requested()`), a second exits at once (status 130): files being written are
    removed, the recording keeps what was flushed (sim.files.remove_partial_files).
    Handlers are restored on exit."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self, quiet: bool = False):
        self.quiet = quiet
        self.count = 0
        self._previous = {}

    def requested(self) -> bool:
        return self.count > 0

    def _handle(self, signum, _frame) -> None:
        self.count += 1
        if self.count > 1:
            os.write(2, b"\ninterrupted again: exiting now\n")
            remove_partial_files()
            os._exit(130)
        os.write(2, f"\n{signal.Signals(signum).name}: stopping after the current step "
                    "(send it again to quit at once)\n".encode())

    def __enter__(self) -> "StopOnSignal":
        if threading.current_thread() is threading.main_thread():  # signal() works only there
            for s in self.SIGNALS:
                self._previous[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for s, h in self._previous.items():
            signal.signal(s, h)
        self._previous.clear()


def step_line(st) -> str:
    """Compact live statistics of one step for the progress bar."""
    line = (f"newton {st.newton_iterations:3d}  |dC|/dt {st.residual:.1e}  {st.t_total * 1e3:6.0f} ms "
            f"(asm {st.t_assembly * 1e3:.0f} fact {st.t_factorization * 1e3:.0f} "
            f"solve {st.t_solve * 1e3:.0f} ccd {st.t_ccd * 1e3:.0f} ls {st.t_line_search * 1e3:.0f})")
    if "contact_count" in st.extra:
        line += f"  contacts {st.extra['contact_count']:.0f}"
    if "min_distance" in st.extra:
        line += f"  dmin {st.extra['min_distance']:.1e} m"
    if "seam_gap_max" in st.extra:
        line += f"  seam gap {st.extra['seam_gap_max'] * 1e3:.2f} mm"
    if st.extra.get("seam_pairs_blocked"):
        line += f"  blocked {st.extra['seam_pairs_blocked']:.0f}"
    return line


def check_outputs(rrd: Path | None, mesh_dir: Path | None, checkpoint: Path | None, render_to: Path | None,
                  quiet: bool) -> None:
    """Refuse, before the run, outputs that could not be written at its end (a folder
    named as the recording, a recording named .mp4, a place that cannot be written); say
    so when the run writes nothing (unless quiet: -q, or streaming to a viewer)."""
    if rrd is not None:
        output_file(rrd, (".rrd",), "the recording (-o, [output] rrd)")
    if mesh_dir is not None:
        output_folder(mesh_dir, "the per-frame mesh folder (--mesh-dir, [output] mesh_dir)")
    if checkpoint is not None:
        output_file(checkpoint, (".npz",), "the checkpoint (--checkpoint)")
    if render_to is not None:
        check_render_target(render_to)
    if rrd is None and mesh_dir is None and render_to is None and not quiet:
        err.print("[yellow]warning:[/] this run writes no output (no -o, --mesh-dir or --render, and no "
                  "\\[output] in the scene): only the statistics are printed")


def check_render_target(out: Path) -> None:
    """A video (.mp4, .gif) or a folder of PNG frames that can be written."""
    from viz.render import output_kind

    try:
        kind = output_kind(out)
    except ValueError as e:
        raise InputError(str(e)) from None
    if kind == "png":
        output_folder(out, "the PNG frames (--render)")
    else:
        output_file(out, (f".{kind}",), "the video (--render)")


def override_frames(scene: Scene, frames: int | None) -> Scene:
    """The scene with [time] frames = `frames` (--frames), checked as the scene key is."""
    if frames is None:
        return scene
    frames = scene_option("--frames", frames, TimeSpec, "frames")
    return dataclasses.replace(scene, time=dataclasses.replace(scene.time, frames=frames))


UP_VECTORS = {"z": (0.0, 0.0, 1.0), "y": (0.0, 1.0, 0.0)}  # --up


def _upright(options, scene: Scene):
    """Render options with the scene's vertical (against gravity) unless given."""
    from viz.render import RenderOptions

    options = options or RenderOptions()
    g = np.asarray(scene.load.gravity, float)
    if options.up is None and np.linalg.norm(g) > 0:
        options = dataclasses.replace(options, up=tuple(-g / np.linalg.norm(g)))
    return options


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
        f"{s['factorization_fraction']:.0%}, solve {s['solve_fraction']:.0%}, CCD "
        f"{s['ccd_fraction']:.0%}, line search {s['line_search_fraction']:.0%}"
        + (f"; [yellow]{unconverged} steps hit the iteration cap" if unconverged else "")
    )
    for path in outputs:
        if path is not None:
            err.print(f"wrote {path}")


def print_seam_summary(sim) -> None:
    """The seams at the end: largest gaps, and matched pairs that could not be sewn."""
    gaps = sim.seam_gaps()
    if not gaps:
        return
    worst = sorted(gaps, key=gaps.get, reverse=True)
    above = [name for name in worst if gaps[name] > 1e-3]
    line = (f"seam gaps at the end: largest {gaps[worst[0]] * 1e3:.2f} mm ({worst[0]}), "
            f"{len(above)} of {len(gaps)} seams above 1 mm")
    if above:
        line += " (" + ", ".join(f"{n} {gaps[n] * 1e3:.2f}" for n in above[:8]) + (", ..." if len(above) > 8 else "") + ")"
    held = sim.seam_pairs_held_open()
    if held:
        line += f"; {held} matched vertex pairs held open (a merge would cross cloth)"
    err.print(line)


def print_logging_cost(log_seconds: float, sim_seconds: float) -> None:
    share = f" ({log_seconds / sim_seconds:.1%} of the simulation time)" if sim_seconds > 0 else ""
    err.print(f"[dim]Rerun logging took {log_seconds:.2f} s{share}")


def run(args) -> int:
    from garment.dress.scene_file import leaves_placement

    data = read_scene_data(args.scene)
    scene = parse_scene(data, args.scene)
    out = scene.output
    rrd = args.output if args.output is not None else out.rrd
    mesh_dir = args.mesh_dir if args.mesh_dir is not None else out.mesh_dir
    if leaves_placement(data):
        scene = placed_for_dressing(scene, data, rrd, args.quiet)
    scene = override_frames(scene, args.frames)
    options = render_options(args) if args.render is not None else None
    number_option("--checkpoint-every", args.checkpoint_every, ge=0)
    number_option("--max-splits", args.max_splits, ge=0, le=30)
    if args.serve is not None:
        number_option("--serve", args.serve, ge=0, le=65535)
    checkpoint = args.checkpoint if args.checkpoint is not None else default_checkpoint(rrd, mesh_dir)
    simulate(scene, rrd, mesh_dir, args.format or out.mesh_format, args.quiet, connect=args.connect,
             serve=args.serve, control_net=args.control_net, render_to=args.render, render_options=options,
             checkpoint=checkpoint, checkpoint_every=args.checkpoint_every, resume=args.resume,
             max_splits=args.max_splits, deterministic=args.deterministic)
    if not args.quiet:
        print_how_to_open(rrd, args.render, mesh_dir, resumed=args.resume)
    return 0


def placed_for_dressing(scene: Scene, data: dict, rrd: Path | None, quiet: bool) -> Scene:
    """A scene that leaves the garment's start to the toolkit, dressed as `garment dress`
    dresses (garment/dress/scene_file.py); the placed garment goes beside the recording."""
    from garment.dress.scene_file import dressed_scene

    folder = rrd.with_suffix("") if rrd is not None else Path("out") / scene.name
    if not quiet:
        err.print(f"[dim]{scene.path}: no pre-roll or body inset given, so the garment is placed and sewn as "
                  f"`garment dress` does it; placed garment: {folder / 'patches.json'}")
    return dressed_scene(data, scene, folder)


def print_how_to_open(rrd: Path | None, video: Path | None = None, mesh_dir: Path | None = None,
                      resumed: bool = False) -> None:
    """On stdout, after a run: where its outputs are and the commands that open them (a
    resumed run's recording is all its parts, run.rrd run.part2.rrd ...)."""
    from shlex import join

    from sim.driver import segments

    files = (segments(rrd) if resumed else [rrd] if rrd.exists() else []) if rrd is not None else []
    if files:
        names = [str(p) for p in files]
        print(f"\nrecording: {'  '.join(str(p.resolve()) for p in files)}\n"
              f"  view it:  {join(['rerun', *names])}  (on a machine with a display)\n"
              f"            {join(['garment', 'view', *names])}  (in a browser: Rerun's web viewer on localhost)\n"
              f"  as USD:   {join(['garment', 'inspect', names[-1], '--export', str(files[-1].with_suffix('.usd'))])}")
    if video is not None and video.exists():
        print(f"video:     {video.resolve()}")
    if mesh_dir is not None and mesh_dir.exists():
        print(f"meshes:    {mesh_dir.resolve()}")


def render_options(args):
    """RenderOptions of --render-size, --fps, --orbit and --up, checked."""
    from viz.render import RenderOptions, parse_size

    try:
        size = parse_size(args.render_size)
    except ValueError as e:
        raise InputError(f"--render-size: {e}") from None
    number_option("--fps", args.fps, gt=0, le=1000)
    return RenderOptions(size=size, fps=args.fps, orbit=args.orbit, up=UP_VECTORS.get(args.up),
                         follow=args.follow)


def add_render_options(p) -> None:
    """--render and its options; shared with `garment inspect`."""
    p.add_argument("--render", type=Path, metavar="OUT",
                   help="render the frames off-screen to OUT: .mp4, .gif, or a folder of PNG frames")
    p.add_argument("--render-size", default="640x480", metavar="WxH", help="image size in pixels (640x480)")
    p.add_argument("--orbit", action="store_true", help="orbit the camera once around the scene")
    p.add_argument("--follow", action="store_true",
                   help="keep the camera on each frame's centre (a body that travels stays large)")
    p.add_argument("--fps", type=float, default=30.0, help="video frames per second (30)")
    p.add_argument("--up", choices=tuple(UP_VECTORS), help="the vertical of the picture "
                   "and the up axis of a USD export (simulate: against the scene's gravity; inspect: z)")


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
    s.add_argument("--checkpoint", type=Path, metavar="FILE",
                   help="state file for --resume (default: next to the first output, run.rrd -> run.ckpt.npz)")
    s.add_argument("--checkpoint-every", type=int, default=10, metavar="K",
                   help="write the checkpoint every K frames (10; 0: only at the end, on a signal or failure)")
    s.add_argument("--resume", action="store_true",
                   help="continue from the checkpoint; the recording continues in run.part2.rrd, ...")
    s.add_argument("--max-splits", type=int, default=4, metavar="N",
                   help="retry a failing step as halves down to dt / 2^N before giving up (4)")
    s.add_argument("--deterministic", action="store_true",
                   help="run contact queries on one thread: reruns and resumed runs repeat frames bit for bit")
    s.add_argument("-q", "--quiet", action="store_true")
    s.set_defaults(func=run)
