"""`garment demo`: the bundled default, the upright hanging cloth for 1 s -> out/demo.rrd."""

from __future__ import annotations

from pathlib import Path

from .simulate import simulate


def run(args) -> int:
    from garment.bench.common import scene as bundled

    n = args.resolution
    simulate(bundled("hanging", (n, n), frames=args.frames), args.output, None, quiet=args.quiet)
    return 0


def register(sub) -> None:
    d = sub.add_parser("demo", help="the bundled default: upright hanging cloth for 1 s")
    d.add_argument("-o", "--output", type=Path, default=Path("out/demo.rrd"))
    d.add_argument("--resolution", type=int, default=40, help="control points per side")
    d.add_argument("--frames", type=int, default=100, help="frames of 0.01 s")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=run)
