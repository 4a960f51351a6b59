"""`garment demo`: conform the bundled poncho, sew it onto the dancing Rumba body and
simulate a short clip -> out/demo.rrd and out/demo.mp4 (assets/scenes/poncho_rumba.toml)."""

from __future__ import annotations

from pathlib import Path

from .simulate import override_frames, print_how_to_open, simulate

SCENE = Path(__file__).resolve().parents[2] / "assets" / "scenes" / "poncho_rumba.toml"


def run(args) -> int:
    from garment.scene import load_scene
    from viz.render import RenderOptions

    scene = override_frames(load_scene(SCENE), args.frames)
    video = None if args.no_video else args.output.with_suffix(".mp4")
    simulate(scene, args.output, None, quiet=args.quiet, render_to=video,
             render_options=RenderOptions(size=(640, 640), fps=25.0, azimuth=-70.0, elevation=10.0))
    print_how_to_open(args.output, video)
    return 0


def register(sub) -> None:
    d = sub.add_parser("demo", help="sew the bundled poncho onto the dancing body and simulate a short clip")
    d.add_argument("-o", "--output", type=Path, default=Path("out/demo.rrd"))
    d.add_argument("--frames", type=int, default=75,
                   help="frames of 0.04 s (the first 0.3 s are the pre-roll that sews the seams)")
    d.add_argument("--no-video", action="store_true", help="skip the MP4")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=run)
