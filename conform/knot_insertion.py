"""Exact refinement of conformed garments: knot insertion at every span midpoint.

A refined patch set describes the same surfaces (rest and world) with twice the control
points per direction per level, so a garment sewn at a coarse knot span can continue at a
fine one from exactly the same shape (garment bench garment --refine). Parameters double
per level: seam samples and boundary intervals are rescaled to match.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from sim.patches import Patch, PatchSet
from sim.seams.spec import BoundaryInterval

from .control_net import refine


def refine_net(X: np.ndarray, levels: int) -> np.ndarray:
    """(n, m, d) net -> the same surface after `levels` rounds of midpoint knot insertion."""
    for _ in range(levels):
        X = refine(X)
    return X


def refine_patchset(ps: PatchSet, levels: int, world: dict[str, np.ndarray] | None = None) -> PatchSet:
    """`ps` refined `levels` times; world[name] (n, m, 3), when given, replaces a patch's
    world net first (a sewn state)."""
    world = world or {}
    scale = 2.0 ** levels
    patches = [Patch(p.name, refine_net(p.rest, levels), refine_net(world.get(p.name, p.world), levels))
               for p in ps.patches]

    def intervals(ivs):
        return [BoundaryInterval(iv.side, scale * iv.t0, scale * iv.t1) for iv in ivs]

    seams = [dataclasses.replace(s, uv_a=scale * np.asarray(s.uv_a), uv_b=scale * np.asarray(s.uv_b),
                                 intervals_a=intervals(s.intervals_a), intervals_b=intervals(s.intervals_b))
             for s in ps.seams]
    return dataclasses.replace(ps, patches=patches, seams=seams)
