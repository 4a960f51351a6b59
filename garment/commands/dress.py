"""`garment dress PATTERN --body BODY -o OUTDIR [--set KEY=VALUE ...] [--json] [-q]`,
or `garment dress SCENE.toml -o OUTDIR` for a scene that names the garment's `source`
and the body's `mesh`: dress the body in the garment with the defaults of
garment/dress/job.py. Exit status 0 when the garment is dressed ("ok"), 3 for any
failure category (the report says which), 2 for bad input, 130 when interrupted."""

from __future__ import annotations

import json
from pathlib import Path

from sim.errors import InputError, Interrupted

from .console import err, print_table, progress

REPORT_COLUMNS = ("status", "seam_gap_max_mm", "crossings", "dofs", "seconds", "settle_time_s")


def from_scene(path: Path) -> tuple[Path, Path, dict]:
    """The garment source and body mesh a scene file names (relative to the scene), and
    the settings it chooses when it leaves the garment's start to the toolkit
    (garment/dress/scene_file.py; a scene that places its garment by hand gives none)."""
    from garment.dress.scene_file import dress_settings, leaves_placement
    from garment.scene.read import read_scene_data

    data = read_scene_data(path)
    try:
        source = data["garment"][0]["source"]
        body = data["obstacle"][0]["mesh"]
    except (KeyError, IndexError, TypeError):
        raise InputError(f"{path}: `garment dress` needs a scene with [[garment]] source and an [[obstacle]] "
                         "mesh (the body)") from None
    settings = dress_settings(data, path) if leaves_placement(data) else {}
    return (path.parent / source).resolve(), (path.parent / body).resolve(), settings


def parse_settings(pairs) -> dict:
    out = {}
    for pair in pairs or ():
        key, sep, value = pair.partition("=")
        if not sep:
            raise InputError(f"--set {pair!r}: expected KEY=VALUE, e.g. --set knot_span_mm=30")
        out[key.strip()] = value.strip()
    return out


def run(args) -> int:
    from garment.dress.job import dress
    from sim.files import input_file

    from .simulate import StopOnSignal

    pattern, chosen = args.pattern, {}
    if pattern.suffix.lower() == ".toml":
        pattern, body, chosen = from_scene(input_file(pattern, "scene"))
        body = args.body or body
    else:
        if args.body is None:
            raise InputError("garment dress: give the body to dress with --body BODY.obj")
        body = args.body
    input_file(pattern, "garment pattern")
    input_file(body, "body mesh")
    overrides = {**chosen, **parse_settings(args.set)}
    quiet = args.quiet or args.json
    with progress(quiet) as bar, StopOnSignal(quiet) as stop:
        task = bar.add_task(Path(pattern).stem[:24], total=None, status="")

        def on_frame(k, n, st):
            if stop.requested():
                raise KeyboardInterrupt
            gap = st.extra.get("seam_gap_max")
            bar.update(task, completed=k, total=n, status=f"newton {st.newton_iterations}"
                       + (f" gap {gap * 1e3:.1f} mm" if gap is not None else ""))

        try:
            report = dress(pattern, body, args.output, overrides, on_frame=on_frame)
        except KeyboardInterrupt:
            raise Interrupted(f"stopped; {args.output} holds what was written so far") from None
    if args.json:
        print(json.dumps(report, indent=1))
    elif not args.quiet:
        print_table(f"garment dress {Path(pattern).name}", REPORT_COLUMNS, [report])
        if report.get("error"):
            err.print(f"{report['status']}: {report['error']}")
        print(f"\noutputs in {Path(args.output).resolve()}: run.rrd, garment.obj, report.json, patches.json\n"
              f"  view it: garment view {Path(args.output) / 'run.rrd'}")
    return 0 if report["status"] == "ok" else 3


def register(sub) -> None:
    d = sub.add_parser("dress", help="dress a body in a garment pattern with defaults: conform, place, sew, "
                                     "settle")
    d.add_argument("pattern", type=Path, help="GarmentCode JSON, a panel mesh, or a scene (.toml) naming both")
    d.add_argument("--body", type=Path, help="the body: a static mesh (OBJ, PLY, ...) in any unit and up axis")
    d.add_argument("-o", "--output", type=Path, required=True, help="output folder")
    d.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="change a default (garment/dress/job.py DressOptions), e.g. knot_span_mm=30")
    d.add_argument("--json", action="store_true", help="print the report as JSON")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=run)
