"""`garment inspect RUN.rrd [--json] [--frame K --export out.obj|ply [--mesh NAME]]
[--export out.usd [--mesh NAME] [--up z|y]]
[--render out.mp4|out.gif|DIR [--render-size WxH] [--orbit] [--fps F]]`.

Summarizes a Rerun recording (ids, entities, frames, time range, vertex counts, scalar
statistics), exports a mesh at a frame (OBJ, PLY) or every frame (USD, garment/io/usd.py),
or renders the recording with PyVista. A damaged
(truncated, corrupted) recording still gives whatever frames are intact, with an error
line on stderr and exit status 1.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from sim.errors import InputError
from sim.files import output_file

from .console import err, print_table
from .simulate import add_render_options, check_render_target, render_frames, render_options


def run(args) -> int:
    from viz.recording import load_recording

    # Outputs and options first: nothing is read when they could not be written.
    if args.export is not None:
        output_file(args.export, (".obj", ".ply", ".usd", ".usda", ".usdc"), "the exported mesh (--export)")
    options = None
    if args.render is not None:
        check_render_target(args.render)
        options = render_options(args)
    rec = load_recording(args.recording)
    if args.json:
        print(json.dumps(rec.summary(), indent=1))
    elif args.export is None and args.render is None:
        print_summary(rec.summary())
    if args.export is not None:
        export(rec, args)
    elif args.frame is not None or args.mesh is not None:
        raise InputError("--frame and --mesh go with --export")
    if args.render is not None:
        render_recording(rec, args.render, options, args.quiet)
    if rec.damaged:
        # Plain print, like the CLI's other errors: one unwrapped line.
        print(f"error: {rec.path} is damaged ({rec.damaged}); recovered {len(rec.frames)} intact frames",
              file=sys.stderr)
        return 1
    return 0


def _frame_index(rec, k: int) -> int:
    """Frame index K of the `frame` timeline; negative counts from the last intact frame."""
    frames = rec.frames
    if not frames:
        raise InputError(f"{rec.path}: no intact frames")
    if k < 0:
        if -k > len(frames):
            raise InputError(f"--frame {k}: the recording has {len(frames)} intact frames")
        return frames[k]
    if k not in frames:
        raise InputError(f"--frame {k}: not an intact frame of {rec.path} (frames {frames[0]}-{frames[-1]})")
    return k


def export(rec, args) -> None:
    from garment.io.usd import SUFFIXES

    if args.export.suffix.lower() in SUFFIXES:
        export_usd(rec, args)
        return
    from viz.recording import export_mesh, garment_mesh

    k = _frame_index(rec, args.frame if args.frame is not None else -1)
    names = [args.mesh] if args.mesh is not None else None
    verts, faces = garment_mesh(rec, k, names)
    export_mesh(args.export, verts, faces)
    if not args.quiet:
        what = args.mesh or " + ".join(rec.cloth_names)
        err.print(f"wrote {args.export}: {what} at frame {k} (t = {rec.time_of(k):.4g} s), "
                  f"{len(verts)} vertices, {len(faces)} triangles")


def export_usd(rec, args) -> None:
    """Every intact frame of every mesh (or of --mesh) to one USD file."""
    from garment.io.usd import write_usd

    if args.frame is not None:
        raise InputError(f"--frame: {args.export.name} gets every frame (--frame is for .obj and .ply)")
    names = [args.mesh] if args.mesh is not None else None
    write_usd(rec, args.export, names, up=args.up or "z")  # SIGTERM unwinds (garment.cli): no temporary file left
    if not args.quiet:
        frames = rec.frames
        what = args.mesh or " + ".join(rec.meshes)
        err.print(f"wrote {args.export}: {what}, {len(frames)} frames ({frames[0]}-{frames[-1]}, "
                  f"t = {rec.time_of(frames[0]):.4g} - {rec.time_of(frames[-1]):.4g} s), "
                  f"up axis {(args.up or 'z').upper()}")


def render_recording(rec, out: Path, options, quiet: bool) -> None:
    from viz.render import recording_frames, recording_meshes

    if not rec.frames:
        raise InputError(f"{rec.path}: no intact frames to render")
    render_frames(recording_meshes(rec), list(recording_frames(rec)), out, options, quiet)


def print_summary(s: dict) -> None:
    """The summary as text: a header, a mesh table and a statistics table."""
    from rich.console import Console

    out = Console(highlight=False)
    out.print(f"[bold]{s['path']}[/bold]  recording {s['recording_id']}  application {s['application_id']}"
              + (f"  name {s['name']!r}" if s["name"] else ""))
    if s["frames"]:
        (f0, f1), (t0, t1) = s["frame_range"], s["time_range"]
        out.print(f"{s['frames']} frames ({f0}-{f1}), sim_time {t0:.4g} s - {t1:.4g} s")
    else:
        out.print("no intact frames")
    out.print("entities: " + ", ".join(f"{e} ({', '.join(a) or '-'})" for e, a in s["entities"].items()))
    meshes = [{"mesh": name, **m} for name, m in s["meshes"].items()]
    if meshes:
        print_table("meshes", ["mesh", "kind", "vertices", "faces", "frames_logged"], meshes)
    stats = [{"statistic": name, **v} for name, v in s["stats"].items()]
    if stats:
        print_table("per-step statistics", ["statistic", "count", "min", "mean", "max"], stats)


def register(sub) -> None:
    p = sub.add_parser("inspect", help="summarize, export from or render a Rerun recording (.rrd)")
    p.add_argument("recording", type=Path)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.add_argument("--frame", type=int, help="frame index for --export (negative: from the end; default last)")
    p.add_argument("--export", type=Path, metavar="OUT",
                   help="write the garment mesh at --frame to OUT (.obj or .ply), or every frame of "
                        "every cloth piece and body to OUT (.usd, .usda, .usdc; up axis from --up, z)")
    p.add_argument("--mesh", help="export only this mesh (a cloth piece or a body)")
    add_render_options(p)
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=run)
