"""One frame and one unit system for the body and the pattern: metres, Z up (the
simulator's frame, as every scene).

A body file may be in metres, centimetres, millimetres, decimetres (MakeHuman) or inches,
Y-up (most character tools, GarmentCode) or Z-up: a standing person is 1-2.3 m tall along
the up axis, which no other combination of unit and axis gives. GarmentCode patterns
state their units (`properties.units_in_meter`) and are Y-up by construction, on bodies
that stand on y = 0; panel meshes are read as given (metres), with the body's up axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.errors import InputError

from ..io.garments import source_head
from ..io.meshfile import read_mesh

HEIGHT_M = (0.9, 2.4)  # a standing person, m
UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254}


@dataclass
class BodyFrame:
    """How to bring a body file into the simulation frame (garment.io.bodies.to_scene_frame)."""

    scale: float
    up: str  # "y" or "z": the file's up axis
    unit: str

    def describe(self) -> str:
        return f"{self.unit}, {self.up.upper()}-up"


def detect(points: np.ndarray, path: Path | str = "the body") -> BodyFrame:
    """The unit and up axis under which `points` (V, 3) stand as a person."""
    ext = np.ptp(np.asarray(points, float), axis=0)
    found = []
    for axis, up in ((1, "y"), (2, "z")):
        others = np.delete(ext, axis)
        for unit, scale in UNITS.items():
            h = ext[axis] * scale
            # Taller than wide and deep: a person stands along the up axis, arms in an A- or
            # T-pose reach at most about their height across.
            if HEIGHT_M[0] <= h <= HEIGHT_M[1] and ext[axis] >= 0.9 * others.max():
                found.append((abs(np.log(h / 1.7)), BodyFrame(scale, up, unit)))
    if not found:
        raise InputError(f"{path}: cannot tell the body's units and up axis: it spans "
                         f"{ext[0]:.4g} x {ext[1]:.4g} x {ext[2]:.4g} (x, y, z) in file units, and no unit "
                         f"(m, dm, cm, mm, in) makes it a standing person {HEIGHT_M[0]}-{HEIGHT_M[1]} m tall along "
                         "Y or Z. Give the body's scale and up axis in a scene ([[obstacle]] scale, up)")
    return min(found, key=lambda f: f[0])[1]


def read_body(path: Path) -> tuple[np.ndarray, np.ndarray, BodyFrame]:
    """A static body mesh: its vertices and faces as read, and the frame detected."""
    V, F = read_mesh(Path(path), "body mesh")
    return V, F, detect(V, path)


def pattern_up(source: Path) -> str:
    """The up axis of a garment source: GarmentCode patterns are Y-up; panel meshes and
    patch files are taken as Z-up (the simulator's frame)."""
    return "y" if Path(source).suffix.lower() == ".json" and '"pattern"' in source_head(source) else "z"
