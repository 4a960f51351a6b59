"""One panel -> one quadratic B-spline patch: the whole conforming pipeline.

    outline (boundary.py) -> corners (corners.py) -> side fits (curve_fit.py)
    -> boundary rows, area match, interior start (control_net.py) -> MIPS (mips.py)
    -> optional knot insertion + MIPS again -> lift to 3D (lift.py) -> report (quality.py)

Control counts: opposite sides share a count, from the longer of the two and the target
knot span (or given). When a side's fit misses the tolerance - max(1 mm, 0.5 % of the
panel diameter) - the pair's count grows by a quarter and the sides are refitted, up to
`adapt_rounds` times; when MIPS cannot untangle the net at all (a boundary that admits no
valid interior at that resolution, e.g. tabs between deep darts), the longer pair's count
grows by a quarter and it starts again, up to UNTANGLE_RETRIES times (neither with given
counts). The attempts share one untangling budget of Newton steps x net cells, sized by
the net the panel's area needs (untangle_budget): a net far denser than that - both pairs
of sides long around little cloth, as a spike from a stray vertex makes them - gets
proportionally fewer steps and fails in seconds, with an error that says so, where it
took minutes of ever larger nets. The boundary rows are the side fits, offset to keep the
panel's area, and stay fixed during MIPS unless MipsOptions.w_boundary is finite.

A garment (conform_all): panels with deep darts are first cut into pieces along the darts'
continuations (split.py, ConformOptions.split), each piece conformed as above and the
seams moved onto the pieces; then every seam is mapped to patch parameters (seams.py).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from sim.budget import require_memory
from sim.errors import InputError
from sim.patches import SIDES, Panel, Patch, PatchSet
from sim.seams.spec import PanelSeam

from . import corners as corners_mod
from .boundary import Outline, PanelError, extract_outline
from .control_net import assemble_boundary, laplace_start, match_area, refine, side_rows, tangential_start
from .curve_fit import (LAMBDA, SideSamples, evaluate, fit_side_reweighted, normal_equations, sample_polyline,
                        second_difference)
from .grading import SHORT, Request, grade
from .lift import lift
from .mips import STALL_WINDOW, BoundaryFit, MipsOptions, det, rule_points
from .mips import refine as mips_refine
from .pleats import TUCK_SEAM_SPAN, fold_panels, fold_span, has_tucks, pleat_faces
from .quality import folded, lift_strain, polyline_distance, report
from .seams import below_resolution, map_seam, seam_hints, short_seams
from .split import (PINCH, SPLIT_IMBALANCE, TRIM_WIDTH, darts_of, imbalance, necks_of, notches_of, split_panel,
                    split_seams, trims_of)


@dataclass
class ConformOptions:
    """knot_span: target knot-span size, metres (ignored with control_points);
    control_points: (n, m) counts along u and v; corners: 4 source vertex ids or 4 (x, y)
    rest positions (None: automatic); tolerance: boundary fit tolerance, metres (None:
    max(1 mm, 0.5 % of the diameter)); refine: knot-insertion levels after the first MIPS
    (each halves the knot spans); lam: side-fit smoothing; mips: solver settings; split:
    "auto" (cut a panel at its darts when one patch would be badly out of balance),
    "darts" (always cut at darts) or "never" (conform/split.py); seam_span: the knot span
    wanted at seams shorter than grading.SHORT knot spans (tucks, dart legs), metres - the
    net is graded towards them (conform/grading.py); None, or one not below knot_span,
    keeps it uniform; "auto" (conform_all): pleats.TUCK_SEAM_SPAN for a garment with
    tucks, else uniform (a single panel: uniform). fold_pleats:
    fold the panels' tucks and knife pleats into their 3D placement, so sewing starts with
    the layers in order (conform/pleats.py; panels without tucks are untouched)."""

    knot_span: float = 0.02
    control_points: tuple[int, int] | None = None
    corners: list | None = None
    tolerance: float | None = None
    refine: int = 0
    adapt_rounds: int = 4
    lam: float = LAMBDA
    mips: MipsOptions = field(default_factory=MipsOptions)
    split: str = "auto"
    seam_span: float | str | None = "auto"
    fold_pleats: bool = True

    @property
    def finest_span(self) -> float:
        """The smallest knot span asked for, metres: what input curves are sampled for
        ("auto": the knot span; only panel meshes have had tucks, and they are not sampled)."""
        graded = self.seam_span if isinstance(self.seam_span, float | int) else None
        return min(self.knot_span, graded or self.knot_span)

    def for_garment(self, panels: list[Panel], seams: list[PanelSeam]) -> "ConformOptions":
        """These options with seam_span a number below the knot span, or None (uniform):
        "auto" becomes pleats.TUCK_SEAM_SPAN where a panel has tucks."""
        span = self.seam_span
        if span == "auto":
            span = TUCK_SEAM_SPAN if has_tucks(panels, seams) else None
        if span is not None and (self.control_points is not None or span >= self.knot_span):
            span = None
        return dataclasses.replace(self, seam_span=span)


@dataclass
class Sides:
    """The four sides of an outline split at corners (loop positions c0..c3)."""

    corners: np.ndarray
    polylines: list[np.ndarray]
    positions: list[np.ndarray]  # loop positions of each side's points, corner to corner

    @property
    def lengths(self) -> np.ndarray:
        return np.array([np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in self.polylines])


def split_sides(outline: Outline, corners: np.ndarray) -> Sides:
    B = len(outline)
    polys, pos = [], []
    for k in range(4):
        a, b = int(corners[k]), int(corners[(k + 1) % 4])
        idx = np.arange(a, a + (b - a) % B + 1) % B
        pos.append(idx)
        polys.append(outline.points[idx])
    return Sides(np.asarray(corners), polys, pos)


def tolerance_for(outline: Outline, options: ConformOptions) -> float:
    if options.tolerance is not None:
        return options.tolerance
    return max(1e-3, 0.005 * outline.diameter)


def side_error(poly: np.ndarray, ctrl: np.ndarray) -> float:
    """Two-sided distance between a side polyline and its fitted curve, metres."""
    n = ctrl.shape[0]
    curve = evaluate(ctrl, np.linspace(0.0, n - 2.0, 24 * (n - 2) + 1))
    mid = 0.5 * (poly[1:] + poly[:-1])
    a = polyline_distance(np.vstack([poly, mid]), curve, closed=False)
    b = polyline_distance(curve, poly, closed=False)
    return float(max(a.max(), b.max()))


def counts_for(sides: Sides, options: ConformOptions) -> tuple[int, int]:
    if options.control_points is not None:
        n, m = options.control_points
        return int(n), int(m)
    L = sides.lengths
    h = options.knot_span
    n = max(5, int(np.ceil(max(L[0], L[2]) / h)) + 2)
    m = max(5, int(np.ceil(max(L[1], L[3]) / h)) + 2)
    return n, m


def fit_sides(sides: Sides, n: int, m: int, spacing: float, lam: float, grading=None):
    """Side fits at counts (n, m, n, m): samples (with their final IRLS weights), control
    points and the fit errors (m). grading: the (u, v) Gradings of a graded net, or None."""
    counts = (n, m, n, m)
    along = side_gradings(grading)
    fits = [fit_side_reweighted(sample_polyline(p, spacing, g), c, lam)
            for p, c, g in zip(sides.polylines, counts, along)]
    ctrls = [f[0] for f in fits]
    samples = [f[1] for f in fits]
    errors = [side_error(p, c) for p, c in zip(sides.polylines, ctrls)]
    return samples, ctrls, np.asarray(errors)


UNTANGLE_RETRIES = 3


def cells_needed(area: float, span: float, n: int, m: int) -> float:
    """The net cells a panel of this area needs at this knot span: area / span^2, and at
    least the 3 spans across of the smallest net along its longer direction (an n x m
    net: 3 (max(n, m) - 2))."""
    return max(area / span**2, 3.0 * (max(n, m) - 2))


def untangle_budget(need: float, options: ConformOptions) -> float:
    """The untangling work one panel may spend at one net level, in Newton steps x net
    cells: the steps every attempt may take (MipsOptions.untangle_iterations, 1 +
    UNTANGLE_RETRIES attempts) on the `need` cells of the net the panel needs
    (cells_needed). A well-laid net gets the steps it always had; one that is k times
    denser than its area needs (a spike: both pairs of sides long around little cloth)
    gets k times fewer, so it costs what a well-laid net of the panel would."""
    return float(options.mips.untangle_iterations * (UNTANGLE_RETRIES + 1) * need)


def _cells(n: int, m: int) -> int:
    return (n - 2) * (m - 2)


def _untangle_cap(budget: float, spent: float, n: int, m: int, options: ConformOptions) -> int:
    """Untangling steps the next attempt on an n x m net may take: what is left of the
    budget, at most MipsOptions.untangle_iterations."""
    return int(min(options.mips.untangle_iterations, max(budget - spent, 0.0) // _cells(n, m)))


def _starved(res, cap: int, options: ConformOptions) -> bool:
    """Whether a failed attempt stopped at the budget's cap, not at the untangler's own."""
    return res.energy == np.inf and cap < options.mips.untangle_iterations and res.untangle_iterations >= cap


def _overdense(panel: Panel, outline: Outline, sides: Sides, n: int, m: int, span: float, need: float) -> PanelError:
    """The error of a net that ran out of untangling budget: how much denser it is than
    the `need` cells the panel's area needs, the sides that made it so, and what to do."""
    sides_m = ", ".join(f"{length:.3g}" for length in sides.lengths)
    return PanelError(panel, f"could not untangle the control net ({n} x {m}) with the work a panel of "
                             f"{outline.area:.3g} m^2 gets: it has {_cells(n, m) / need:.0f} times the cells that area "
                             f"needs at {span * 1e3:.3g} mm knot spans, its four sides ({sides_m} m) running long "
                             "around little cloth - a spike or a stray vertex in the outline? Check the outline, or "
                             "give the panel's four corners with --corners")


def _grow(count: int) -> int:
    """A quarter more knot spans."""
    return int(np.ceil(1.25 * (count - 2))) + 2


def _mean_spans(lengths, n: int, m: int) -> tuple[float, float]:
    """Mean knot-span sizes along u and v of sides `lengths` (loop order), metres."""
    return 0.5 * (lengths[0] + lengths[2]) / (n - 2), 0.5 * (lengths[1] + lengths[3]) / (m - 2)


def _spans(sides: Sides, n: int, m: int, grading=None):
    """MIPS's target knot-span sizes along u and v, metres: the means, or on a graded net
    functions of the parameter."""
    a, b = _mean_spans(sides.lengths, n, m)
    if grading is None:
        return a, b
    gu, gv = grading
    return (lambda u: gu.span(u, n, a * (n - 2))), (lambda v: gv.span(v, m, b * (m - 2)))


def side_gradings(grading) -> list:
    """Each side's Grading in its loop direction (sides 2 and 3 run against u and v)."""
    if grading is None:
        return [None] * 4
    gu, gv = grading
    return [gu, gv, gu.reversed(), gv.reversed()]


def seam_requests(outline: Outline, sides: Sides, short_seams, span: float) -> list[Request]:
    """The stretches of the sides that short seams (rest points (K, 2) each, on this
    panel's outline) cover. A seam that only touches a side at its corner asks nothing of
    that side."""
    near = float(np.diff(outline.s).max())
    arcs = [np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]) for p in sides.polylines]
    requests = []
    for pts in short_seams:
        pos = corners_mod.loop_positions(outline, pts, near)
        for k, (side_pos, arc) in enumerate(zip(sides.positions, arcs)):
            hit = np.isin(side_pos, pos)
            if not hit[1:-1].any():
                continue
            requests.append(Request(k, float(arc[hit].min()), float(arc[hit].max()), span))
    return requests


def _spacing(spacing: float, sides: Sides, n: int, m: int) -> float:
    """Side sampling: at least four samples per knot span."""
    L = sides.lengths
    return min(spacing, 0.25 * min(max(L[0], L[2]) / (n - 2), max(L[1], L[3]) / (m - 2)))


def _solve(X: np.ndarray, scale, samples: list[SideSamples], options: ConformOptions, w_boundary: float,
           untangle_iterations: int | None = None):
    """MIPS on the net X whose boundary rows are the side fits: the boundary fixed
    (w_boundary = inf) or held by the penalty w_boundary E_fit, anchored to those rows;
    untangle_iterations: the untangling steps this attempt may take (None: the options')."""
    n, m = X.shape[:2]
    fixed = np.zeros((n, m), bool)
    fixed[[0, 0, -1, -1], [0, -1, 0, -1]] = True
    if not np.isfinite(w_boundary):
        fixed[0, :] = fixed[-1, :] = fixed[:, 0] = fixed[:, -1] = True
    # Targets on the current boundary curves (area-corrected fits), so E_fit = 0 there.
    anchored = [dataclasses.replace(s, points=evaluate(row, s.parameters(row.shape[0])))
                for s, row in zip(samples, side_rows(X))]
    h = float(np.sqrt(np.prod(_mean_spans([smp.length for smp in samples], n, m))))
    bt = boundary_term(anchored, n, m, options.lam, h)
    bt.c -= bt.value(X.reshape(-1, 2)) * bt.h**2  # round-off: E_fit(X) = 0 exactly
    mips_options = dataclasses.replace(options.mips, w_boundary=w_boundary)
    if untangle_iterations is not None:
        mips_options = dataclasses.replace(mips_options, untangle_iterations=untangle_iterations)
    return mips_refine(X, scale, bt, fixed, mips_options)


def interior_start(Xb: np.ndarray) -> np.ndarray:
    """The tangential-projection start of docs/design.md 4b.3; if it inverts quadrature points,
    the harmonic (Laplace) net when that inverts fewer."""
    n, m = Xb.shape[:2]
    guard = rule_points(n, m)

    def inverted(X):
        return int((det(guard.jacobians(X.reshape(-1, 2))) <= 0).sum())

    X = tangential_start(Xb)
    bad = inverted(X)
    if bad:
        Xl = laplace_start(Xb)
        if inverted(Xl) < bad:
            X = Xl
    return X


def boundary_term(samples: list[SideSamples], n: int, m: int, lam: float, h: float) -> BoundaryFit:
    """The side fits' objective on the boundary rows of an (n, m) net."""
    idx = np.arange(n * m).reshape(n, m)
    rows = [idx[:, 0], idx[-1, :], idx[::-1, -1], idx[0, ::-1]]
    H = sp.csr_matrix((n * m, n * m))
    b = np.zeros((n * m, 2))
    c = 0.0
    for side, row in zip(samples, rows):
        k = row.shape[0]
        W = side.w / side.length
        A, bk = normal_equations(side.parameters(k), k, W, side.points)
        D = second_difference(k, side.abscissae(k)) * np.sqrt(lam / (k - 2))
        A = A + D.T @ D
        r, cc = np.meshgrid(row, row, indexing="ij")
        H = H + sp.csr_matrix((A.ravel(), (r.ravel(), cc.ravel())), shape=(n * m, n * m))
        b[row] += bk
        c += float((W * (side.points**2).sum(1)).sum())
    return BoundaryFit(H.tocsr(), b, c, h)


def choose_corners(panel: Panel, outline: Outline, options: ConformOptions, hints=(), avoid=()) -> np.ndarray:
    """Four loop positions: the user's (options.corners) or the automatic choice with the
    panel's own hints, the seam ends (hints, rest positions) and never a point of avoid."""
    if options.corners is not None:
        return corners_mod.corners_from_user(panel, outline, options.corners)
    pos_of = {int(v): k for k, v in enumerate(outline.vertices)}
    near = float(np.diff(outline.s).max())  # seam points lie on the outline
    own = [pos_of[int(h)] for h in panel.corner_hints if int(h) in pos_of]
    seam_ends = list(corners_mod.loop_positions(outline, hints, near))
    avoid_pos = corners_mod.loop_positions(outline, avoid, near)
    try:
        return corners_mod.pick_corners(outline, own + seam_ends, hints_only=panel.faces is None and len(own) >= 4,
                                        avoid=avoid_pos)
    except corners_mod.TooFewCorners as e:
        raise PanelError(panel, f"{e}; give its four corners with --corners, or check its outline "
                                f"for a stray vertex") from None


def conform_panel(panel: Panel, options: ConformOptions | None = None, hints=(), avoid=(),
                  lift_from: Panel | None = None, short_seams=(), warp=None) -> tuple[Patch, dict]:
    """Conform one panel. hints: rest positions (P, 2) preferred as corners (seam ends);
    avoid: rest positions never made corners (points on darts); lift_from: the panel whose
    3D placement the patch takes (default: this one; a piece of a split panel: its parent);
    short_seams: rest points (K, 2) of each short seam on the panel, which the net is
    graded towards when options.seam_span is set; warp: rest points -> displacement of
    the placement (folded pleats, conform/pleats.py).
    Returns the patch and its report (quality numbers and provenance)."""
    options = options or ConformOptions()
    start = time.perf_counter()
    outline = extract_outline(panel)
    tol = tolerance_for(outline, options)
    c = choose_corners(panel, outline, options, hints, avoid)
    sides = split_sides(outline, c)
    if np.any(sides.lengths <= 0) or any(len(p) < 2 for p in sides.polylines):
        raise PanelError(panel, "two corners coincide")

    # Side fits, growing the counts where the fit misses the tolerance.
    n, m = counts_for(sides, options)
    h_target = options.knot_span if options.control_points is None else float(
        np.mean(sides.lengths) / max(np.mean([n, m]) - 2, 1))
    grading = None
    if options.seam_span == "auto":  # no garment to judge by: uniform
        options = dataclasses.replace(options, seam_span=None)
    requests = [] if options.seam_span is None or options.control_points is not None else seam_requests(
        outline, sides, short_seams, options.finest_span)
    if requests:
        grading = (grade(requests, sides.lengths, 0, options.knot_span, n - 2),
                   grade(requests, sides.lengths, 1, options.knot_span, m - 2))
        n, m = grading[0].spans + 2, grading[1].spans + 2
        h_target = options.finest_span
    spacing = min(h_target, float(np.median(np.diff(outline.s)))) / 4.0
    samples, ctrls, errors = fit_sides(sides, n, m, spacing, options.lam, grading)
    rounds = 0
    while options.control_points is None and rounds < options.adapt_rounds and errors.max() > 0.8 * tol:
        rounds += 1
        if max(errors[0], errors[2]) > 0.8 * tol:
            n = _grow(n)
        if max(errors[1], errors[3]) > 0.8 * tol:
            m = _grow(m)
        spacing = _spacing(spacing, sides, n, m)
        samples, ctrls, errors = fit_sides(sides, n, m, spacing, options.lam, grading)

    # Boundary rows with the panel's area, the interior start (the tangential projection,
    # or a harmonic net where that folds less), MIPS; then knot-insertion levels.
    Xb, area_offset = match_area(assemble_boundary(ctrls), outline.area)
    X = interior_start(Xb)
    t_fit = time.perf_counter() - start
    solves = []
    failed_iterations = 0
    for level in range(options.refine + 1):
        if level > 0:
            X = refine(X)
            n, m = X.shape[:2]
            spacing = _spacing(spacing, sides, n, m)
            samples, ctrls, errors = fit_sides(sides, n, m, spacing, options.lam, grading)
            Xb, area_offset = match_area(assemble_boundary(ctrls), outline.area)
            X[:, 0], X[-1, :], X[::-1, -1], X[0, ::-1] = Xb[:, 0], Xb[-1, :], Xb[::-1, -1], Xb[0, ::-1]
        # Given counts are the user's: their untangling keeps its per-attempt cap only.
        span = h_target / 2**level
        need = cells_needed(outline.area, span, n, m)
        budget = np.inf if options.control_points is not None else untangle_budget(need, options)
        spent = 0.0
        cap = _untangle_cap(budget, spent, n, m, options)
        res = _solve(X, _spans(sides, n, m, grading), samples, options, options.mips.w_boundary, cap)
        starved = _starved(res, cap, options)
        retries = 0
        while res.energy == np.inf and options.control_points is None and retries < UNTANGLE_RETRIES:
            # No valid interior at this resolution (typically tabs between darts crowding
            # the rows along the other pair of sides): more control points along the
            # longer pair of sides, refit, start again - if the budget still pays for
            # the untangler to judge progress there (STALL_WINDOW steps).
            spent += res.untangle_iterations * _cells(n, m)
            L = sides.lengths
            grown = (_grow(n), m) if max(L[0], L[2]) >= max(L[1], L[3]) else (n, _grow(m))
            cap = _untangle_cap(budget, spent, *grown, options)
            if cap < STALL_WINDOW:
                starved = True
                break
            retries += 1
            failed_iterations += res.untangle_iterations
            n, m = grown
            spacing = _spacing(spacing, sides, n, m)
            samples, ctrls, errors = fit_sides(sides, n, m, spacing, options.lam, grading)
            Xb, area_offset = match_area(assemble_boundary(ctrls), outline.area)
            X = interior_start(Xb)
            res = _solve(X, _spans(sides, n, m, grading), samples, options, options.mips.w_boundary, cap)
            starved = _starved(res, cap, options)
        solves.append(res)
        X = res.X
        if res.energy == np.inf:
            if starved:
                raise _overdense(panel, outline, sides, n, m, span, need)
            raise PanelError(panel, f"could not untangle the control net ({n} x {m}); try other corners "
                                    "or a finer knot span")

    world = lift(lift_from if lift_from is not None else panel, X, warp)
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(world))):
        raise PanelError(panel, "the fit produced non-finite control points")
    patch = Patch(panel.name, X, world)
    rep = report(outline, X, tol)
    rep.update({
        "lift_max_strain": lift_strain(X, world),
        "seconds": time.perf_counter() - start,
        "seconds_fit": t_fit,
        "mips_iterations": sum(r.iterations for r in solves),
        "untangle_iterations": sum(r.untangle_iterations for r in solves) + failed_iterations,
        "mips_converged": all(r.converged for r in solves),
        "mips_energy": solves[-1].energy,
        "adapt_rounds": rounds,
        "area_offset_mm": 1e3 * area_offset,
        "side_fit_error_mm": [1e3 * e for e in errors],
    })
    rep["status"] = "ok" if rep["inverted_points"] == 0 else "inverted"
    rep["provenance"] = provenance(panel, outline, sides)
    return patch, rep


def provenance(panel: Panel, outline: Outline, sides: Sides) -> dict:
    """Where the patch came from: source, panel, corners, and what each side covers."""
    ids = np.asarray(panel.vertex_ids)
    corner_vertices = outline.vertices[sides.corners]
    out = {
        "source": panel.source,
        "panel": panel.name,
        "corner_vertex_ids": [int(ids[v]) for v in corner_vertices] if panel.faces is not None else None,
        "corner_positions": [[float(x) for x in outline.points[c]] for c in sides.corners],
        "sides": {},
    }
    for name, pos in zip(SIDES, sides.positions):
        entry = {}
        if panel.faces is not None:
            # The input boundary edges are the consecutive pairs of these vertex ids.
            entry["boundary_vertex_ids"] = [int(ids[outline.vertices[p]]) for p in pos]
        else:
            # Outline panels: the first and last outline point of the side (panel indices;
            # a piece of a split panel: the parent's, -1 for a point the split added).
            entry["outline_range"] = [int(ids[outline.vertices[pos[0]]]), int(ids[outline.vertices[pos[-1]]])]
        if panel.segment_edges is not None:
            seg = panel.segment_edges[outline.vertices[pos[:-1]]]
            edges = [int(e) for k, e in enumerate(seg) if e >= 0 and (k == 0 or e != seg[k - 1])]
            entry["pattern_edges"] = edges
            if np.any(seg < 0):
                entry["cut"] = True  # runs along a cut of a split panel (an internal seam)
        out["sides"][name] = entry
    return out


def plan_split(panel: Panel, outline: Outline, seams: list[PanelSeam], options: ConformOptions, hints=(),
               avoid=()):
    """The split of a darted panel into pieces (conform/split.py), or None to keep it one
    patch: options.split "never", no dart that can be cut, user corners for the panel, or
    ("auto") sides of one patch balanced within SPLIT_IMBALANCE."""
    if options.split == "never" or options.corners is not None:
        return None
    darts = darts_of(panel.name, seams)
    if not darts:
        return None
    if options.split == "auto":
        sides = split_sides(outline, choose_corners(panel, outline, options, hints, avoid))
        if imbalance(sides.lengths) <= SPLIT_IMBALANCE:
            return None
    return split_panel(panel, outline, darts)


RESCUE_DEPTH = 2  # a piece of a rescued panel may be cut once more (a strap above a dart)
NECK_LOBE = 4.0  # knot spans around the outline on either side of a neck, at least


def rescue_splits(panel: Panel, outline: Outline, seams: list[PanelSeam], options: ConformOptions):
    """Ways to cut a panel whose single patch fails (cannot be untangled, or folds over),
    most natural first: at every dart and notch; else at one of its narrowest necks."""
    darts = darts_of(panel.name, seams)
    darts += notches_of(outline, darts)
    if darts:
        split = split_panel(panel, outline, darts)
        if split is not None:
            yield split
    for neck in necks_of(outline, NECK_LOBE * options.knot_span):
        # A neck is cut across; a pinch (narrower than any cloth) is cut off on both
        # sides (split.trims_of), and so, next, is a neck under TRIM_WIDTH: cut across it
        # (where the cut can be made at all), its pieces keep a side of a few mm against
        # their others and fold (jumpsuit_777_03's hood, whose neckline swings within
        # 4.9 mm of its front edge).
        cuts = [[neck]] if neck.depth >= PINCH else []
        if neck.depth < TRIM_WIDTH:
            cuts.append(trims_of(outline, neck))
        for cut in cuts:
            split = split_panel(panel, outline, cut) if cut else None
            if split is not None:
                yield split


# Peak memory of conforming one panel (garment conform, a 1 m square, peak resident set):
# 0.45 GB at 53^2 control points, 0.92 GB at 103^2, 1.55 GB at 145^2, 2.78 GB at 203^2.
CONFORM_BASE_BYTES = 0.3e9
CONFORM_BYTES_PER_POINT = 65e3


def estimated_counts(panel: Panel, options: ConformOptions) -> tuple[int, int]:
    """Control points (n, m) conforming `panel` will use at least: the given counts, or
    its bounding box in knot spans (an upper bound of the sides' lengths), each knot
    insertion level doubling the spans."""
    if options.control_points is not None:
        n, m = options.control_points
    else:
        w, h = np.ptp(panel.rest, axis=0) / options.knot_span if panel.rest.size else (0.0, 0.0)
        n, m = int(np.ceil(min(w, 1e12))) + 2, int(np.ceil(min(h, 1e12))) + 2
    grow = 2 ** max(options.refine, 0)
    return (n - 2) * grow + 2, (m - 2) * grow + 2


def check_request(panels: list[Panel], options: ConformOptions) -> None:
    """Refuse, before any work, panels with non-finite coordinates and a request whose
    largest panel needs more memory than the machine has (with the knot span to change)."""
    for p in panels:
        for what, a in (("rest layout", p.rest), ("3D placement", p.world), ("placement", p.transform)):
            if a is not None and not np.all(np.isfinite(a)):
                raise InputError(f"{p.source}: panel {p.name}: the {what} has non-finite coordinates (NaN or inf)")
    if not panels:
        return
    counts = {p.name: estimated_counts(p, options) for p in panels}
    name = max(counts, key=lambda k: counts[k][0] * counts[k][1])
    n, m = counts[name]
    need = CONFORM_BASE_BYTES + CONFORM_BYTES_PER_POINT * n * m
    if options.control_points is not None:
        fix = f"use fewer control points (now {n} x {m})"
    else:
        h = options.knot_span * 1e3
        fix = f"raise the knot span (now {h:.4g} mm)"
        if h < 1.0:
            fix += f"; {h:.4g} mm looks like metres typed for millimetres: did you mean {h * 1e3:.4g} mm?"
    if options.refine > 0:
        fix += f", or fewer knot-insertion levels (now {options.refine})"
    require_memory(need, f"{panels[0].source}: conforming panel {name} ({n} x {m} control points)", fix)


def conform_all(panels: list[Panel], seams: list[PanelSeam], options: ConformOptions | None = None,
                corners: dict | None = None, on_panel=None) -> PatchSet:
    """Conform every panel (a failing panel is recorded, the others go on) and map the
    seams between converted panels to their patches. A panel with deep darts is split into
    pieces `name.0`, `name.1`, ... (plan_split), each its own patch, sewn together along
    the cuts. corners: panel (or piece) name -> 4 corners (overrides); on_panel(panel,
    report or None, error or None) after each panel or piece."""
    options = options or ConformOptions()
    check_request(panels, options)
    options = options.for_garment(panels, seams)
    corners = corners or {}
    names = {p.name for p in panels}
    unknown = {c for c in corners if c not in names and c.rpartition(".")[0] not in names}
    if unknown:
        raise InputError(f"corners: no panel named {', '.join(sorted(unknown))}")
    patches, quality, prov, failures, tol, splits = {}, {}, {}, {}, {}, {}
    warps, flat, spans = {}, {}, {}
    if options.fold_pleats:
        if options.seam_span is not None:  # graded nets: fine enough at the tucks to fold
            spans = {p.name: fold_span(p.name, seams, options.finest_span) for p in panels}
            spans = {name: h for name, h in spans.items() if h < options.finest_span}
        warps, flat = fold_panels(panels, seams, options.finest_span, spans)

    # 1. Plan: outlines, splits, and the seams moved onto the pieces. Corner hints of
    # panels that stay whole come from the seams as given.
    work = []  # (panel to conform, hints, avoid, lift_from, split)
    all_seams = list(seams)
    for panel in panels:
        hints, avoid = seam_hints(panel.name, seams)
        opts = dataclasses.replace(options, corners=corners.get(panel.name, options.corners))
        try:
            outline = extract_outline(panel)
            split = plan_split(panel, outline, seams, opts, hints, avoid)
        except PanelError as e:
            failures[panel.name] = str(e)
            if on_panel:
                on_panel(panel, None, e)
            continue
        if split is None:
            work.append((panel, hints, avoid, None, None))
            continue
        all_seams = split_seams(all_seams, split, tolerance_for(outline, options))
        splits[panel.name] = split
        for piece in split.pieces:
            work.append((piece.panel, None, piece.avoid, panel, split))

    # 2. Conform every panel and piece. A whole panel whose one patch cannot be untangled
    # or folds over is cut (at its darts and notches, else at a neck) and its pieces tried.
    def attempt(panel, hints, avoid, parent, split, seams):
        if split is not None:
            hints, dart_points = seam_hints(panel.name, seams)
            avoid = np.concatenate([np.asarray(avoid).reshape(-1, 2), dart_points])
        origin = root_of(parent or panel)  # whose placement it takes
        opts = dataclasses.replace(options, corners=corners.get(panel.name, options.corners),
                                   seam_span=spans.get(origin.name, options.seam_span))
        short = short_seams(panel.name, seams, SHORT * options.knot_span)
        patch, rep = conform_panel(panel, opts, hints, avoid, lift_from=parent, short_seams=short,
                                   warp=warps.get(origin.name))
        rep["folds"] = folded(patch)
        return patch, rep

    roots = {}  # piece name -> the panel whose placement it takes

    def root_of(panel):
        return roots.get(panel.name, panel)

    def conform_tree(panel, hints, avoid, parent, split, seams, depth):
        """[(piece, patch, report, split)] and the seams, the panel cut as needed."""
        error, patch, rep = None, None, None
        outline = extract_outline(panel)
        # A piece of a rescued panel that still has a dart or notch (a dart whose cut would
        # cross another) is cut again: one patch around a dart tip is what failed before.
        darted = depth > 0 and bool(darts_of(panel.name, seams) or notches_of(outline))
        try:
            if darted and depth < RESCUE_DEPTH:
                raise PanelError(panel, "a dart or notch inside a piece")
            patch, rep = attempt(panel, hints, avoid, parent, split, seams)
            if not rep["folds"]:
                return [(panel, patch, rep, split)], seams, []
        except PanelError as e:
            error = e
        if depth < RESCUE_DEPTH and options.split != "never" and corners.get(panel.name) is None:
            for rescue in rescue_splits(panel, outline, seams, options):
                trial = split_seams(seams, rescue, tolerance_for(outline, options))
                done, below = [], [rescue]
                roots.update({piece.panel.name: root_of(panel) for piece in rescue.pieces})
                for piece in rescue.pieces:
                    try:
                        parts, trial, more = conform_tree(piece.panel, None, piece.avoid, root_of(panel), rescue,
                                                          trial, depth + 1)
                    except PanelError:
                        break
                    if any(r["folds"] for _, _, r, _ in parts):
                        break
                    done, below = done + parts, below + more
                else:  # every piece conformed without folding
                    return done, trial, below
        if patch is None and error is not None and darted:  # no cut helped: the piece whole
            patch, rep = attempt(panel, hints, avoid, parent, split, seams)
            error = None if not rep["folds"] else error
        if patch is None:
            raise error
        return [(panel, patch, rep, split)], seams, []  # folded: kept, flagged in its report

    for panel, hints, avoid, parent, split in work:
        try:
            parts, all_seams, rescues = conform_tree(panel, hints, avoid, parent, split, all_seams, 0)
        except PanelError as e:
            failures[panel.name] = str(e)
            if on_panel:
                on_panel(panel, None, e)
            continue
        for rescue in rescues:
            splits[rescue.parent.name] = rescue
        for piece, patch, rep, sp in parts:
            origin = root_of(parent or piece)
            prov[piece.name] = rep.pop("provenance")
            if sp is not None:
                prov[piece.name].update(piece_provenance(sp, piece.name))
            if origin.name in warps:
                rep["pleat_folds"] = int(warps[origin.name].fold.lines.size)
            if origin.name in spans:
                rep["pleat_span_mm"] = round(1e3 * spans[origin.name], 3)
            if flat.get(origin.name):
                rep["pleats_left_flat"] = flat[origin.name]
            patches[piece.name], quality[piece.name] = patch, rep
            tol[piece.name] = 2e-3 * rep["tolerance_mm"]  # twice the fit tolerance, metres
            if on_panel:
                on_panel(piece, rep, None)
    mapped, fit = [], {name: 0.5 * t for name, t in tol.items()}  # the boundary fit tolerances
    for s in all_seams:
        if s.panel_a not in patches or s.panel_b not in patches:
            continue
        if below_resolution(s, fit):
            quality[s.panel_a].setdefault("seams_below_resolution", []).append(s.name)
            continue
        mapped.append(map_seam(s, patches, tol))
    if warps:
        faces = {name: tucks for w in warps.values() for name, tucks in pleat_faces(w.fold, all_seams).items()}
        mapped = [dataclasses.replace(m, after=faces[m.name]) if m.name in faces else m for m in mapped]
    source = panels[0].source if panels else ""
    summary = {name: split_summary(sp_, quality) for name, sp_ in splits.items()}
    return PatchSet(list(patches.values()), mapped, prov, quality, failures, source, summary)


def piece_provenance(split, name: str) -> dict:
    """What a piece of a split panel is: the parent panel, its index, the cuts."""
    piece = next(p for p in split.pieces if p.panel.name == name)
    return {
        "panel": split.parent.name,
        "patch": name,
        "piece": piece.index,
        "pieces": len(split.pieces),
        "cuts": [{"from": [float(x) for x in c.p0], "to": [float(x) for x in c.p1], "dart": c.dart}
                 for k, c in enumerate(split.cuts) if k in piece.cuts],
    }


def split_summary(split, quality: dict) -> dict:
    """Per split panel: its patches, cuts, total seconds and the area of the patches
    together against the panel's (exact and reduced-rule), %."""
    names = split.piece_names()
    done = [quality[n] for n in names if n in quality]
    area = split.parent.area if split.parent.area is not None else extract_outline(split.parent).area
    out = {
        "patches": names,
        "cuts": [{"from": [float(x) for x in c.p0], "to": [float(x) for x in c.p1], "dart": c.dart,
                  "length_mm": 1e3 * c.length} for c in split.cuts],
        "seconds": float(sum(q["seconds"] for q in done)),
        "converted": len(done) == len(names),
    }
    for key in ("gauss2", "reduced"):
        vals = [q.get(f"area_{key}_m2") for q in done]
        if len(done) == len(names) and all(v is not None for v in vals):
            out[f"area_error_{key}_pct"] = 100.0 * (sum(vals) - area) / area
    return out
