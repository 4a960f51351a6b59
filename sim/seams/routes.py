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
path clears the body the sample pulls straight again.
"""

from __future__ import annotations

import numpy as np

from ..intersect import crossing_pairs

MIN_GAP = 2e-3  # m: shorter paths are not checked (a closing seam lies on the cloth)
DIRECTIONS = 12  # around each path
HEIGHTS = 0.01 * 1.5 ** np.arange(10)  # m: 1 to 38 cm from the path's midpoint
ALONG = 0.5  # directions within 30 degrees of across the seam (|d . seam tangent| <= 0.5)


def through(a: np.ndarray, b: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(K,) bool: whether the segment a_k b_k passes through a triangle of (V, F)."""
    hit = np.zeros(len(a), bool)
    if len(a) == 0 or len(F) == 0:
        return hit
    x = np.concatenate([np.stack([a, b], axis=1).reshape(-1, 3), V])
    edges = np.arange(2 * len(a)).reshape(-1, 2)
    hit[crossing_pairs(x, edges, np.asarray(F) + 2 * len(a))[:, 0]] = True
    return hit


def waypoints(a: np.ndarray, b: np.ndarray, V: np.ndarray, F: np.ndarray,
              tangent: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Paths a_k -> b_k (K, 3) against the body (V, F), the seam running along tangent_k
    (K, 3; zero or None: any direction): (routed (K,) bool, waypoints (K, 3)). A path is
    routed when it passes through the body and some waypoint clears it; waypoints of
    the others are their midpoints."""
    mid = 0.5 * (a + b)
    routed = np.zeros(len(a), bool)
    points = mid.copy()
    todo = np.flatnonzero(through(a, b, V, F))
    if len(todo) == 0:
        return routed, points
    ring = _ring(b[todo] - a[todo])  # (T, DIRECTIONS, 3)
    across = np.ones(ring.shape[:2], bool)
    if tangent is not None:
        t = tangent[todo] / np.maximum(np.linalg.norm(tangent[todo], axis=1, keepdims=True), 1e-300)
        across = np.abs(np.einsum("tdk,tk->td", ring, t)) <= ALONG + 1e-12
        across[~across.any(axis=1)] = True  # a seam along its own path: any direction
    for h in HEIGHTS:
        w = mid[todo, None, :] + h * ring  # (T, DIRECTIONS, 3)
        A = np.broadcast_to(a[todo, None, :], w.shape).reshape(-1, 3)
        B = np.broadcast_to(b[todo, None, :], w.shape).reshape(-1, 3)
        W = w.reshape(-1, 3)
        legs = through(np.concatenate([A, W]), np.concatenate([W, B]), V, F)  # one body BVH for both legs
        blocked = (legs[:len(W)] | legs[len(W):]).reshape(len(todo), DIRECTIONS)
        length = np.linalg.norm(w - a[todo, None], axis=2) + np.linalg.norm(w - b[todo, None], axis=2)
        length[blocked | ~across] = np.inf
        best = np.argmin(length, axis=1)
        found = np.isfinite(length[np.arange(len(todo)), best])
        k = todo[found]
        routed[k] = True
        points[k] = w[found, best[found]]
        todo, ring, across = todo[~found], ring[~found], across[~found]
        if len(todo) == 0:
            break
    return routed, points


def _ring(axis: np.ndarray) -> np.ndarray:
    """(K, DIRECTIONS, 3) unit directions perpendicular to each axis (K, 3)."""
    e = axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-300)
    helper = np.where(np.abs(e[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(e, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(e, u)
    theta = 2.0 * np.pi * np.arange(DIRECTIONS) / DIRECTIONS
    return np.cos(theta)[None, :, None] * u[:, None, :] + np.sin(theta)[None, :, None] * v[:, None, :]
