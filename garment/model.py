"""The data model shared by every stage: patches of quadratic B-spline cloth.

A patch is a tensor-product quadratic B-spline surface with open uniform integer knots
(DESIGN.md section 2): n x m control points, parameter domain [0, n-2] x [0, m-2].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
