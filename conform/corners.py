"""Splitting the boundary loop into four sides at four corners (docs/design.md section 4b.1).

Automatic choice: candidates are the sharpest convex turns of the outline (turning angle
measured over an arc-length window, so mesh noise does not count), plus hinted vertices
(pattern vertices, seam endpoints). Every choice of four candidates is scored by
- corner angles: interior angles near 90 degrees are best, ((theta - 90) / 45)^2 each;
- sides should be straight on the whole: a side's net turning T (the change of its
  direction from just after its first corner to just before its last, so a dart or a
  wave that turns back counts as nothing) costs (T / 45)^2;
- balance: opposite sides of very different length squeeze the spans, log(L0 / L2)^2 +
  log(L1 / L3)^2, and a side shorter than a quarter of the mean side costs extra;
- hints: a corner on a hinted vertex (pattern vertex, seam end) earns a small bonus;
points on darts and pleats (seams that sew a panel to itself) are never corners.
The lowest score wins. Users override with four vertex ids or four positions.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from sim.patches import Panel

from .boundary import Outline, PanelError

HINT_BONUS = 0.3
MIN_TURN_DEG = 12.0
MAX_CANDIDATES = 18


class TooFewCorners(ValueError):
    """An outline with fewer than four points that can be corners."""


def window_length(outline: Outline) -> float:
    """Arc-length window over which turning angles are measured: a few boundary edges,
    at least 1 % of the perimeter."""
    seg = np.diff(outline.s)
    return float(max(2.5 * np.median(seg), 0.01 * outline.perimeter))


def turning_angles(outline: Outline, window: float | None = None) -> np.ndarray:
    """Signed turning angle (degrees, positive = convex for a counter-clockwise loop) at
    each loop point, between the chords to the points `window` before and after it."""
    w = window_length(outline) if window is None else window
    s = outline.s[:-1]
    p = outline.points
    before, after = outline.at(s - w), outline.at(s + w)
    d_in, d_out = p - before, after - p
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    dot = (d_in * d_out).sum(axis=1)
    return np.degrees(np.arctan2(cross, dot))


def _arc_gap(outline: Outline, i, j) -> np.ndarray:
    """Arc length from loop point i forward to j."""
    s = outline.s[:-1]
    return np.mod(s[j] - s[i], outline.perimeter)


def candidates(outline: Outline, hints=(), hints_only: bool = False, avoid=()) -> np.ndarray:
    """Loop positions that may become corners: the sharpest convex turns and the hints,
    never a position in `avoid` (e.g. on a dart)."""
    w = window_length(outline)
    tau = turning_angles(outline, w)
    B = len(outline)
    hints = np.unique(np.asarray(hints, dtype=np.int64))
    if hints_only and hints.size >= 4:
        pool = hints
    else:
        # Local maxima of the turning angle within the window (non-maximum suppression).
        order = np.argsort(-tau)
        taken = np.zeros(B, bool)
        keep = []
        s = outline.s[:-1]
        for i in order:
            if tau[i] < MIN_TURN_DEG:
                break
            d = np.abs(s - s[i])
            d = np.minimum(d, outline.perimeter - d)
            if np.any(taken & (d < w)):
                continue
            taken[i] = True
            keep.append(i)
        pool = np.unique(np.concatenate([np.asarray(keep, np.int64), hints]))
    avoid = np.asarray(avoid, dtype=np.int64)
    if avoid.size:
        pool = pool[~np.isin(pool, avoid)]
    pool = pool[np.argsort(-tau[pool])][:MAX_CANDIDATES]
    if pool.size < 4:
        # Too few turns (round shapes): add evenly spaced points.
        extra = np.searchsorted(outline.s[:-1], np.linspace(0, outline.perimeter, 12, endpoint=False))
        extra = np.minimum(extra, B - 1)
        # None next to a candidate or an avoided point: an evenly spaced point one loop
        # point past a seam's end is a corner that seam wraps round (skirt_06: a cut
        # sewn up to a sharp tip, the corner 3 mm past it), and one beside a dart tip
        # is that dart tip.
        near = np.concatenate([pool, avoid])
        clear = extra[_clear_of(outline, extra, near, 0.5 * w)]
        if np.unique(np.concatenate([pool, clear])).size < 4:
            # A spiky outline leaves too few clear points: any not avoided will do.
            clear = extra[~np.isin(extra, avoid)]
        pool = np.unique(np.concatenate([pool, clear]))
    return np.sort(pool)


def _arc_distance(outline: Outline, pos, others) -> np.ndarray:
    """(len(pos), len(others)) arc length between loop positions, the shorter way round."""
    s = outline.s[:-1]
    d = np.abs(s[np.asarray(pos)][:, None] - s[np.asarray(others)][None, :])
    return np.minimum(d, outline.perimeter - d)


def _clear_of(outline: Outline, pos: np.ndarray, others: np.ndarray, gap: float) -> np.ndarray:
    """(len(pos),) bool: loop positions farther than `gap` (arc length) from all `others`."""
    return ~(_arc_distance(outline, pos, others) <= gap).any(axis=1)


def _cumulative_turning(outline: Outline) -> np.ndarray:
    """Unwrapped direction (degrees) of each loop segment k (point k to k + 1)."""
    seg = np.roll(outline.points, -1, axis=0) - outline.points
    a = np.degrees(np.arctan2(seg[:, 1], seg[:, 0]))
    turn = (np.diff(a) + 180.0) % 360.0 - 180.0
    return np.concatenate([[a[0]], a[0] + np.cumsum(turn)])


def net_turning(outline: Outline, a: int, b: int, window: float) -> float:
    """Net turning (degrees) of the side from loop point a forward to b, measured between
    the chords one window after a and one window before b."""
    s, P = outline.s[:-1], outline.perimeter
    sa = s[a]
    sb = sa + (s[b] - sa) % P
    w = min(window, 0.25 * (sb - sa))
    p0, p1 = outline.at(np.array([sa, sa + w])), outline.at(np.array([sb - w, sb]))
    d0, d1 = p0[1] - p0[0], p1[1] - p1[0]
    D = np.degrees(np.arctan2(d0[0] * d1[1] - d0[1] * d1[0], d0 @ d1))
    # The raw segment turning between the two chords decides how many full turns to add.
    phi = _cumulative_turning(outline)
    x0, x1 = (sa + w) % P, (sb - w) % P
    k0 = int(np.searchsorted(s, x0, side="right") - 1)
    k1 = int(np.searchsorted(s, x1, side="right") - 1)
    if x0 <= x1:
        raw = phi[k1] - phi[k0]
    else:  # the side passes the start of the loop
        last = len(outline) - 1
        raw = (phi[last] - phi[k0]) + ((phi[0] - phi[last] + 180.0) % 360.0 - 180.0) + (phi[k1] - phi[0])
    return float(D + 360.0 * np.round((raw - D) / 360.0))


def pick_corners(outline: Outline, hints=(), hints_only: bool = False, avoid=()) -> np.ndarray:
    """Four loop positions, in loop order, starting with the lowest-left corner. hints:
    loop positions preferred as corners; avoid: loop positions never used."""
    w = window_length(outline)
    tau = turning_angles(outline, w)
    cand = candidates(outline, hints, hints_only, avoid)
    hints = np.asarray(hints, dtype=np.int64)
    is_hint = np.zeros(len(outline), bool)
    if hints.size:
        is_hint = (_arc_distance(outline, np.arange(len(outline)), hints) < 0.5 * w).any(axis=1)

    k = cand.size
    if k < 4:
        raise TooFewCorners(f"only {k} points of its outline can be corners, a patch needs 4")
    net = np.zeros((k, k))
    for i in range(k):
        for j in range(k):
            if i != j:
                net[i, j] = net_turning(outline, cand[i], cand[j], w)
    combos = np.array(list(combinations(range(k), 4)))
    C = cand[combos]  # (K, 4) loop positions, increasing
    theta = 180.0 - tau[C]
    cost = (((theta - 90.0) / 45.0) ** 2).sum(axis=1)
    for side in range(4):
        cost += (net[combos[:, side], combos[:, (side + 1) % 4]] / 45.0) ** 2
    # Balance of the four sides.
    L = np.stack([_arc_gap(outline, C[:, q], C[:, (q + 1) % 4]) for q in range(4)], axis=1)
    L = np.maximum(L, 1e-12)
    cost += np.log(L[:, 0] / L[:, 2]) ** 2 + np.log(L[:, 1] / L[:, 3]) ** 2
    short = np.clip(np.log(0.25 * outline.perimeter / 4.0 / L), 0.0, None)
    cost += 4.0 * (short**2).sum(axis=1)
    cost -= HINT_BONUS * is_hint[C].sum(axis=1)
    best = C[int(np.argmin(cost))]
    return canonical_order(outline, best)


def canonical_order(outline: Outline, corners) -> np.ndarray:
    """Corners in loop order, rotated so the first is the lowest-left (min x + y)."""
    c = np.sort(np.asarray(corners, dtype=np.int64))
    p = outline.points[c]
    first = int(np.argmin(p[:, 0] + p[:, 1]))
    return np.roll(c, -first)


def loop_positions(outline: Outline, points, tol: float) -> np.ndarray:
    """Loop positions of the outline points within tol (metres) of the given points."""
    points = np.asarray(points, float).reshape(-1, 2)
    if points.size == 0:
        return np.zeros(0, np.int64)
    from scipy.spatial import cKDTree

    d, k = cKDTree(outline.points).query(points)
    return np.unique(k[d <= tol])


def corners_from_user(panel: Panel, outline: Outline, spec) -> np.ndarray:
    """Four loop positions from four source vertex ids (ints) or positions ((x, y) in the
    rest layout, metres: the nearest boundary vertex). Kept in loop order from the first."""
    spec = list(spec)
    if len(spec) != 4:
        raise PanelError(panel, f"--corners needs exactly 4 corners, got {len(spec)}")
    out = []
    ids = np.asarray(panel.vertex_ids)[outline.vertices]
    for c in spec:
        if np.ndim(c) == 0:
            hit = np.nonzero(ids == int(c))[0]
            if hit.size == 0:
                raise PanelError(panel, f"corner vertex {int(c)} is not on the panel's boundary")
            out.append(int(hit[0]))
        else:
            p = np.asarray(c, float)
            out.append(int(np.argmin(np.linalg.norm(outline.points - p, axis=1))))
    if len(set(out)) != 4:
        raise PanelError(panel, "the 4 corners must be different boundary vertices")
    first = out[0]
    return np.asarray(sorted(out, key=lambda k: (k - first) % len(outline)))
