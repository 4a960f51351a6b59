"""Where simulated frames go. `sim` hands frames to sinks and never imports `viz`.

A sink is any object with `open(meshes)`, `write(frame)` and `close()`; several sinks can
run at once. `viz` provides the Rerun and PyVista sinks, `garment.io` the mesh exporter.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .stats import StepStats


@dataclass
class MeshTopology:
    """Static part of one triangle mesh: faces (F, 3) int32; for cloth also the fixed
    parametric coordinates uv (V, 2) and rest positions (V, 2) in metres of its vertices.

    kind: "cloth" (an embedded B-spline mesh) or "body" (an obstacle or animated body,
    whose uv and rest are empty (0, 2) arrays).
    """

    name: str
    faces: np.ndarray
    uv: np.ndarray
    rest: np.ndarray
    kind: str = "cloth"


@dataclass
class Frame:
    """One output frame: vertex positions (V, 3) float64 in metres per mesh (cloth pieces
    and bodies, keyed by MeshTopology.name), and the statistics of the steps taken since
    the previous frame."""

    index: int
    time: float
    positions: dict[str, np.ndarray]
    steps: list[StepStats] = field(default_factory=list)


class Sink(Protocol):
    def open(self, meshes: list[MeshTopology]) -> None: ...

    def write(self, frame: Frame) -> None: ...

    def close(self) -> None: ...
