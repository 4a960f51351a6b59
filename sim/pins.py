"""Pinned control points: which ones, and where they are at time t."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.patches import Patch


@dataclass
class PinGroup:
    """Global control-point indices held at rest positions + velocity * active time."""

    indices: np.ndarray
    velocity: np.ndarray  # (3,) m/s
    start: float = 0.0
    duration: float = np.inf

    def displacement(self, t: float) -> np.ndarray:
        active = np.clip(t - self.start, 0.0, self.duration)
        return self.velocity * active


def select(shape: tuple[int, int], corners=(), sides=(), box=None, depth: int = 1) -> np.ndarray:
    """Local (i * m + j) indices of control points picked by corner, side or parameter box.

    corners: "u0v0", "u1v0", "u0v1", "u1v1"; sides: "u0", "u1", "v0", "v1"; box:
    ((u_min, v_min), (u_max, v_max)) on Greville abscissae normalised to [0, 1]; depth:
    rows counted from the boundary (2 also fixes the boundary tangent).
    """
    n, m = shape
    mask = np.zeros((n, m), bool)
    d_u, d_v = min(depth, n), min(depth, m)
    rows = {"u0": slice(0, d_u), "u1": slice(n - d_u, n)}
    cols = {"v0": slice(0, d_v), "v1": slice(m - d_v, m)}
    for c in corners:
        mask[rows[c[:2]], cols[c[2:]]] = True
    for s in sides:
        if s in rows:
            mask[rows[s], :] = True
        else:
            mask[:, cols[s]] = True
    if box is not None:
        (u0, v0), (u1, v1) = box
        s = Patch.greville(n) / (n - 2)
        t = Patch.greville(m) / (m - 2)
        eps = 1e-9
        mask |= ((s >= u0 - eps) & (s <= u1 + eps))[:, None] & ((t >= v0 - eps) & (t <= v1 + eps))[None, :]
    return np.flatnonzero(mask.ravel())
