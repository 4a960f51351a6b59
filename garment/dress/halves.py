"""Panels round one leg that reach across the body's mid-plane, bent back into their own
half before sewing.

A flared trouser cuff (jumpsuit_777_03's cuff skirts, 67 cm wide at the hem) laid flat in
front of and behind its ankle reaches 19 cm past the middle between the legs, and the
other leg's cuff, laid the same way, reaches as far the other way: two flat loops at one
height whose insides overlap, neither inside the other. Sewn shut, they must cross, and
no rigid move parts them (each would have to move its own width). So each panel's part
past the mid-plane is bent, about a vertical line, through a quarter turn toward its
partner across the leg (a front panel backwards, a back panel forwards), the way a
tailor folds the excess round the leg. Bending a flat panel about a line is an isometry:
it starts unstrained. Front walls end nearer the mid-plane than back walls, so the two
never meet.
"""

from __future__ import annotations

import numpy as np

from .groups import members, merged
from .layout import Surface, crossings
from .paths import CAUGHT, seams_through_cloth

RADIUS = 0.06  # m, of the quarter turn: a knot span or more, so the B-spline follows it
WALL = {1: 0.015, -1: 0.03}  # m, from the mid-plane, of a front (turning +y) and a back (-y) panel's bent part
FLAT = 0.01  # m, a panel whose control points spread more than this across its plane is not bent


def bend(world: np.ndarray, side: float, turn: float, wall: float, radius: float = RADIUS) -> np.ndarray:
    """The control points `world` (..., 3) of a panel flat in a plane y = const, bent about
    the vertical line `radius` short of x = `wall` (on the panel's `side` of it, -1 or 1)
    through a quarter turn towards `turn` * y, and on from there in the plane x = wall:
    each point keeps its distance from the bend's start along the panel."""
    out = np.array(world, float)
    start = wall + side * radius
    d = -side * (out[..., 0] - start)  # how far past the bend's start, along the panel
    arc = np.clip(d, 0.0, 0.5 * np.pi * radius)
    past = np.maximum(d - 0.5 * np.pi * radius, 0.0)
    bent = d > 0.0
    out[..., 0] = np.where(bent, start - side * radius * np.sin(arc / radius), out[..., 0])
    out[..., 1] += np.where(bent, turn * (radius * (1.0 - np.cos(arc / radius)) + past), 0.0)
    return out


def into_own_half(patches, seams, body_V: np.ndarray, body_F: np.ndarray, panels=None) -> dict[str, float]:
    """Bend the panels of a seam, and the panels caught in its closing paths
    (seams_through_cloth, CAUGHT paths or more), back into their own half of the body
    where they all reach across its mid-plane (x through the body's middle) at a height
    where the body does not (below the crotch: between the legs). Kept only when no seam
    then closes through those panels and nothing crosses that did not. Returns each bent
    patch's width bent round (m)."""
    panels = panels or [p.name for p in patches]
    surface = Surface.of(patches)  # sampled once: bends move control points, not the sampling
    found = {k for k, n in seams_through_cloth(patches, seams, panels, surface).items() if n >= CAUGHT}
    if not found:
        return {}
    patches_of = members(patches, panels)
    group_of = {p.name: panel for p, panel in zip(patches, panels)}
    by_name = {s.name: s for s in seams}
    middle = np.asarray(body_V, float)[:, :2].mean(axis=0)

    # The panels of each catching seam with those it catches; groups sharing a panel joined.
    groups = merged([{caught, group_of[by_name[seam].patch_a], group_of[by_name[seam].patch_b]}
                      for seam, caught in found])
    bent: dict[str, float] = {}
    for involved in groups:
        bent.update(_bend_group(patches, seams, panels, body_V, body_F, surface, patches_of, involved, found, middle))
    return bent


def _bend_group(patches, seams, panels, body_V, body_F, surface, patches_of, involved, found, middle) -> dict[str, float]:
    """into_own_half for one group of pattern panels (`involved`); {} when it is not kept."""
    bendable = [p for panel in sorted(involved) for p in patches_of[panel] if _reaches_across(p.world, middle[0])]
    if not bendable:
        return {}
    points = np.concatenate([p.world.reshape(-1, 3) for p in bendable])
    band = (body_V[:, 2] > points[:, 2].min() - RADIUS) & (body_V[:, 2] < points[:, 2].max() + RADIUS)
    if np.any(np.abs(body_V[band, 0] - middle[0]) < max(WALL.values()) + RADIUS):
        return {}  # the body fills the middle there (the trunk): no half to bend into
    before = {k: len(v) for k, v in crossings(patches, body_V, body_F, surface).items()}
    start = {p.name: p.world.copy() for p in bendable}
    bent: dict[str, float] = {}
    for p in bendable:
        w = p.world.reshape(-1, 3)
        if np.ptp(w[:, 1]) > FLAT:
            continue
        side = np.sign(w[:, 0].mean() - middle[0]) or 1.0
        turn = np.sign(middle[1] - w[:, 1].mean()) or 1.0
        wall = middle[0] + side * WALL[int(turn)]
        p.world = np.ascontiguousarray(bend(p.world, side, turn, wall))
        bent[p.name] = float(np.max(-side * (w[:, 0] - wall - side * RADIUS)))
    after = {k for k, n in seams_through_cloth(patches, seams, panels, surface).items() if n >= CAUGHT}
    crosses = any(len(v) > before.get(k, 0) for k, v in crossings(patches, body_V, body_F, surface).items())
    if not bent or crosses or after - found or any(panel in involved for _, panel in after):
        for p in bendable:
            p.world = start[p.name]
        return {}
    return bent


def _reaches_across(world: np.ndarray, x: float) -> bool:
    w = world.reshape(-1, 3)
    return bool(w[:, 0].min() < x < w[:, 0].max())
