"""What a seam is, at each stage: matched points of two panels (PanelSeam, from a pattern
or panel meshes), matched parameter samples of two patches (PatchSeam, from conforming)
and the simulator's seam between two pieces (SeamSpec)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PanelSeam:
    """Matched points along a seam between two panels (or within one, e.g. a dart).

    points_a, points_b: (K, 2) rest positions on panel_a and panel_b that are sewn
    together, in order along the seam; vertices_a / vertices_b: (K,) vertex index on that
    panel when the point is a vertex, else -1 (None: all -1).
    """

    name: str
    panel_a: str
    panel_b: str
    points_a: np.ndarray
    points_b: np.ndarray
    vertices_a: np.ndarray | None = None
    vertices_b: np.ndarray | None = None


@dataclass
class BoundaryInterval:
    """A stretch of one patch side: parameter t along the side from t0 to t1 (t0 > t1
    runs against the side's direction). t is u on v0/v1 and v on u0/u1."""

    side: str
    t0: float
    t1: float


@dataclass
class PatchSeam:
    """A seam between patch boundaries: matched parameter samples uv_a[k] ~ uv_b[k]
    ((K, 2) each, in the patches' parameter domains) and the boundary intervals they
    cover on each patch (consecutive samples on one side, split at corners). `after`:
    seams (tucks of a folded pleat this seam is sewn onto) that must nearly close before
    this one pulls (conform/pleats.py, pleat_faces)."""

    name: str
    patch_a: str
    patch_b: str
    uv_a: np.ndarray
    uv_b: np.ndarray
    intervals_a: list[BoundaryInterval]
    intervals_b: list[BoundaryInterval]
    after: tuple[str, ...] = ()



@dataclass
class SeamSpec:
    piece_a: str
    uv_a: np.ndarray
    piece_b: str
    uv_b: np.ndarray
    name: str = ""
    # Seams (indices in the simulator's list) this one waits for: the tucks of a folded
    # pleat it is sewn onto (PatchSeam.after; sim.seams.sewing.SewingOptions.pleat_wait_gap).
    after: tuple[int, ...] = ()


def side_length(points) -> float:
    """Length of a seam side's polyline of points (K, d)."""
    return float(np.linalg.norm(np.diff(np.asarray(points, float), axis=0), axis=1).sum())
