"""`garment view RUN.rrd [--port N] [--grpc-port M]`: serve a recording in Rerun's web
viewer on 127.0.0.1 (viz/web_viewer.py) and print the URL; the way to look at a run on a
headless machine (through an SSH tunnel from another one). Serves until Ctrl-C or
SIGTERM (exit 130); a missing or unreadable file or a taken port exits 2."""

from __future__ import annotations

from pathlib import Path

from rich.markup import escape

from sim.errors import InputError, Interrupted, RunStopped

from .console import err


def run(args) -> int:
    from viz.recording import load_recording
    from viz.web_viewer import WebViewer

    from .signals import terminate_raises_interrupt

    for option, port in (("--port", args.port), ("--grpc-port", args.grpc_port)):
        if not 1 <= port <= 65535:
            raise InputError(f"{option}: a port is 1-65535, got {port}")
    rec = load_recording(args.recording)  # InputError: missing, or not a Rerun recording
    viewer = WebViewer(rec, web_port=args.port, grpc_port=args.grpc_port)
    with terminate_raises_interrupt():
        try:
            viewer.start()
        except ConnectionError as e:
            raise InputError(f"{args.recording}: {e}") from None
        except RuntimeError as e:
            raise RunStopped(f"{args.recording}: {e}") from None
        try:
            if not args.quiet:
                describe(rec, viewer)
            print(viewer.url, flush=True)
            status = viewer.wait()
        except KeyboardInterrupt:
            raise Interrupted(f"stopped serving {args.recording}") from None
        finally:
            viewer.stop()
    raise RunStopped(f"the Rerun web viewer stopped by itself (status {status})")


def describe(rec, viewer) -> None:
    """What is served and how to reach it, on stderr (the URL alone goes to stdout)."""
    frames = rec.frames
    what = (f"{len(frames)} frames, t = {rec.time_of(frames[0]):.4g} - {rec.time_of(frames[-1]):.4g} s"
            if frames else "no intact frames")
    if rec.damaged:
        err.print(f"[yellow]warning:[/] {escape(str(rec.path))} is damaged ({escape(rec.damaged)}); "
                  "serving what rerun can read")
    err.print(f"serving {escape(str(rec.path))} ({what}) in Rerun's web viewer on this machine only; Ctrl-C to stop.\n"
              f"From another machine: ssh -L {viewer.web_port}:127.0.0.1:{viewer.web_port} "
              f"-L {viewer.grpc_port}:127.0.0.1:{viewer.grpc_port} THIS_HOST, then open the URL there.",
              highlight=False, soft_wrap=True)


def register(sub) -> None:
    from viz.web_viewer import GRPC_PORT, WEB_PORT

    v = sub.add_parser("view", help="serve a recording (.rrd) in Rerun's web viewer on localhost and print the URL")
    v.add_argument("recording", type=Path)
    v.add_argument("--port", type=int, default=WEB_PORT, help=f"port of the web page ({WEB_PORT})")
    v.add_argument("--grpc-port", type=int, default=GRPC_PORT,
                   help=f"port the page fetches the recording from ({GRPC_PORT})")
    v.add_argument("-q", "--quiet", action="store_true", help="print only the URL")
    v.set_defaults(func=run)
