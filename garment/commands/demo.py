"""`garment demo`: the CC0 MakeHuman body dances a forward jump of CMU motion capture
01_01 in a GarmentCode skirt of 9 panels (graded to the body: assets/garments/
make_demo_skirt.py), dressed on its bind pose by `garment dress`'s mechanism
(garment/dress/) -> out/demo.rrd, out/demo.mp4 (a camera that follows the dancer) and
out/demo.usd.

During the 1 s pre-roll the body holds its A-pose, slimmed: the seams close weightless in
the first half, the body grows back in the second and blends into the first motion frame
over its last 0.2 s; then gravity ramps in as the dance starts."""

from __future__ import annotations

from pathlib import Path

from .simulate import print_how_to_open, simulate

ROOT = Path(__file__).resolve().parents[2]
PATTERN = ROOT / "assets" / "garments" / "skirt_makehuman.json"
PREROLL = 1.0  # s
# Of the clip's lively stretch (garment.io.rigged.LIVELY): the first jump and landing. At
# 2.0-2.2 s the crouch after the second landing brings the hands to within 2-3 cm of the
# hips (the skinned mesh nearly meets itself) and traps the skirt between them.
SECONDS = 1.8


def body_table() -> dict:
    """The dancing body as a scene [[obstacle]] table (docs/bodies.md)."""
    from garment.io.rigged import LIVELY, MAKEHUMAN_CMU, MAKEHUMAN_JOINTS

    d = MAKEHUMAN_CMU
    start = LIVELY[0] / 120.0  # the BVH is 120 fps
    return {"name": "body", "scale": 0.1, "up": "y", "blend": 0.2,
            "skin": {"mesh": str(d / "body.obj"), "group": "body", "rig": str(d / "rig.cmu_mb.json"),
                     "weights": str(d / "weights.cmu_mb.json"), "motion": str(d / "01_01.bvh"),
                     "joints": [list(kv) for kv in MAKEHUMAN_JOINTS.items()],
                     "start": start, "end": start + SECONDS}}


def demo_scene(out: Path, frames: int | None):
    """Place the skirt around the body's bind pose and build the scene."""
    from garment.dress.frame import BodyFrame
    from garment.dress.job import DressOptions, dress_scene, place_garment
    from garment.io.rigged import MAKEHUMAN_CMU as d
    from garment.io.rigged import read_makehuman, rig_to_scene

    options = DressOptions()
    bind = rig_to_scene(read_makehuman(d / "body.obj", "body", d / "rig.cmu_mb.json", d / "weights.cmu_mb.json"),
                        0.1, "y", (0.0, 0.0, 0.0))  # the A-pose, in the scene's frame
    folder = out.with_suffix("")
    folder.mkdir(parents=True, exist_ok=True)
    place_garment(PATTERN, BodyFrame(1.0, "z", "m"), bind.vertices, bind.faces, options, folder)
    per_frame = options.dt * options.steps_per_frame
    frames = frames or int(round((PREROLL + SECONDS) / per_frame))
    return dress_scene(folder / "patches.json", body_table(), options, preroll=PREROLL, frames=frames, name="demo",
                       drag=False)


def run(args) -> int:
    from garment.io.usd import write_usd
    from viz.recording import load_recording
    from viz.render import RenderOptions

    scene = demo_scene(args.output, args.frames)
    video = None if args.no_video else args.output.with_suffix(".mp4")
    simulate(scene, args.output, None, quiet=args.quiet, render_to=video,
             render_options=RenderOptions(size=(640, 640), fps=25.0, azimuth=-70.0, elevation=10.0, follow=True))
    usd = args.output.with_suffix(".usd")
    write_usd(load_recording(args.output), usd)
    print_how_to_open(args.output, video)
    print(f"USD:       {usd.resolve()}")
    return 0


def register(sub) -> None:
    d = sub.add_parser("demo", help="dress the bundled CC0 body in a 9-panel skirt and dance a CMU motion clip")
    d.add_argument("-o", "--output", type=Path, default=Path("out/demo.rrd"))
    d.add_argument("--frames", type=int,
                   help="frames of 0.04 s (default: the 1 s pre-roll that sews the skirt, then 1.8 s of dance)")
    d.add_argument("--no-video", action="store_true", help="skip the MP4")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=run)
