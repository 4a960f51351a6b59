"""Splitting a darted panel into several patches along the continuations of its darts.

A dart is a seam that sews a panel to itself and whose two legs meet at a tip (the point
sewn to itself). One patch around deep darts is badly distorted: the darts lengthen one
side (the dress's skirt_back: 2.0 m of waist with four ~20 cm darts against a 0.5 m hem),
so opposite sides share a control count over very different lengths and the narrow tabs
between the darts crowd the rows. Pattern makers convert such darts into panel seams
("princess seams"); so does this module: each dart is continued from its tip along its
axis (mouth midpoint -> tip) to the outline, and the panel is cut along these lines into
pieces. Every piece is an outline panel of its own, conformed as usual; each cut becomes a
seam between the two pieces it separates (conform_all maps it to boundary intervals, so
the garment stage welds the pieces back together), and every seam of the panel is
re-attached to the piece(s) it runs along - split where it crosses a cut's end.

With the skirt, every piece is a quad: a stretch of hem, the cut plus a dart leg on each
side (one straight line with a few degrees of kink at the tip), and a stretch of waist.
The tips are kept off the pieces' corners, the cut ends are preferred as corners.

When: `ConformOptions.split` = "auto" (default) cuts a panel with darts when its four
sides, as the corner choice for one patch finds them, are out of balance by more than
SPLIT_IMBALANCE (longest side over its opposite); "darts" cuts at every dart; "never" keeps
every panel whole.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.patches import Panel
from sim.seams.spec import PanelSeam

from .boundary import Outline, polygon_area

SPLIT_IMBALANCE = 2.0  # one patch when opposite sides differ by less (dress_knife: <= 3.6 without darts)
DART_GAP = 1e-3  # a self-seam is a dart when its legs meet within this fraction of its size
STITCH_SPACING = 0.01  # samples along a cut seam, metres (as GarmentCode stitches)


@dataclass
class Dart:
    """Where a cut starts: a dart of a panel (its seam, tip (rest position, m) and unit axis
    (mouth -> tip)), a notch in the outline (a dart or slit no seam declares) or one end
    of a neck (axis: towards the other end)."""

    seam: str
    tip: np.ndarray
    axis: np.ndarray
    depth: float  # mouth midpoint to tip, m (a neck: its width)
    kind: str = "dart"  # "dart", "notch", "neck" or "trim" (one side of a pinch's sliver)


@dataclass
class Cut:
    """A straight cut from a dart tip to the outline: loop positions of both ends in the
    augmented outline, their rest positions, and the dart it continues."""

    start: int
    end: int
    p0: np.ndarray
    p1: np.ndarray
    dart: str
    kind: str = "dart"

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.p1 - self.p0))


@dataclass
class Piece:
    """One piece of a split panel. panel: the piece as an outline panel (CCW, rest in the
    parent's layout, same placement), named `parent.k`; nodes: the parent's augmented-loop
    positions of its outline points (-1 inside a cut); avoid: rest positions never made
    corners (dart tips)."""

    panel: Panel
    parent: str
    index: int
    nodes: np.ndarray
    avoid: np.ndarray
    cuts: list = field(default_factory=list)  # indices of the cuts on its boundary


@dataclass
class Split:
    """A panel cut into pieces: the augmented parent outline (loop points plus the cut
    ends), the cuts, the pieces and the seams along the cuts."""

    parent: Panel
    points: np.ndarray  # (B', 2) augmented loop
    s: np.ndarray  # (B' + 1,) its arc lengths
    cuts: list[Cut]
    pieces: list[Piece]
    cut_seams: list[PanelSeam]
    segment_owner: np.ndarray = None  # (B',) piece index of each augmented loop segment

    def __post_init__(self):
        Bp = self.points.shape[0]
        self.segment_owner = np.full(Bp, -1)
        for piece in self.pieces:
            nodes = [a for a in piece.nodes if a >= 0]
            for i, a in enumerate(nodes):
                if nodes[(i + 1) % len(nodes)] == (a + 1) % Bp:
                    self.segment_owner[a] = piece.index

    def piece_names(self) -> list[str]:
        return [p.panel.name for p in self.pieces]


def darts_of(panel_name: str, seams: list[PanelSeam]) -> list[Dart]:
    """The darts of a panel among the seams (a seam of the panel with itself whose legs
    meet at one end)."""
    out = []
    for s in seams:
        if s.panel_a != panel_name or s.panel_b != panel_name or len(s.points_a) < 2:
            continue
        a, b = np.asarray(s.points_a, float), np.asarray(s.points_b, float)
        gap = np.linalg.norm(a - b, axis=1)
        size = np.ptp(np.concatenate([a, b]), axis=0).max()
        if gap.min() > DART_GAP * max(size, 1e-9):
            continue
        k = int(np.argmin(gap))
        if k not in (0, len(gap) - 1):
            continue  # legs meet in the middle: not a dart
        far = len(gap) - 1 - k
        tip = 0.5 * (a[k] + b[k])
        mouth = 0.5 * (a[far] + b[far])
        axis = tip - mouth
        depth = float(np.linalg.norm(axis))
        if depth <= 0:
            continue
        out.append(Dart(s.name, tip, axis / depth, depth))
    return out


NOTCH_OPENING = np.radians(60.0)  # legs closer than this (seen LEG samples out): a notch
NOTCH_LEG = 3
NECK_RATIO = 0.35  # a neck: a chord shorter than this fraction of the outline around its lobe


def notches_of(outline: Outline, known: list[Dart] = ()) -> list[Dart]:
    """Notches of the outline that no dart declares: loop points where the outline turns
    back on itself into the panel (a slit for a godet, a dart sewn some other way). The
    axis points from the notch's mouth to its tip."""
    P = outline.points
    B = len(outline)
    w = NOTCH_LEG
    if B < 2 * w + 3:
        return []
    u1 = np.roll(P, w, axis=0) - P  # towards the point w samples back
    u2 = np.roll(P, -w, axis=0) - P
    u1 /= np.maximum(np.linalg.norm(u1, axis=1), 1e-300)[:, None]
    u2 /= np.maximum(np.linalg.norm(u2, axis=1), 1e-300)[:, None]
    opening = np.arccos(np.clip((u1 * u2).sum(1), -1.0, 1.0))
    reflex = (u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]) > 0  # CCW loop: the tip points inwards
    spacing = float(np.median(np.diff(outline.s)))
    out = []
    for k in np.nonzero(reflex & (opening < NOTCH_OPENING))[0]:
        if opening[k] > opening[(k - 1) % B] or opening[k] > opening[(k + 1) % B]:
            continue  # the sharpest point of the notch is its tip
        if any(np.linalg.norm(P[k] - d.tip) < 2 * w * spacing for d in known):
            continue
        axis = -(u1[k] + u2[k])
        out.append(Dart(f"notch{len(out)}", P[k].copy(), axis / np.linalg.norm(axis), w * spacing, "notch"))
    return out


def necks_of(outline: Outline, min_arc: float, count: int = 3) -> list[Dart]:
    """The narrowest necks of the outline, best first: chords inside the panel much shorter
    than the outline around the lobe they cut off (a strap on a torso panel), each lobe
    at least min_arc around. Returned as cut starts (one end, axis to the other)."""
    P = outline.points
    B = len(outline)
    stride = max(1, B // 400)
    idx = np.arange(0, B, stride)
    Q, s = P[idx], outline.s[idx]
    per = outline.perimeter
    chord = np.linalg.norm(Q[:, None] - Q[None], axis=-1)
    arc = np.abs(s[:, None] - s[None])
    arc = np.minimum(arc, per - arc)
    with np.errstate(divide="ignore", invalid="ignore"):
        score = np.where((arc >= min_arc) & (chord > 0), chord / arc, np.inf)
    score[np.tril_indices(len(idx))] = np.inf
    out = []
    for flat in np.argsort(score, axis=None):
        i, j = np.unravel_index(flat, score.shape)
        if not score[i, j] < NECK_RATIO or len(out) == count:
            break
        # The narrowest chord among the full outline's points near the subsampled pair.
        near = np.arange(-stride, stride + 1)
        wa, wb = (idx[i] + near) % B, (idx[j] + near) % B
        d = np.linalg.norm(P[wa][:, None] - P[wb][None], axis=-1)
        ka, kb = np.unravel_index(np.argmin(d), d.shape)
        a, b = P[wa[ka]], P[wb[kb]]
        width = float(d[ka, kb])
        if width == 0.0:
            continue
        if any(min(np.linalg.norm(a - d.tip), np.linalg.norm(b - d.tip)) < 0.5 * min_arc for d in out):
            continue  # the same neck again
        if not _inside(P, 0.5 * (a + b)) or _crosses_outline(P, a, b):
            continue
        out.append(Dart(f"neck{len(out)}", a.copy(), (b - a) / width, width, "neck"))
    return out


PINCH = 3e-3  # m: a neck narrower than this is no cloth the contact mesh can hold
TRIM_WIDTH = 10e-3  # m: a pinch's sliver is cut off where its lobes are this wide


def trims_of(outline: Outline, neck: Dart, width: float = TRIM_WIDTH) -> list[Dart]:
    """Two cuts, one into each lobe of a pinched neck (two curves of the outline that all
    but meet: upper_garment_06's armhole and back neckline, 1 mm apart on its sampled
    outline), where the lobe is `width` wide. Cut at the pinch itself, a lobe keeps a side
    of 1 mm against a 79 mm one and its patch folds; the sliver between the two cuts
    (pinched in the middle, at most `width` wide) is dropped and its seams left open.
    [] when a lobe never gets that wide."""
    P = outline.points
    B = len(outline)
    ia = int(np.argmin(np.linalg.norm(P - neck.tip, axis=1)))
    ib = int(np.argmin(np.linalg.norm(P - (neck.tip + neck.depth * neck.axis), axis=1)))
    out = []
    for step in (1, -1):  # the lobe from ia forward to ib, then from ib forward to ia
        n = ((ib - ia) * step) % B  # points of the lobe's loop between the pinch's ends
        side_b = P[(ib - step * np.arange(1, n // 2 + 1)) % B]
        for k in range(1, n // 2 + 1):
            p = P[(ia + step * k) % B]
            d = np.linalg.norm(side_b - p, axis=1)
            j = int(np.argmin(d))
            if d[j] >= width:
                out.append(Dart(f"trim{len(out)}", p.copy(), (side_b[j] - p) / d[j], float(d[j]), "trim"))
                break
        else:
            return []
    return out


def _crosses_outline(P: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment a-b crosses the closed polygon P anywhere but at its ends."""
    return bool(np.any(_crossing(a, b, P, np.roll(P, -1, axis=0))))


def _ray_hit(points: np.ndarray, origin: np.ndarray, direction: np.ndarray, skip: set) -> tuple[int, float, float]:
    """First crossing of the ray origin + t direction (t > 0) with the closed polygon:
    (segment index, t along the ray, fraction along the segment); (-1, inf, 0) if none."""
    a, b = points, np.roll(points, -1, axis=0)
    e = b - a
    den = direction[0] * e[:, 1] - direction[1] * e[:, 0]
    w = a - origin
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / den
        f = (w[:, 0] * direction[1] - w[:, 1] * direction[0]) / den
    ok = np.isfinite(t) & (t > 1e-9) & (f >= -1e-12) & (f <= 1 + 1e-12)
    if skip:
        ok[list(skip)] = False
    if not ok.any():
        return -1, np.inf, 0.0
    k = int(np.argmin(np.where(ok, t, np.inf)))
    return k, float(t[k]), float(np.clip(f[k], 0.0, 1.0))


def _crossing(p0, p1, q0, q1) -> np.ndarray:
    """Whether segments p0-p1 and q0-q1 cross at a point inside both (broadcasting over
    leading axes; touching does not count)."""
    def orient(a, b, c):
        return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])

    d1, d2 = orient(q0, q1, p0), orient(q0, q1, p1)
    d3, d4 = orient(p0, p1, q0), orient(p0, p1, q1)
    return (d1 * d2 < 0) & (d3 * d4 < 0)


def _segments_cross(p0, p1, q0, q1) -> bool:
    return bool(_crossing(np.asarray(p0), np.asarray(p1), np.asarray(q0), np.asarray(q1)))


def _inside(poly: np.ndarray, p: np.ndarray) -> bool:
    x, y = poly[:, 0], poly[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = (y > p[1]) != (yn > p[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = x + (p[1] - y) * (xn - x) / (yn - y)
    return bool(np.sum(cross & (p[0] < xi)) % 2)


def plan_cuts(outline: Outline, darts: list[Dart]) -> tuple[np.ndarray, np.ndarray, list[Cut]]:
    """Cuts continuing the darts to the outline. Returns the augmented loop (the outline
    points with every cut end inserted), the augmented loop's parent loop position of each
    point (-1 for an inserted point) and the cuts; a dart whose continuation leaves the
    panel or crosses an earlier cut is not cut."""
    P = outline.points
    B = len(outline)
    spacing = float(np.median(np.diff(outline.s)))
    plans = []  # (tip loop position, segment hit, fraction along it, dart seam, cut end)
    for d in darts:
        tip = int(np.argmin(np.linalg.norm(P - d.tip, axis=1)))
        if np.linalg.norm(P[tip] - d.tip) > 0.5 * spacing:
            continue  # the tip is not on the outline
        seg, t, f = _ray_hit(P, P[tip], d.axis, skip={(tip - 1) % B, tip})
        if seg < 0:
            continue
        end = P[seg] + f * (P[(seg + 1) % B] - P[seg])
        if not _inside(P, 0.5 * (P[tip] + end)) or t < 2 * spacing:
            continue
        if any(_segments_cross(P[tip], end, P[q[0]], q[4]) for q in plans):
            continue
        plans.append((tip, seg, f, d, end))
    # Insert the cut ends (onto a loop point only when they hit it: moving a cut end would
    # turn the cut off the dart's axis).
    inserts = {}  # segment -> [(fraction, plan index)]
    snapped = {}
    for k, (tip, seg, f, _, end) in enumerate(plans):
        seglen = np.linalg.norm(P[(seg + 1) % B] - P[seg])
        if f * seglen <= 1e-6 * spacing:
            snapped[k] = seg
        elif (1 - f) * seglen <= 1e-6 * spacing:
            snapped[k] = (seg + 1) % B
        else:
            inserts.setdefault(seg, []).append((f, k))
    pts, parent, where = [], [], {}
    for i in range(B):
        pts.append(P[i])
        parent.append(i)
        for f, k in sorted(inserts.get(i, [])):
            where[k] = len(pts)
            pts.append(plans[k][4])
            parent.append(-1)
    new_pos = {i: p for p, i in enumerate(parent) if i >= 0}
    cuts = []
    pts = np.asarray(pts)
    for k, (tip, seg, f, d, end) in enumerate(plans):
        e = new_pos[snapped[k]] if k in snapped else where[k]
        cuts.append(Cut(new_pos[tip], e, pts[new_pos[tip]].copy(), pts[e].copy(), d.seam, d.kind))
    return pts, np.asarray(parent), cuts


def _pieces_of(B: int, cuts: list[Cut]) -> list[list[int]]:
    """Cyclic node lists (augmented loop positions) of the pieces cut off by the chords."""
    pieces = [list(range(B))]
    for c in cuts:
        for k, nodes in enumerate(pieces):
            if c.start in nodes and c.end in nodes:
                i, j = nodes.index(c.start), nodes.index(c.end)
                rot = nodes[i:] + nodes[:i]
                jj = (j - i) % len(nodes)
                pieces[k] = rot[: jj + 1]  # start ... end, closed by the cut end -> start
                pieces.append(rot[jj:] + rot[:1])  # end ... start, closed by start -> end
                break
    return pieces


def split_panel(panel: Panel, outline: Outline, darts: list[Dart]) -> Split | None:
    """Cut the panel along its darts' continuations; None when no dart can be cut."""
    points, parent_pos, cuts = plan_cuts(outline, darts)
    if not cuts:
        return None
    Bp = points.shape[0]
    closed = np.vstack([points, points[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    spacing = float(np.median(np.diff(outline.s)))
    B = len(outline)
    hint_pos = set()
    if panel.corner_hints is not None and len(panel.corner_hints):
        by_vertex = {int(v): k for k, v in enumerate(outline.vertices)}
        hint_pos = {by_vertex[int(h)] for h in panel.corner_hints if int(h) in by_vertex}
    seg_edges = panel.segment_edges
    bulge = panel.segment_bulge
    ids = np.asarray(panel.vertex_ids)
    # A dart's or notch's tip lies in the middle of a piece's side (leg + cut, nearly
    # straight) and is never a corner; both ends of a neck are.
    tips = np.array([c.p0 for c in cuts if c.kind not in ("neck", "trim")]).reshape(-1, 2)
    neck_starts = {c.start for c in cuts if c.kind in ("neck", "trim")}

    def loop_next(a):
        return (a + 1) % Bp

    raw = _pieces_of(Bp, cuts)
    # Order: by the first parent loop position each piece covers (the outline's start first).
    def first_parent(nodes):
        par = [parent_pos[a] for a in nodes if parent_pos[a] >= 0]
        return min(par) if par else B

    raw.sort(key=first_parent)
    pieces = []
    for k, nodes in enumerate(raw):
        pts, node_of, seg_e, blg, vid, hints = [], [], [], [], [], []
        on_cuts = set()
        for idx, a in enumerate(nodes):
            b = nodes[(idx + 1) % len(nodes)]
            if parent_pos[a] in hint_pos or parent_pos[a] < 0 or a in neck_starts:
                hints.append(len(pts))  # pattern vertices and the cut ends on the outline
            pts.append(points[a])
            node_of.append(a)
            vid.append(int(ids[outline.vertices[parent_pos[a]]]) if parent_pos[a] >= 0 else -1)
            if b == loop_next(a):  # along the parent's outline
                pa = _parent_segment(parent_pos, a)
                seg_e.append(int(seg_edges[outline.vertices[pa]]) if seg_edges is not None else -1)
                blg.append(_bulge_part(bulge, outline, points, parent_pos, a, b) if bulge is not None else 0.0)
            else:  # along a cut: sampled like the outline
                c = next(i for i, c in enumerate(cuts) if {c.start, c.end} == {a, b})
                on_cuts.add(c)
                L = float(np.linalg.norm(points[b] - points[a]))
                cnt = max(int(np.ceil(L / spacing)), 1)
                seg_e.append(-1)
                blg.append(0.0)
                for t in np.arange(1, cnt) / cnt:
                    pts.append(points[a] + t * (points[b] - points[a]))
                    node_of.append(-1)
                    vid.append(-1)
                    seg_e.append(-1)
                    blg.append(0.0)
        pts = np.asarray(pts)
        area = polygon_area(pts) + float(np.sum(blg))
        sub = Panel(name=f"{panel.name}.{k}", source=panel.source, rest=pts, faces=None, world=None,
                    transform=panel.transform, vertex_ids=np.asarray(vid), corner_hints=np.asarray(hints, np.int64),
                    segment_edges=np.asarray(seg_e) if seg_edges is not None else None,
                    segment_bulge=np.asarray(blg) if bulge is not None else None, area=area)
        if sum(cuts[c].kind == "trim" for c in on_cuts) < 2:  # between two trims: a pinch's sliver, dropped
            pieces.append(Piece(sub, panel.name, k, np.asarray(node_of), tips, sorted(on_cuts)))

    # The cut seams: sampled from the tip to the outline, the same points on both pieces.
    cut_seams = []
    for i, c in enumerate(cuts):
        owners = [p for p in pieces if i in p.cuts]
        if len(owners) != 2:
            continue
        cnt = max(int(np.ceil(c.length / STITCH_SPACING)), 2) + 1
        t = np.linspace(0.0, 1.0, cnt)[:, None]
        q = c.p0 + t * (c.p1 - c.p0)
        cut_seams.append(PanelSeam(f"{panel.name}.cut{i}", owners[0].panel.name, owners[1].panel.name, q, q.copy()))
    return Split(panel, points, s, cuts, pieces, cut_seams)


def _parent_segment(parent_pos: np.ndarray, a: int) -> int:
    """The parent loop segment (its start position) that augmented point a lies on."""
    while parent_pos[a] < 0:
        a = (a - 1) % parent_pos.shape[0]
    return int(parent_pos[a])


def _bulge_part(bulge, outline: Outline, points, parent_pos, a, b) -> float:
    """The exact-curve area correction of the augmented segment a -> b: the parent
    segment's bulge, shared by length when a cut end splits it (the cut ends lie on the
    chord, so the sum stays exact)."""
    Bp = points.shape[0]
    pa = parent_pos[a]
    back = a
    while pa < 0:
        back = (back - 1) % Bp
        pa = parent_pos[back]
    fwd = (back + 1) % Bp
    while parent_pos[fwd] < 0:
        fwd = (fwd + 1) % Bp
    seg = int(outline.vertices[pa])
    L = np.linalg.norm(points[fwd] - points[back])
    part = np.linalg.norm(points[b] - points[a])
    # A parabola-like bulge over the chord: the share of [t0, t1] is 3t^2 - 2t^3 at the ends.
    t0 = np.linalg.norm(points[a] - points[back]) / L
    t1 = t0 + part / L

    def cdf(t):
        return 3 * t**2 - 2 * t**3

    return float(bulge[seg] * (cdf(min(t1, 1.0)) - cdf(t0)))


# ------------------------------------------------------------------------------- seams


def _arc_project(points: np.ndarray, s: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc length (along the closed polyline points, arc lengths s) and distance of the
    nearest polyline point to each q (K, 2)."""
    a, b = points, np.roll(points, -1, axis=0)
    e = b - a
    L2 = np.maximum((e**2).sum(1), 1e-300)
    t = np.clip((((q[:, None, :] - a[None]) * e[None]).sum(-1)) / L2[None], 0.0, 1.0)
    foot = a[None] + t[..., None] * e[None]
    d = np.linalg.norm(q[:, None, :] - foot, axis=-1)
    k = np.argmin(d, axis=1)
    r = np.arange(q.shape[0])
    return s[k] + t[r, k] * np.sqrt(L2[k]), d[r, k]


def _owner_of_arc(split: Split, sigma: float) -> int:
    """Index of the piece whose outline covers arc length sigma of the augmented loop."""
    sigma = sigma % split.s[-1]
    k = min(int(np.searchsorted(split.s, sigma, side="right") - 1), split.points.shape[0] - 1)
    return int(split.segment_owner[k])


def _owner_of_point(split: Split, p: np.ndarray) -> int:
    for piece in split.pieces:
        if _inside(piece.panel.rest, p):
            return piece.index
    return -1


def split_seams(seams: list[PanelSeam], split: Split, tol: float) -> list[PanelSeam]:
    """The seams with every reference to the split panel moved to its pieces: a seam side
    along the outline is cut where it passes a cut end (the exact cut end inserted, the
    partner side interpolated there), and each run on one piece (pair) becomes a seam,
    named `seam.r` when there are several. Darts become seams between neighbouring pieces.
    The cut seams are appended."""
    name = split.parent.name
    ends = np.array([split.s[c.end] for c in split.cuts] + [split.s[c.start] for c in split.cuts])
    P = split.s[-1]
    out = []
    for seam in seams:
        if name not in (seam.panel_a, seam.panel_b):
            out.append(seam)
            continue
        a, b = np.asarray(seam.points_a, float), np.asarray(seam.points_b, float)
        sides = [seam.panel_a == name, seam.panel_b == name]
        arcs = []
        for on, q in zip(sides, (a, b)):
            arcs.append(_arc_project(split.points, split.s, q) if on else None)
        # Transition points (fractional sample index) where a side passes a cut end.
        inserts = []  # (k + f, side, exact point)
        for side, on in enumerate(sides):
            if not on:
                continue
            s, d = arcs[side]
            for k in range(len(s) - 1):
                if d[k] > tol or d[k + 1] > tol:
                    continue
                ds = (s[k + 1] - s[k] + 0.5 * P) % P - 0.5 * P  # short way
                for e in ends:
                    f = ((e - s[k] + 0.5 * P) % P - 0.5 * P) / ds if ds != 0 else -1.0
                    if 1e-9 < f < 1 - 1e-9:
                        inserts.append((k + f, side, _at(split, e)))
        pts = [a, b]
        if inserts:
            inserts.sort(key=lambda x: x[0])
            idx = np.arange(len(a), dtype=float)
            pos = np.concatenate([idx, [x[0] for x in inserts]])
            order = np.argsort(pos, kind="stable")
            pos = pos[order]
            new = []
            for q in (a, b):
                new.append(np.stack([np.interp(pos, idx, q[:, 0]), np.interp(pos, idx, q[:, 1])], 1))
            for t, side, exact in inserts:  # the transitioning side gets the exact cut end
                j = int(np.nonzero(np.isclose(pos, t, rtol=0, atol=1e-12))[0][0])
                new[side][j] = exact
            pts = new
        # Owners per segment (or per point for a single-point seam).
        K = len(pts[0])
        owner = np.full((max(K - 1, 1), 2), -1)
        for side, on in enumerate(sides):
            if not on:
                continue
            q = pts[side]
            for k in range(owner.shape[0]):
                m = q[k] if K == 1 else 0.5 * (q[k] + q[k + 1])
                sig, dist = _arc_project(split.points, split.s, m[None])
                owner[k, side] = (_owner_of_arc(split, float(sig[0])) if dist[0] <= tol
                                  else _owner_of_point(split, m))
        runs = []
        start = 0
        for k in range(1, owner.shape[0] + 1):
            if k == owner.shape[0] or np.any(owner[k] != owner[start]):
                runs.append((start, k, owner[start]))
                start = k
        for r, (k0, k1, own) in enumerate(runs):
            sl = slice(k0, k1 + 1) if K > 1 else slice(0, 1)
            pa = f"{name}.{own[0]}" if sides[0] else seam.panel_a
            pb = f"{name}.{own[1]}" if sides[1] else seam.panel_b
            if (sides[0] and own[0] < 0) or (sides[1] and own[1] < 0):
                continue  # off every piece (should not happen)
            out.append(PanelSeam(seam.name + (f".{r}" if len(runs) > 1 else ""), pa, pb,
                                 pts[0][sl].copy(), pts[1][sl].copy(),
                                 None if sides[0] else _slice(seam.vertices_a, sl, inserts),
                                 None if sides[1] else _slice(seam.vertices_b, sl, inserts)))
    return out + list(split.cut_seams)


def _at(split: Split, sigma: float) -> np.ndarray:
    closed = np.vstack([split.points, split.points[:1]])
    sigma = sigma % split.s[-1]
    return np.array([np.interp(sigma, split.s, closed[:, 0]), np.interp(sigma, split.s, closed[:, 1])])


def _slice(vertices, sl, inserts):
    if vertices is None or inserts:
        return None
    return np.asarray(vertices)[sl]


def imbalance(lengths: np.ndarray) -> float:
    """Longest side over its opposite side."""
    L = np.maximum(np.asarray(lengths, float), 1e-300)
    return float(max(L[0] / L[2], L[2] / L[0], L[1] / L[3], L[3] / L[1]))
