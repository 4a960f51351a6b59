"""Closing paths round bodies: where a seam sample's straight path to its partner passes
through a body, both sides pull towards a waypoint beside the body instead.

Pulled straight, such a seam presses its cloth into the body: a strap tip laid in front
of a shoulder and its partner behind it close through the shoulder, so the strap lodges
against it (the GarmentCode dress_00's strap stitches stalled 77-89 mm open from the
12th sewing step on, contacts down to 1e-7 m, while the seam stiffness grew 4000-fold).
Lifting the panels once at the start (garment/dress/layout.py) is not enough: the rest of
the garment closing round the torso drags the straps down again. So the paths are
checked at the start of every step, and a blocked one goes round: the waypoint is the
path's midpoint moved sideways (perpendicular to the path) by the least of a few heights
that clears the body on both legs, in whichever of a ring of directions is shortest.
Directions along the seam itself are left out: they slide the seam sideways, and on a
sloping shoulder the shortest way over is down the slope to the arm, where the straps then
closed at the shoulder's tip and were pinched as the body grew back. Once the straight
path clears the body the sample pulls straight again, unless it cleared it on the other
side: a routed path keeps its side (`waypoints`, previous).

Where seams meet (a cuff's side seam ending on its seams to the sleeve and the flounce:
four panel corners that become one point), the samples at the junction go round together,
to one waypoint that clears the body from every corner (`junction_waypoints`). Each on its
own, upper_garment_06's left-cuff junction sent the cuff's pair under the wrist and the
flounce's over it, one corner pulled to two waypoints on opposite sides, and the four
corners stayed round the wrist 17-31 mm apart until the run failed.
"""

from __future__ import annotations

import numpy as np

from ..intersect import Triangles, crossing_pairs

MIN_GAP = 2e-3  # m: shorter paths are not checked (a closing seam lies on the cloth)
DIRECTIONS = 12  # around each path
HEIGHTS = 0.01 * 1.5 ** np.arange(10)  # m: 1 to 38 cm from the path's midpoint
ALONG = 0.5  # directions within 30 degrees of across the seam (|d . seam tangent| <= 0.5)


def through(a: np.ndarray, b: np.ndarray, body: Triangles) -> np.ndarray:
    """(K,) bool: whether the segment a_k b_k passes through a triangle of the body."""
    hit = np.zeros(len(a), bool)
    hit[body.crossed(a, b)[:, 0]] = True
    return hit


def through_cloth(a: np.ndarray, b: np.ndarray, pieces: np.ndarray, x: np.ndarray, faces: np.ndarray,
                  face_piece: np.ndarray) -> np.ndarray:
    """(K,) bool: whether the segment a_k b_k passes through a cloth triangle (x[faces],
    of piece face_piece) of a piece other than its own two (pieces (K, 2))."""
    hit = np.zeros(len(a), bool)
    pairs = Triangles(x, faces).crossed(a, b)
    if len(pairs):
        other = (face_piece[pairs[:, 1], None] != pieces[pairs[:, 0]]).all(axis=1)
        hit[pairs[other, 0]] = True
    return hit


def enclosed(a: np.ndarray, b: np.ndarray, p: np.ndarray, body: Triangles) -> np.ndarray:
    """(K,) bool: whether the body's edges pass through the triangle a_k p_k b_k, that
    is, whether the loop from a over p to b and straight back goes round it."""
    hit = np.zeros(len(a), bool)
    E = body.edges
    if len(a) == 0 or len(E) == 0:
        return hit
    x = np.concatenate([np.stack([a, p, b], axis=1).reshape(-1, 3), body.V])
    triangles = np.arange(3 * len(a)).reshape(-1, 3)
    hit[crossing_pairs(x, E + 3 * len(a), triangles)[:, 1]] = True
    return hit


def waypoints(a: np.ndarray, b: np.ndarray, body: Triangles,
              tangent: np.ndarray | None = None,
              previous: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Paths a_k -> b_k (K, 3) against the body, the seam running along tangent_k
    (K, 3; zero or None: any direction): (routed (K,) bool, waypoints (K, 3)). A path is
    routed when it passes through the body and some waypoint clears it; waypoints of
    the others are their midpoints.

    previous (K, 3): the waypoints of the last step (NaN: not routed then). A routed path
    keeps its side of the body: its new waypoint lies on the same side of the path, and
    it stays routed while the loop over its last waypoint still goes round the body even
    where the straight path has come clear on the other side (upper_garment_06's cuff side
    seam, routed over the wrist, slid down the arm's side until its straight paths passed
    under the wrist, and closed there while the flounce's side seam closed over it)."""
    mid = 0.5 * (a + b)
    routed = np.zeros(len(a), bool)
    points = mid.copy()
    through_now = through(a, b, body)
    going = through_now.copy()
    side = np.zeros_like(a)
    if previous is not None:
        kept = np.flatnonzero(np.isfinite(previous[:, 0]))
        side[kept] = previous[kept] - mid[kept]
        if len(kept):
            going[kept] |= enclosed(a[kept], b[kept], previous[kept], body)
    todo = np.flatnonzero(going)
    if len(todo) == 0:
        return routed, points
    ring = _ring(b[todo] - a[todo])  # (T, DIRECTIONS, 3)
    across = np.ones(ring.shape[:2], bool)
    if tangent is not None:
        t = tangent[todo] / np.maximum(np.linalg.norm(tangent[todo], axis=1, keepdims=True), 1e-300)
        across = np.abs(np.einsum("tdk,tk->td", ring, t)) <= ALONG + 1e-12
        across[~across.any(axis=1)] = True  # a seam along its own path: any direction
    # On its side: a new waypoint on the same side of the path, and where the straight path
    # has come clear, a loop that still goes round the body.
    same_side = np.einsum("tdk,tk->td", ring, side[todo]) >= 0.0
    wrap = ~through_now[todo]  # routed only because its loop goes round the body
    found, w = _detour(a[todo], b[todo], ring, across & same_side, body, wrap)
    again = np.flatnonzero(~found & ~wrap & (across & ~same_side).any(axis=1))
    if len(again):  # no way round on its side: any side
        found[again], w[again] = _detour(a[todo[again]], b[todo[again]], ring[again], across[again], body)
    routed[todo] = found
    points[todo[found]] = w[found]
    return routed, points


def _detour(a: np.ndarray, b: np.ndarray, ring: np.ndarray, allowed: np.ndarray, body: Triangles,
            wrap: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For each path a_k -> b_k, the shortest waypoint at the least height (HEIGHTS) above
    its midpoint in an allowed direction of its ring (K, DIRECTIONS, 3) whose legs clear
    the body, and for those in wrap (K,) bool whose loop goes round it (`enclosed`):
    (found (K,) bool, waypoints (K, 3))."""
    mid = 0.5 * (a + b)
    found = np.zeros(len(a), bool)
    points = mid.copy()
    todo = np.arange(len(a))
    for h in HEIGHTS:
        w = mid[todo, None, :] + h * ring[todo]  # (T, DIRECTIONS, 3)
        A = np.broadcast_to(a[todo, None, :], w.shape).reshape(-1, 3)
        B = np.broadcast_to(b[todo, None, :], w.shape).reshape(-1, 3)
        W = w.reshape(-1, 3)
        legs = through(np.concatenate([A, W]), np.concatenate([W, B]), body)
        blocked = (legs[:len(W)] | legs[len(W):]).reshape(len(todo), DIRECTIONS)
        if wrap is not None and wrap[todo].any():
            rows = np.repeat(wrap[todo], DIRECTIONS)
            blocked.reshape(-1)[rows] |= ~enclosed(A[rows], B[rows], W[rows], body)
        length = np.linalg.norm(w - a[todo, None], axis=2) + np.linalg.norm(w - b[todo, None], axis=2)
        length[blocked | ~allowed[todo]] = np.inf
        best = np.argmin(length, axis=1)
        ok = np.isfinite(length[np.arange(len(todo)), best])
        found[todo[ok]] = True
        points[todo[ok]] = w[ok, best[ok]]
        todo = todo[~ok]
        if len(todo) == 0:
            break
    return found, points


def junction_waypoints(groups: list[np.ndarray], a: np.ndarray, b: np.ndarray, routed: np.ndarray,
                       points: np.ndarray, body: Triangles, previous: np.ndarray | None = None) -> None:
    """Samples that share a side point (each group: indices into a, b (K, 3) of the open
    samples at one junction) go round together: where any of a group is routed, all of it
    pulls to the one point, among heights above its corners' centroid in the directions
    across each member's path, whose legs from every corner clear the body and are
    shortest in sum, on the side of the group's last waypoints (previous (K, 3), NaN: none)
    where there is one. routed (K,) and points (K, 3) are updated in place; a group with no
    such point keeps its samples' own waypoints."""
    for g in groups:
        if not routed[g].any():
            continue
        corners = np.concatenate([a[g], b[g]])
        centre = corners.mean(axis=0)
        ring = _ring(b[g] - a[g]).reshape(-1, 3)
        w = np.concatenate([(centre + HEIGHTS[:, None, None] * ring[None]).reshape(-1, 3), points[g][routed[g]]])
        A = np.repeat(corners, len(w), axis=0)
        W = np.tile(w, (len(corners), 1))
        blocked = through(A, W, body).reshape(len(corners), len(w)).any(axis=0)
        length = np.linalg.norm(W - A, axis=1).reshape(len(corners), len(w)).sum(axis=0)
        length[blocked] = np.inf
        if previous is not None and np.isfinite(previous[g, 0]).any():
            side = np.nanmean(previous[g] - centre, axis=0)
            mine = np.where((w - centre) @ side >= 0.0, length, np.inf)
            length = mine if np.isfinite(mine).any() else length
        best = int(np.argmin(length))
        if np.isfinite(length[best]):
            routed[g] = True
            points[g] = w[best]


def _ring(axis: np.ndarray) -> np.ndarray:
    """(K, DIRECTIONS, 3) unit directions perpendicular to each axis (K, 3)."""
    e = axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-300)
    helper = np.where(np.abs(e[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(e, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(e, u)
    theta = 2.0 * np.pi * np.arange(DIRECTIONS) / DIRECTIONS
    return np.cos(theta)[None, :, None] * u[:, None, :] + np.sin(theta)[None, :, None] * v[:, None, :]
