"""`garment view RUN.rrd [MORE.rrd ...] [--port N] [--grpc-port M]`: serve recordings in
Rerun's web viewer on 127.0.0.1 (viz/web_viewer.py) and print the URL; the way to look at
a run on a headless machine (through an SSH tunnel from another one). Several files: the
parts of a resumed run, `run.rrd run.part2.rrd`. Serves until Ctrl-C or SIGTERM (exit
130); a missing or unreadable file or a taken port exits 2."""

from __future__ import annotations

from pathlib import Path

from rich.markup import escape

from sim.errors import InputError, Interrupted, RunStopped

from .console import err


def run(args) -> int:
    from viz.recording import load_recording
    from viz.web_viewer import WebViewer

    for option, port in (("--port", args.port), ("--grpc-port", args.grpc_port)):
        if not 1 <= port <= 65535:
            raise InputError(f"{option}: a port is 1-65535, got {port}")
    recordings = [load_recording(p) for p in args.recordings]  # InputError: missing, not a recording
    names = " ".join(str(p) for p in args.recordings)
    viewer = WebViewer(recordings, web_port=args.port, grpc_port=args.grpc_port)
    # SIGTERM arrives as KeyboardInterrupt (garment.cli), like Ctrl-C.
    try:
        viewer.start()
        if not args.quiet:
            describe(recordings, viewer)
        print(viewer.url, flush=True)
        status = viewer.wait()
    except ConnectionError as e:
        raise InputError(f"{names}: {e}") from None
    except RuntimeError as e:
        raise RunStopped(f"{names}: {e}") from None
    except KeyboardInterrupt:
        raise Interrupted(f"stopped serving {names}") from None
    finally:
        viewer.stop()
    raise RunStopped(f"the Rerun web viewer stopped by itself (status {status})")


def describe(recordings, viewer) -> None:
    """What is served and how to reach it, on stderr (the URL alone goes to stdout)."""
    for rec in recordings:
        frames = rec.frames
        what = (f"{len(frames)} frames, t = {rec.time_of(frames[0]):.4g} - {rec.time_of(frames[-1]):.4g} s"
                if frames else "no intact frames")
        if rec.damaged:
            err.print(f"[yellow]warning:[/] {escape(str(rec.path))} is damaged ({escape(rec.damaged)}); "
                      "serving what rerun can read", soft_wrap=True)
        err.print(f"serving {escape(str(rec.path))} ({what})", highlight=False, soft_wrap=True)
    err.print("in Rerun's web viewer on this machine only; Ctrl-C to stop.\n"
              f"From another machine: ssh -L {viewer.web_port}:127.0.0.1:{viewer.web_port} "
              f"-L {viewer.grpc_port}:127.0.0.1:{viewer.grpc_port} THIS_HOST, then open the URL there.",
              highlight=False, soft_wrap=True)


def register(sub) -> None:
    from viz.web_viewer import GRPC_PORT, WEB_PORT

    v = sub.add_parser("view", help="serve recordings (.rrd) in Rerun's web viewer on localhost and print the URL")
    v.add_argument("recordings", type=Path, nargs="+", metavar="RUN.rrd",
                   help="a recording; several: the parts of a resumed run (run.rrd run.part2.rrd)")
    v.add_argument("--port", type=int, default=WEB_PORT, help=f"port of the web page ({WEB_PORT})")
    v.add_argument("--grpc-port", type=int, default=GRPC_PORT,
                   help=f"port the page fetches the recording from ({GRPC_PORT})")
    v.add_argument("-q", "--quiet", action="store_true", help="print only the URL")
    v.set_defaults(func=run)
