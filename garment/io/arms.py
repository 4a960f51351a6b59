"""A standing body's arms, found from its mesh alone, and the body with its arms raised.

An A-pose body's hands hang beside its hips, and a wide skirt laid flat around the hips
in the pattern's layout covers them: sewn shut there, the skirt closes round the hands,
which a fitted waist cannot do (the arm reaches the hands outside the waistband), so its
side seams stall over the forearms. Dressed with the arms raised clear of the skirt and
lowered while the body grows back, the skirt hangs inside the arms.

The arms are what hangs free beside the torso: cut the body at a height and keep the
triangles below it; below the armpits the two arms are components of their own, one on
each side of the torso. The highest such cut is taken (the armpit); the arm is the part
below it, and it turns about the middle of its cut, outwards, blended into the torso over
BLEND so the mesh stays closed (linear blend skinning with two bones).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

CUT_STEP = 0.01  # of the body's height, between the cuts tried
CUT_RANGE = (0.85, 0.45)  # of the height above the feet: where armpits can be
ARM_SHARE = 0.03  # of the body's vertices, at least, in each arm below the cut
BLEND = 0.1  # m below the cut over which an arm turns from not at all to fully


@dataclass
class Arm:
    vertices: np.ndarray  # indices of the body vertices below the armpit cut
    weights: np.ndarray  # (len(vertices),) how fully each turns, 0 at the cut to 1
    pivot: np.ndarray  # (3,) the middle of the cut
    axis: np.ndarray  # (3,) unit: a positive turn about it lifts the hand outwards


def find_arms(V: np.ndarray, F: np.ndarray) -> list[Arm]:
    """The two arms of a Z-up standing body (V (n, 3) m, F (m, 3)), or [] when no cut
    between CUT_RANGE of its height leaves two side components beside a middle one."""
    z = V[:, 2]
    lo, height = z.min(), np.ptp(z)
    n = len(V)
    for frac in np.arange(CUT_RANGE[0], CUT_RANGE[1], -CUT_STEP):
        cut = lo + frac * height
        arms = _side_components(V, F[(z[F] < cut).all(axis=1)], n)
        if arms is not None:
            return [_arm(V, idx, cut) for idx in arms]
    return []


def _side_components(V, F, n):
    """The vertex sets of two components of the faces F, one on either side of the
    largest one (the torso), each holding ARM_SHARE of the vertices; else None."""
    if len(F) == 0:
        return None
    rows = F.ravel()
    cols = np.roll(F, 1, axis=1).ravel()
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    used = np.unique(F)
    labels, counts = np.unique(label[used], return_counts=True)
    big = labels[counts >= ARM_SHARE * n]
    if len(big) < 3:
        return None
    members = [used[label[used] == b] for b in big]
    torso = max(range(len(big)), key=lambda k: len(members[k]))
    centre = V[members[torso]].mean(axis=0)
    # The lateral direction: the torso's widest horizontal axis.
    spread = V[members[torso]][:, :2] - centre[:2]
    lateral = np.linalg.eigh(spread.T @ spread)[1][:, -1]
    side = {k: float((V[m].mean(axis=0)[:2] - centre[:2]) @ lateral) for k, m in enumerate(members) if k != torso}
    left, right = min(side, key=side.get), max(side, key=side.get)
    if not side[left] < 0.0 < side[right]:
        return None
    return [members[left], members[right]]


def _arm(V, idx, cut) -> Arm:
    P = V[idx]
    ring = P[P[:, 2] > cut - 0.02]
    pivot = ring.mean(axis=0) if len(ring) else P.mean(axis=0)
    weights = np.clip((cut - P[:, 2]) / BLEND, 0.0, 1.0)
    # Outwards from the pivot, horizontally; the turn that lifts it is about up x out.
    out = P.mean(axis=0) - pivot
    out[2] = 0.0
    out /= np.linalg.norm(out) or 1.0
    axis = np.cross(out, [0.0, 0.0, 1.0])
    # Check the sign on the hand: the lowest point must rise.
    low = P[np.argmin(P[:, 2])] - pivot
    if (turn(low[None], axis, 0.1) - low[None])[0, 2] < 0.0:
        axis = -axis
    return Arm(np.asarray(idx), weights, pivot, axis)


def turn(X: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """X (k, 3) turned by `angle` about the unit `axis` through the origin (Rodrigues)."""
    cos, sin = np.cos(angle), np.sin(angle)
    return X * cos + np.cross(axis, X) * sin + np.outer(X @ axis, axis) * (1.0 - cos)


def raised(V: np.ndarray, arms: list[Arm], angle: float) -> np.ndarray:
    """V with each arm turned up and out by `angle` (radians) about its pivot, blended
    into the torso by its weights."""
    out = V.copy()
    if angle == 0.0:
        return out
    for a in arms:
        X = V[a.vertices] - a.pivot
        turned = turn(X, a.axis, angle)
        out[a.vertices] = V[a.vertices] + a.weights[:, None] * (turned - X)
    return out
