"""`garment conform INPUT -o OUTDIR [--knot-span MM | --control-points NxM] [--corners ...]`.

INPUT is a panel mesh (OBJ with `vt` layout, `g` panels and `seam`/`stitch` lines, or any
flat mesh trimesh/meshio read) or a GarmentCode pattern (.json). Every panel is conformed;
the patches, seams and reports go to OUTDIR/patches.json (format: garment/io/patchfile.py).
A panel with deep darts is cut along its darts' continuations into several patches
(`--split`, conform/split.py): one table row per patch (`skirt_back.0`, ...) and a summary
row for the panel. A panel that cannot be converted is reported and skipped; the exit
status is then 1.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path

import numpy as np
from rich.markup import escape

from sim.errors import InputError, printable
from sim.files import atomic_write, output_file, output_folder

from garment.io.garments import read_pattern
from garment.scene import GarmentSpec

from .console import err, print_table, progress
from .options import number_option, scene_option

COLUMNS = ("panel", "status", "control_net", "boundary_error_mm", "tolerance_mm", "jacobian_min_max",
           "min_corner_angle_deg", "area_error_pct", "reduced_area_error_pct", "seconds")


def parse_corners(specs: list[str]) -> dict:
    """`PANEL=i,j,k,l` (input vertex ids) or `PANEL=x,y;x,y;x,y;x,y` (rest positions, m)."""
    out = {}
    for spec in specs or []:
        name, sep, rest = spec.partition("=")
        if not sep or not name:
            raise InputError(f"--corners {spec!r}: expected PANEL=i,j,k,l or PANEL=x,y;x,y;x,y;x,y")
        try:
            if ";" in rest:
                corners = [tuple(float(x) for x in p.split(",")) for p in rest.split(";")]
                if any(len(c) != 2 or not all(np.isfinite(c)) for c in corners):
                    raise ValueError
            else:
                corners = [int(x) for x in rest.split(",")]
        except ValueError:
            raise InputError(f"--corners {spec!r}: expected 4 integers or 4 x,y pairs") from None
        if len(corners) != 4:
            raise InputError(f"--corners {spec!r}: needs exactly 4 corners, got {len(corners)}")
        out[name] = corners
    return out


def row(name: str, rep: dict | None, error: str | None) -> dict:
    if rep is None:
        return {"panel": name, "status": "failed", "error": error}
    r = {
        "panel": name,
        "status": rep["status"],
        "control_points": rep["control_points"],
        "control_net": "x".join(str(c) for c in rep["control_points"]),
        "boundary_error_mm": rep["boundary_error_mm"],
        "tolerance_mm": rep["tolerance_mm"],
        "min_jacobian_ratio": rep["min_jacobian_ratio"],
        "max_jacobian_ratio": rep["max_jacobian_ratio"],
        "jacobian_min_max": f"{rep['min_jacobian_ratio']:.3f} / {rep['max_jacobian_ratio']:.2f}",
        "min_corner_angle_deg": rep["min_corner_angle_deg"],
        "area_error_pct": rep.get("area_error_gauss2_pct"),
        "reduced_area_error_pct": rep.get("area_error_reduced_pct"),
        "inverted_points": rep["inverted_points"],
        "seconds": rep["seconds"],
    }
    return r


def split_row(name: str, summary: dict) -> dict:
    """The summary row of a panel split into several patches."""
    return {
        "panel": name,
        "status": "split",
        "control_net": f"{len(summary['patches'])} patches",
        "area_error_pct": summary.get("area_error_gauss2_pct"),
        "reduced_area_error_pct": summary.get("area_error_reduced_pct"),
        "seconds": summary["seconds"],
    }


def with_split_rows(rows: list[dict], splits: dict) -> list[dict]:
    """rows with each split panel's summary row after its last patch's row."""
    out = list(rows)
    for name, summary in splits.items():
        at = max((k for k, r in enumerate(out) if r["panel"] in summary["patches"]), default=len(out) - 1)
        out.insert(at + 1, split_row(name, summary))
    return out


def run(args) -> int:
    from conform.mips import MipsOptions
    from conform.pipeline import ConformOptions, check_request, conform_all
    from garment.io.patchfile import save_patchset

    if args.knot_span is not None and args.control_points is not None:
        raise InputError("give either --knot-span or --control-points, not both")
    counts = None
    if args.control_points is not None:
        m = re.fullmatch(r"(\d+)x(\d+)", args.control_points)
        if not m or min(int(m[1]), int(m[2])) < 5:
            raise InputError(f"--control-points {printable(args.control_points, 40)!r}: expected NxM with N, M >= 5")
        counts = (int(m[1]), int(m[2]))
    # Millimetres on the command line, checked as the scene's knot_span_mm; metres after.
    span = scene_option("--knot-span", args.knot_span if args.knot_span is not None else 20.0, GarmentSpec,
                        "knot_span_mm")
    seam_span = "auto" if args.seam_span is None else scene_option("--seam-span", args.seam_span, GarmentSpec,
                                                                   "seam_span_mm")
    tolerance = None if args.tolerance is None else 1e-3 * number_option("--tolerance", args.tolerance, gt=0)
    number_option("--refine", args.refine, ge=0, le=6)
    options = ConformOptions(knot_span=span, control_points=counts, refine=args.refine, tolerance=tolerance,
                             mips=MipsOptions(), split=args.split, seam_span=seam_span,
                             fold_pleats=args.fold_pleats)
    out_dir = Path(args.output)
    output_folder(out_dir, "the output directory (-o)")
    if args.preview is not None:
        output_file(args.preview, (".png",), "the preview (--preview)")
    # Bad input leaves nothing behind: read it before creating the output directory.
    panels, seams = read_pattern(args.input, options.finest_span)
    if args.panels:
        wanted = [p.strip() for p in args.panels.split(",") if p.strip()]
        missing = set(wanted) - {p.name for p in panels}
        if missing:
            raise InputError(f"{args.input}: no panel named {', '.join(sorted(missing))}")
        panels = [p for p in panels if p.name in wanted]
    corners = parse_corners(args.corners)
    check_request(panels, options)  # memory, before the output folder and the work
    options = options.for_garment(panels, seams)  # the seam span: "auto" decided once, here
    created = not out_dir.exists()
    try:  # fail before the work, not after it
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"{out_dir}: cannot create the output directory ({e.strerror})") from None

    rows = []
    quiet = args.quiet or args.json
    with progress(quiet) as bar:
        task = bar.add_task("conform", total=len(panels), status="")

        def on_panel(panel, rep, error):
            rows.append(row(panel.name, rep, None if error is None else str(error)))
            # A split panel reports each of its pieces: the total grows with them.
            bar.update(task, advance=1, total=max(len(panels), len(rows)), status=f"{escape(printable(panel.name))}: " + (
                "failed" if rep is None else f"{rep['control_points'][0]}x{rep['control_points'][1]}, "
                                             f"{rep['seconds']:.2f} s"))

        ps = conform_all(panels, seams, options, corners=corners, on_panel=on_panel)
    if not ps.patches:  # every panel failed: an empty patch file would only mislead
        if created:
            out_dir.rmdir()
        for r in rows:
            print(f"error: {printable(r.get('error') or r['panel'] + ': could not be conformed')}", file=sys.stderr)
        return 1
    try:
        out = save_patchset(out_dir / "patches.json", ps)
    except OSError as e:
        raise InputError(f"{out_dir / 'patches.json'}: cannot write ({e.strerror})") from None
    if args.preview is not None:
        render_preview(ps, panels, args.preview)
    failed = [r for r in rows if r["status"] != "ok"]
    rows = with_split_rows(rows, ps.splits)
    if args.json:
        keys = ("panel", "status", "control_points", "boundary_error_mm", "min_jacobian_ratio",
                "max_jacobian_ratio", "min_corner_angle_deg", "area_error_pct", "reduced_area_error_pct",
                "seconds", "error")
        print(json.dumps({"input": str(args.input), "output": str(out),
                          "panels": [{k: r[k] for k in keys if k in r} for r in rows if r["status"] != "split"],
                          "splits": ps.splits, "seams": len(ps.seams)}, indent=1, default=float))
    else:
        print_table(f"garment conform {args.input}", COLUMNS, rows)
    for r in failed:
        # One plain line per failure: the message names the file and the panel.
        msg = r.get("error") or f"{r['panel']}: {r.get('inverted_points')} inverted quadrature points"
        print(f"error: {printable(msg)}", file=sys.stderr)
    if not quiet:
        err.print(f"wrote {out} ({len(ps.patches)} patches, {len(ps.seams)} seams)"
                  + (f", preview {args.preview}" if args.preview else ""))
        if args.seam_span is None and options.seam_span is not None:  # say what the default did
            err.print(f"the pattern has tucks: nets graded to {options.seam_span * 1e3:g} mm spans at its short seams "
                      f"(--seam-span MM to choose, --seam-span {span * 1e3:g} for uniform nets)")
    return 1 if failed else 0


def render_preview(ps, panels, path) -> None:
    """Control nets and knot spans over the input outlines, PyVista offscreen, one PNG.

    Panels whose layouts overlap (pattern pieces each in its own frame) are laid out in a
    grid. The patch surface is coloured by the Jacobian ratio det / mean det."""
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSOpenGLRenderWindow")
    import pyvista as pv

    from conform.boundary import extract_outline
    from sim.bspline import basis_matrix
    from sim.embedding import grid_faces

    by_name = {p.name: p for p in ps.patches}
    items = []
    for panel in panels:
        try:
            outline = extract_outline(panel).points
        except InputError:
            outline = panel.rest if panel.faces is None else None
        # A split panel shows all its pieces' patches over its outline.
        names = ps.splits[panel.name]["patches"] if panel.name in ps.splits else [panel.name]
        items.append((panel.name, outline, [by_name[n] for n in names if n in by_name]))
    boxes = []
    for name, outline, patches in items:
        pts = [outline] if outline is not None else []
        pts += [p.rest.reshape(-1, 2) for p in patches]
        P = np.concatenate(pts) if pts else np.zeros((1, 2))
        boxes.append((P.min(0), P.max(0)))
    offsets = _layout(boxes)

    pl = pv.Plotter(off_screen=True, window_size=(1600, 1100))
    pl.set_background("white")
    for (name, outline, patches), off, (lo, hi) in zip(items, offsets, boxes):
        def lift(P):
            P = np.asarray(P, float).reshape(-1, 2) + off
            return np.column_stack([P, np.zeros(len(P))])

        for patch in patches:
            X = patch.rest
            n, m = X.shape[:2]
            k = 6
            u = np.linspace(0, n - 2, k * (n - 2) + 1)
            v = np.linspace(0, m - 2, k * (m - 2) + 1)
            Bu, Bv = basis_matrix(u, n), basis_matrix(v, m)
            S = np.einsum("ai,bj,ijd->abd", Bu, Bv, X, optimize=True)
            Su = np.einsum("ai,bj,ijd->abd", basis_matrix(u, n, 1), Bv, X, optimize=True)
            Sv = np.einsum("ai,bj,ijd->abd", Bu, basis_matrix(v, m, 1), X, optimize=True)
            det = Su[..., 0] * Sv[..., 1] - Su[..., 1] * Sv[..., 0]
            faces = grid_faces(u.size, v.size)
            surf = pv.PolyData(lift(S), np.column_stack([np.full(len(faces), 3), faces]).ravel())
            surf["J / mean J"] = (det / det.mean()).ravel()
            pl.add_mesh(surf, scalars="J / mean J", cmap="RdYlGn", clim=(0.0, 2.0), show_edges=False,
                        opacity=0.55, show_scalar_bar=len(pl.scalar_bars) == 0,
                        scalar_bar_args={"title": "Jacobian ratio", "color": "black"})
            lines = [S[::k, :], S[:, ::k].transpose(1, 0, 2)]  # knot lines along v, along u
            for family in lines:
                for curve in family:
                    pl.add_mesh(pv.lines_from_points(lift(curve)), color="black", line_width=0.7)
            for grid in (X, X.transpose(1, 0, 2)):
                for polyline in grid:
                    pl.add_mesh(pv.lines_from_points(lift(polyline)), color="#d62728", line_width=0.5,
                                opacity=0.6)
            pl.add_points(lift(X), color="#d62728", point_size=3, render_points_as_spheres=True)
        for cut in ps.splits.get(name, {}).get("cuts", []):  # internal seams of a split panel
            pl.add_mesh(pv.lines_from_points(lift(np.array([cut["from"], cut["to"]]))), color="#1f77b4",
                        line_width=2.0)
        if outline is not None:
            closed = np.vstack([outline, outline[:1]])
            pl.add_mesh(pv.lines_from_points(lift(closed)), color="#1f77b4", line_width=2.5)
        label = name if patches else f"{name} (failed)"
        if len(patches) > 1:
            label += f" ({len(patches)} patches)"
        pl.add_point_labels(lift(np.array([[0.5 * (lo[0] + hi[0]), hi[1]]])), [label], font_size=12,
                            text_color="black", shape=None, show_points=False, always_visible=True)
    pl.view_xy()
    pl.enable_parallel_projection()
    pl.reset_camera(bounds=None)
    pl.camera.zoom(1.05)
    with atomic_write(path, keep_suffix=True) as tmp:
        pl.screenshot(str(tmp))
    pl.close()


def _layout(boxes) -> list[np.ndarray]:
    """Offsets that keep panels where they are unless their boxes overlap; then a grid."""
    overlap = False
    for i, (lo1, hi1) in enumerate(boxes):
        for lo2, hi2 in boxes[:i]:
            if np.all(lo1 < hi2) and np.all(lo2 < hi1):
                overlap = True
    if not overlap:
        return [np.zeros(2) for _ in boxes]
    size = np.array([hi - lo for lo, hi in boxes])
    gap = 0.15 * size.max()
    cols = int(np.ceil(np.sqrt(len(boxes) * 1.5)))
    cell = size.max(axis=0) + gap
    return [np.array([(k % cols) * cell[0], -(k // cols) * cell[1]]) - lo for k, (lo, _) in enumerate(boxes)]


def register(sub) -> None:
    c = sub.add_parser("conform", help="conform garment panels to quadratic B-spline patches")
    c.add_argument("input", type=Path, help="panel mesh (OBJ with vt/v/g/seam, PLY, ...) or GarmentCode .json")
    c.add_argument("-o", "--output", type=Path, required=True, help="directory for patches.json")
    g = c.add_mutually_exclusive_group()
    g.add_argument("--knot-span", type=float, metavar="MM", help="target knot-span size in mm (default 20)")
    g.add_argument("--control-points", metavar="NxM", help="control points along u and v for every panel")
    c.add_argument("--seam-span", type=float, metavar="MM",
                   help="grade the control nets towards this knot span at seams shorter than two knot spans "
                        "(tucks, dart legs; default: 8 mm on a garment with tucks, else uniform nets; "
                        "the knot span or more: uniform)")
    c.add_argument("--fold-pleats", action=argparse.BooleanOptionalAction, default=True,
                   help="fold tucks and knife pleats into the panels' 3D placement, so sewing starts with the "
                        "layers in order (default; --no-fold-pleats leaves them flat)")
    c.add_argument("--corners", action="append", metavar="PANEL=SPEC",
                   help="corners of one panel: input vertex ids i,j,k,l or rest positions x,y;x,y;x,y;x,y "
                        "(metres, nearest boundary vertex); repeatable")
    c.add_argument("--panels", help="comma-separated panel names to convert (default: all)")
    c.add_argument("--tolerance", type=float, metavar="MM",
                   help="boundary fit tolerance in mm (default: max(1 mm, 0.5%% of the panel diameter))")
    c.add_argument("--split", choices=("auto", "darts", "never"), default="auto",
                   help="cut darted panels into several patches along the darts' continuations: when one "
                        "patch would be badly out of balance (auto, default), always (darts) or never")
    c.add_argument("--refine", type=int, default=0, metavar="K", help="knot-insertion levels after the fit")
    c.add_argument("--preview", type=Path, metavar="PNG", help="render control nets over the outlines")
    c.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    c.add_argument("-q", "--quiet", action="store_true")
    c.set_defaults(func=run)
