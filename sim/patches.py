"""The data model shared by every stage: patches of quadratic B-spline cloth.

A patch is a tensor-product quadratic B-spline surface with open uniform integer knots
(docs/design.md section 2): n x m control points, parameter domain [0, n-2] x [0, m-2].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .seams.spec import PatchSeam


@dataclass
class Patch:
    """One cloth piece.

    rest:  (n, m, 2) control points in material space, metres.
    world: (n, m, 3) initial control points in world space, metres.
    """

    name: str
    rest: np.ndarray
    world: np.ndarray

    def __post_init__(self) -> None:
        self.rest = np.ascontiguousarray(self.rest, dtype=np.float64)
        self.world = np.ascontiguousarray(self.world, dtype=np.float64)
        n, m = self.rest.shape[:2]
        if self.rest.shape != (n, m, 2) or self.world.shape != (n, m, 3):
            raise ValueError(
                f"patch {self.name!r}: rest {self.rest.shape} and world {self.world.shape} "
                "must be (n, m, 2) and (n, m, 3)"
            )

    @property
    def shape(self) -> tuple[int, int]:
        return self.rest.shape[0], self.rest.shape[1]

    @property
    def n_control_points(self) -> int:
        return self.shape[0] * self.shape[1]

    @staticmethod
    def greville(n: int) -> np.ndarray:
        """Greville abscissae of n quadratic control points: 0, 0.5, 1.5, ..., n-2.5, n-2."""
        g = np.arange(n, dtype=np.float64) - 0.5
        g[0], g[-1] = 0.0, n - 2.0
        return g

    @classmethod
    def rectangle(
        cls,
        name: str,
        size: tuple[float, float],
        control_points: tuple[int, int],
        origin=(0.0, 0.0, 0.0),
        axis_u=(1.0, 0.0, 0.0),
        axis_v=(0.0, 1.0, 0.0),
    ) -> "Patch":
        """A flat rectangular sheet of size (width along u, height along v) in metres.

        Control points sit at their Greville abscissae, so X(u, v) is affine: the rest
        map has constant Jacobian and the quadrature is exact on it.
        """
        n, m = control_points
        s = cls.greville(n) / (n - 2)
        t = cls.greville(m) / (m - 2)
        S, T = np.meshgrid(s * size[0], t * size[1], indexing="ij")
        rest = np.stack([S, T], axis=-1)
        au = np.asarray(axis_u, float)
        av = np.asarray(axis_v, float)
        au /= np.linalg.norm(au)
        av /= np.linalg.norm(av)
        world = np.asarray(origin, float) + S[..., None] * au + T[..., None] * av
        return cls(name, rest, world)


# ---------------------------------------------------------------- panels, seams, patch sets
# The conforming stage (conform/) turns Panels into Patches; seams given between panels
# become seams between patch boundaries. Everything in metres.

SIDES = ("v0", "u1", "v1", "u0")
"""Patch sides in counter-clockwise order: v0 (v = 0, u increasing), u1 (u = n-2), v1
(v = m-2, u decreasing), u0 (u = 0, v decreasing). Names as in scene pins."""


@dataclass
class Panel:
    """A flat garment panel: a triangle mesh or an outline in its rest layout.

    rest:      (V, 2) vertex positions in the flat layout, metres.
    faces:     (F, 3) int triangles into rest, or None for an outline-only panel, whose
               vertices are the closed outline in counter-clockwise order.
    world:     (V, 3) placement of the vertices in 3D (metres), or None.
    transform: (4, 4) rigid placement of the layout plane, world = R [x, y, 0] + t, or None
               (neither world nor transform: the panel lies flat at z = 0).
    vertex_ids: (V,) ids of the vertices in the source file (0-based), for messages,
               corner overrides and provenance.
    corner_hints: vertex indices preferred as corners (pattern vertices, seam endpoints).
    segment_edges: outline panels only, (V,) id of the source edge that the outline
               segment from vertex k to k+1 belongs to (GarmentCode edge index).
    area:      reference rest area, m^2 (None: the triangles' area).
    segment_bulge: outline panels only, (V,) area (m^2) between the exact source curve and
               the straight outline segment from vertex k to k+1 (positive outwards), so
               that area = polygon area + sum; None: straight segments.
    """

    name: str
    source: str
    rest: np.ndarray
    faces: np.ndarray | None = None
    world: np.ndarray | None = None
    transform: np.ndarray | None = None
    vertex_ids: np.ndarray | None = None
    corner_hints: np.ndarray | None = None
    segment_edges: np.ndarray | None = None
    area: float | None = None
    segment_bulge: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.rest = np.ascontiguousarray(self.rest, dtype=np.float64).reshape(-1, 2)
        if self.faces is not None:
            self.faces = np.ascontiguousarray(self.faces, dtype=np.int64).reshape(-1, 3)
        if self.world is not None:
            self.world = np.ascontiguousarray(self.world, dtype=np.float64).reshape(-1, 3)
        if self.vertex_ids is None:
            self.vertex_ids = np.arange(self.rest.shape[0])
        if self.corner_hints is None:
            self.corner_hints = np.zeros(0, dtype=np.int64)

    def positions(self) -> np.ndarray:
        """(V, 3) the vertices in 3D: `world`, or the rest layout placed."""
        return self.world if self.world is not None else self.place(self.rest)

    def place(self, points: np.ndarray) -> np.ndarray:
        """3D positions (P, 3) of rest points (P, 2) under the rigid transform (or z = 0)."""
        points = np.asarray(points, float)
        flat = np.concatenate([points, np.zeros((points.shape[0], 1))], axis=1)
        if self.transform is None:
            return flat
        T = np.asarray(self.transform, float)
        return flat @ T[:3, :3].T + T[:3, 3]


@dataclass
class PatchSet:
    """Conformed patches with their seams, provenance and quality reports (by patch name),
    the panels that failed (name -> message), and the panels split into several patches
    (name -> {"patches": [names], "cuts": [...], totals})."""

    patches: list[Patch]
    seams: list[PatchSeam]
    provenance: dict
    quality: dict
    failures: dict
    source: str = ""
    splits: dict = field(default_factory=dict)

    def panel_of(self, name: str) -> str:
        """The pattern panel a patch was cut from (through nested splits), or its own name."""
        parent = {piece: panel for panel, sp in self.splits.items() for piece in sp["patches"]}
        while name in parent:
            name = parent[name]
        return name

    def patch(self, name: str) -> Patch:
        for p in self.patches:
            if p.name == name:
                return p
        raise KeyError(name)
