"""Knife pleats and tucks folded into a panel's 3D placement before sewing.

A tuck is a seam of a panel with itself whose two stretches lie on one straight side and
face each other: sewing pulls the cloth between them into a fold whose tip is midway
between the stretches' inner ends. Knife pleats (dress_knife's waist) are tucks in pairs,
each tuck's tip on the other's root, so three layers stack in a Z. Sewn from flat panels
the layers fold in whatever order the first steps give them; where a layer ends up
between a seam's two sides the seam cannot close without taking cloth through cloth, and
contact holds it open (docs/findings.md, "Folded pleats").

So the placement is folded before sewing, along lines across the panel at right angles to
the side: every tuck at its tip and at one root (in a knife pleat the root on the other
tuck's tip, for a lone tuck its first). Turned all the way (180 degrees, the direction
flipping at each line) this would bring each stitch's two points together, which is
checked. The placement turns only FOLD_ANGLE at each line, consecutive lines opposite
ways, each turn spread over TURN_WIDTH knot spans, and each group of overlapping tucks
tilted about its ends so the cloth past it stays level: that sets which way every fold
goes, hence the order of the layers, and the seams fold the rest of the way. The layer
sewn to other panels (a waistband) comes out on top, away from the garment's centre, like
a pressed pleat's face; the others lie under it. The cloth only bends (the profile is
isometric), but a net cannot follow a fold much sharper than its span: dress_knife's
panel11 at 8 mm spans lifts with 6 % strain at 60 degrees over two spans, 34 % at 150.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.patches import Panel
from sim.seams.spec import PanelSeam

from .lift import affine_map

# How far each fold line turns the placement (a quarter of the way would do to set it).
FOLD_ANGLE = np.radians(60.0)
# Pleats shallower than this many of the finest knot spans are left flat: the net cannot
# fold them (dress_knife's bodice pleats, 6.2-9.6 mm deep, at 8 mm spans).
PLEAT_DEPTH = 1.5
# A panel whose pleats are too shallow to fold at the seam span is graded finer at its
# tucks (fold_span), down to the seam span over this. dress_knife's bodices at 8 mm: their
# pleats stay flat and their layers hold seam53/54 1.1-1.4 mm open; at 5 mm (6 of each
# bodice's 8 tucks folded) every seam closed; at 4.8 and 4.1 mm (all folded) the dart
# seam43 next to panel13's 6.2 mm pleat stayed 10-14 mm open (docs/findings.md, "Folded pleats").
PLEAT_REFINE = 1.6
# The knot span a garment with tucks is graded to at its short seams (tucks, dart legs)
# when no seam span is asked for: a quadratic net folds centimetres of cloth only over
# several spans. dress_knife's widest seam after sewing was 12.2 mm at uniform 40 mm spans,
# 2.8 mm at 20 mm and 0.09 mm at 8 mm (docs/findings.md, "Garments"). Garments without
# tucks (every GarmentCode design read so far) keep uniform nets.
TUCK_SEAM_SPAN = 0.008
# Each fold turns over this many knot spans of cloth: sharper folds the net cannot follow
# without straining the placement.
TURN_WIDTH = 2.0
# A tuck's stretches must run within this angle of the line between them: the bodices'
# waists bend, so at 20 degrees their tucks were read in pieces (lone tucks tilted 62
# degrees, seam20 pulled 212 mm apart instead of 168).
STRAIGHT = np.radians(45.0)


@dataclass
class Tuck:
    """A tuck on the pleated side, in side coordinates (metres along the fold's
    direction): its roots (the stitched stretches' outer ends, sorted), its tip, and the
    two points of each stitch (K, 2)."""

    seam: str
    roots: tuple[float, float]
    tip: float
    pairs: np.ndarray


@dataclass
class PleatFold:
    """The folds of one panel: the side line (a rest point on it, unit direction), the
    fold lines (side coordinates, sorted) and the angle each turns the cloth by, and the
    groups of overlapping tucks (first and last root) with the tilt that levels each."""

    panel: str
    origin: np.ndarray
    direction: np.ndarray
    tucks: list[Tuck]
    lines: np.ndarray
    angles: np.ndarray
    groups: np.ndarray  # (G, 2)
    tilts: np.ndarray  # (G,)
    width: float = 0.0  # metres of cloth each turn is spread over

    def side(self, points: np.ndarray) -> np.ndarray:
        """Side coordinates of rest points (P, 2)."""
        return (np.asarray(points, float) - self.origin) @ self.direction

    def profile(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Folded position along the side and height off the panel (metres) of side
        coordinates s, each fold turning evenly over `width` of cloth."""
        return _integrate(self.lines, self.angles, self.groups, self.tilts, self.width, s)

    def fully_folded(self, s: np.ndarray) -> np.ndarray:
        """Position along the side with every fold turned all the way (180 degrees, sharp):
        the direction flips at each line."""
        lines = np.sort(self.lines)
        direction = np.where(np.arange(lines.size + 1) % 2 == 0, 1.0, -1.0)
        at = np.concatenate([[lines[0]], lines[0] + np.cumsum(direction[1:-1] * np.diff(lines))])
        s = np.asarray(s, float)
        k = np.searchsorted(lines, s, side="right")  # lines passed
        last = np.maximum(k - 1, 0)
        return np.where(k == 0, s, at[last] + direction[k] * (s - lines[last]))


GRID = 5e-5  # metres between the samples the profile is integrated on


def _direction(lines, angles, groups, tilts, width, grid) -> np.ndarray:
    """The cloth's direction angle at side coordinates `grid`: 0 outside the groups,
    turning by angles[i] across lines[i] -/+ width / 2, and less tilts[g] within groups[g]
    (turned on at its ends the same way)."""
    def ramp(at):
        if width <= 0.0:
            return (grid >= at).astype(float)
        return np.clip((grid - at) / width + 0.5, 0.0, 1.0)

    theta = np.zeros_like(grid)
    for line, angle in zip(lines, angles):
        theta += angle * ramp(line)
    for (g0, g1), tilt in zip(groups, tilts):
        theta -= tilt * (ramp(g0) - ramp(g1))
    return theta


def _integrate(lines, angles, groups, tilts, width, s) -> tuple[np.ndarray, np.ndarray]:
    """x, h at side coordinates s: the integral of (cos, sin) of the direction angle,
    starting from x = s, h = 0 before the first turn (on a GRID-spaced trapezoid rule)."""
    s = np.asarray(s, float)
    lo = min(np.min(lines), np.min(groups)) - width - GRID
    hi = max(np.max(lines), np.max(groups)) + width + GRID
    grid = np.linspace(lo, hi, int(np.ceil((hi - lo) / GRID)) + 1)
    theta = _direction(lines, angles, groups, tilts, width, grid)
    dx = np.diff(grid)
    x = lo + np.concatenate([[0.0], np.cumsum(0.5 * dx * (np.cos(theta[1:]) + np.cos(theta[:-1])))])
    h = np.concatenate([[0.0], np.cumsum(0.5 * dx * (np.sin(theta[1:]) + np.sin(theta[:-1])))])
    # Past either end the cloth runs straight along the side (theta = 0 there).
    xs = np.where(s < lo, s, np.where(s > hi, x[-1] + s - hi, np.interp(s, grid, x)))
    hs = np.where(s < lo, 0.0, np.where(s > hi, h[-1], np.interp(s, grid, h)))
    return xs, hs


# ----------------------------------------------------------------------------- finding


def _across(e: np.ndarray) -> np.ndarray:
    """The rest-plane unit vector at right angles to unit direction e."""
    return np.array([-e[1], e[0]])


def _tuck_line(a: np.ndarray, b: np.ndarray):
    """(unit direction, tip point, root points) of a seam sewing stretch a to stretch b
    of one straight side, facing each other; None for any other seam (a dart's legs meet
    at an angle, a sleeve's seam joins parallel sides)."""
    d = b - a
    gap = np.linalg.norm(d, axis=1)
    outer, inner = int(np.argmax(gap)), int(np.argmin(gap))
    if gap[outer] <= 0.0 or gap[inner] >= 0.9 * gap[outer]:
        return None
    e = d[outer] / gap[outer]
    # Both stretches run along the line, each towards the other from its outer end.
    for pts, sign in ((a, 1.0), (b, -1.0)):
        run = pts[inner] - pts[outer]
        length = np.linalg.norm(run)
        if length > 0.0 and sign * (run @ e) < np.cos(STRAIGHT) * length:
            return None
    off = (np.concatenate([a, b]) - a[outer]) @ _across(e)
    if np.abs(off).max() > np.tan(STRAIGHT) * 0.5 * gap[outer]:
        return None
    return e, 0.5 * (a[inner] + b[inner]), (a[outer], b[outer])


def find_tucks(panel: str, seams: list[PanelSeam]):
    """The tucks of one panel on its most pleated side: (origin, direction, tucks,
    names of the panel's other tucks left flat (another side))."""
    found = []
    for s in seams:
        if s.panel_a == s.panel_b == panel and len(s.points_a) >= 2:
            a, b = np.asarray(s.points_a, float), np.asarray(s.points_b, float)
            line = _tuck_line(a, b)
            if line is not None:
                found.append((s, a, b) + line)
    if not found:
        return None
    # The tucks along one line: those parallel to the largest such set, within a tuck's
    # depth of its line.
    best = []
    for _, _, _, e0, tip0, _ in found:
        same = [f for f in found if abs(f[3] @ e0) >= np.cos(STRAIGHT)
                and abs((f[4] - tip0) @ _across(e0)) <= np.linalg.norm(f[5][1] - f[5][0])]
        if len(same) > len(best):
            best = same
    e0 = best[0][3]
    e = np.sum([f[3] * np.sign(f[3] @ e0) for f in best], axis=0)
    e /= np.linalg.norm(e)
    origin = np.mean([f[4] for f in best], axis=0)
    tucks = []
    for s, a, b, _, tip, roots in best:
        r = sorted(float((p - origin) @ e) for p in roots)
        tucks.append(Tuck(s.name, (r[0], r[1]), float((tip - origin) @ e),
                          np.stack([(a - origin) @ e, (b - origin) @ e], axis=1)))
    left = [f[0].name for f in found if all(f[0] is not g[0] for g in best)]
    return origin, e, sorted(tucks, key=lambda t: t.roots[0]), left


# ---------------------------------------------------------------------------- folding


def plan_fold(panel: Panel, seams: list[PanelSeam], span: float) -> tuple[PleatFold | None, list[str]]:
    """The folds of a panel's tucks for a net of knot span `span` (m: pleats shallower
    than PLEAT_DEPTH spans stay flat, turns spread over TURN_WIDTH spans), and why any
    tuck is left flat."""
    min_depth = PLEAT_DEPTH * span
    found = find_tucks(panel.name, seams)
    if found is None:
        return None, []
    origin, e, tucks, left = found
    notes = [f"{name}: a tuck on another side" for name in left]
    sewn = _sewn_elsewhere(panel.name, seams, origin, e, max(_depth(t) for t in tucks))
    lines, angles, groups, kept = [], [], [], []
    for group in _overlapping(tucks):
        depth = min(_depth(t) for t in group)
        if depth < min_depth:
            notes += [f"{t.seam}: its pleat is {1e3 * depth:.1f} mm deep, under {1e3 * min_depth:.1f} mm"
                      for t in group]
            continue
        g0 = min(t.roots[0] for t in group)
        g1 = max(t.roots[1] for t in group)
        tol = _root_tolerance(group)
        glines = sorted({t.tip for t in group} | {_free_root(t, group, tol) for t in group} - {None})
        glines = np.array(glines)
        if glines.size % 2:
            notes += [f"{t.seam}: its pleat does not fold flat (odd fold count)" for t in group]
            continue
        # The layer sewn to other panels goes outside: the last one, unless only the
        # first is sewn (then the turns are mirrored).
        first = np.count_nonzero((sewn > g0) & (sewn < glines[0]))
        last = np.count_nonzero((sewn > glines[-1]) & (sewn < g1))
        sign = -1.0 if first > last else 1.0
        turns = sign * FOLD_ANGLE * np.where(np.arange(glines.size) % 2 == 0, 1.0, -1.0)
        trial = PleatFold(panel.name, origin, e, group, glines, turns, np.array([[g0, g1]]), np.zeros(1))
        pairs = np.concatenate([t.pairs for t in group])
        miss = np.abs(np.diff(trial.fully_folded(pairs.ravel()).reshape(-1, 2), axis=1)).max()
        if miss > tol:
            notes += [f"{t.seam}: folding at its tip does not bring its stitches together "
                      f"({1e3 * miss:.1f} mm apart)" for t in group]
            continue
        lines.append(glines)
        angles.append(turns)
        groups.append((g0, g1))
        kept += group
    if not groups:
        return None, notes
    lines, angles, groups = np.concatenate(lines), np.concatenate(angles), np.array(groups)
    width = TURN_WIDTH * span
    tilts = np.array([_level_tilt(lines, angles, g, width) for g in groups])
    return PleatFold(panel.name, origin, e, kept, lines, angles, groups, tilts, width), notes


def _depth(t: Tuck) -> float:
    """How deep a tuck folds: half the distance between its roots."""
    return 0.5 * (t.roots[1] - t.roots[0])


def _root_tolerance(group: list[Tuck]) -> float:
    """How near (m, along the side) a point counts as at a group's root or tip: a quarter
    of its narrowest tuck."""
    return 0.25 * min(t.roots[1] - t.roots[0] for t in group)


def _overlapping(tucks: list[Tuck]) -> list[list[Tuck]]:
    """Tucks (sorted by first root) grouped where their spans overlap."""
    groups: list[list[Tuck]] = []
    end = -np.inf
    for t in tucks:
        if groups and t.roots[0] < end:
            groups[-1].append(t)
            end = max(end, t.roots[1])
        else:
            groups.append([t])
            end = t.roots[1]
    return groups


def _free_root(t: Tuck, group: list[Tuck], tol: float):
    """None when one of the tuck's roots lies on another tuck's tip (a knife pleat folds
    there already), else its first root, which a lone tuck folds at."""
    for r in t.roots:
        if any(o is not t and abs(o.tip - r) <= tol for o in group):
            return None
    return t.roots[0]


def _sewn_elsewhere(panel: str, seams: list[PanelSeam], origin, e, near: float) -> np.ndarray:
    """Side coordinates of this panel's points sewn to other panels within `near` (m) of
    the side line."""
    by_seam = _sewn_by_seam(panel, seams, origin, e, near)
    return np.concatenate(list(by_seam.values())) if by_seam else np.zeros(0)


def _sewn_by_seam(panel: str, seams: list[PanelSeam], origin, e, near: float,
                  tucks: set | None = None) -> dict[str, np.ndarray]:
    """_sewn_elsewhere's points by the seam that sews them (seams with none left out);
    given the names of its tucks, the panel's other seams with itself too (darts)."""
    out: dict[str, list[np.ndarray]] = {}
    for s in seams:
        if s.panel_a == s.panel_b and (tucks is None or s.name in tucks):
            continue
        for name, p in ((s.panel_a, s.points_a), (s.panel_b, s.points_b)):
            if name == panel and len(p):
                rel = np.asarray(p, float).reshape(-1, 2) - origin
                out.setdefault(s.name, []).append((rel @ e)[np.abs(rel @ _across(e)) <= near])
    side = {name: np.concatenate(parts) for name, parts in out.items()}
    return {name: x for name, x in side.items() if x.size}


def pleat_faces(fold: PleatFold, seams: list[PanelSeam]) -> dict[str, tuple[str, ...]]:
    """The seams that join other panels to the layers of a folded pleat (a waistband
    onto its face), or the panel to itself across them (a dart from the pleat's folds),
    each with the tucks of that pleat: the simulator lets such a seam pull only once
    those tucks have nearly closed (SewingOptions.pleat_wait_gap), so the other panel
    comes down onto a pleat already folded rather than into the fold, and a dart closes
    over the folded layers instead of round one of them (dress_knife's seam43: pulled
    from the start, panel13's innermost layer came between its legs and held it 3.3 mm
    open)."""
    sewn = _sewn_by_seam(fold.panel, seams, fold.origin, fold.direction, max(_depth(t) for t in fold.tucks),
                         tucks={t.seam for t in fold.tucks})
    faces: dict[str, tuple[str, ...]] = {}
    for g0, g1 in fold.groups:
        group = [t for t in fold.tucks if g0 <= t.roots[0] and t.roots[1] <= g1]
        tucks = tuple(t.seam for t in group)
        tol = _root_tolerance(group)  # seams ending at a root stay out
        for name, x in sewn.items():
            if np.any((x > g0 + tol) & (x < g1 - tol)):
                faces[name] = tuple(dict.fromkeys(faces.get(name, ()) + tucks))
    return faces


def _level_tilt(lines, angles, group, width) -> float:
    """The rotation of a group's cloth that brings the cloth past it back to the side
    line (the turns at the group's ends are rounded too, so solved for, not the chord's
    angle)."""
    from scipy.optimize import brentq

    g0, g1 = group
    inside = (lines > g0) & (lines < g1)
    ends = np.array([g0 - width, g1 + width])

    def rise(tilt):
        h = _integrate(lines[inside], angles[inside], np.array([group]), np.array([tilt]), width, ends)[1]
        return h[1] - h[0]

    return brentq(rise, -0.5 * np.pi, 0.5 * np.pi, xtol=1e-12)


@dataclass
class PleatWarp:
    """A panel's fold as a displacement of its flat placement: rest points (P, 2) ->
    (P, 3), along the side's world direction and off the panel, outwards (away from the
    garment's centre); the panel's centroid keeps its place."""

    fold: PleatFold
    along: np.ndarray
    normal: np.ndarray
    shift: float

    def __call__(self, points: np.ndarray) -> np.ndarray:
        s = self.fold.side(points)
        x, h = self.fold.profile(s)
        return (x - s - self.shift)[:, None] * self.along + h[:, None] * self.normal


def fold_span(panel: str, seams: list[PanelSeam], span: float) -> float:
    """The knot span (m) at which a panel's net folds all its pleats: `span`, or finer
    where its shallowest pleat needs it, but not below span / PLEAT_REFINE."""
    found = find_tucks(panel, seams)
    if found is None:
        return span
    shallowest = min(_depth(t) for t in found[2])
    fine = np.floor(1e4 * shallowest / PLEAT_DEPTH) / 1e4  # whole 0.1 mm, so it passes plan_fold
    return float(np.clip(fine, span / PLEAT_REFINE, span))


def has_tucks(panels: list[Panel], seams: list[PanelSeam]) -> bool:
    """Whether any panel has a tuck or knife pleat (find_tucks)."""
    return any(find_tucks(p.name, seams) is not None for p in panels)


def fold_panels(panels: list[Panel], seams: list[PanelSeam], span: float,
                spans: dict | None = None) -> tuple[dict, dict]:
    """The warps of the panels whose tucks fold (by name) for nets of knot span `span`
    (m; spans: panel name -> its own, from fold_span), and notes on the tucks left flat."""
    spans = spans or {}
    worlds = {p.name: p.positions() for p in panels}
    centre = np.concatenate(list(worlds.values())).mean(axis=0)
    warps, notes = {}, {}
    for panel in panels:
        fold, why = plan_fold(panel, seams, spans.get(panel.name, span))
        if why:
            notes[panel.name] = why
        if fold is None:
            continue
        A = affine_map(panel)
        along = fold.direction @ A[:2]
        normal = np.cross(A[0], A[1])
        normal /= np.linalg.norm(normal)
        if normal @ (worlds[panel.name].mean(axis=0) - centre) < 0.0:
            normal = -normal
        s = fold.side(panel.rest)
        shift = float(np.mean(fold.profile(s)[0] - s))
        warps[panel.name] = PleatWarp(fold, along / np.linalg.norm(along), normal, shift)
    return warps, notes
