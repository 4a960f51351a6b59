"""Scene files: what to simulate, read from TOML and validated before anything runs.

Every table and key, with its type, unit, default and allowed values, is listed in
docs/scene-reference.md, generated from the declarations in specs.py
(``python -m garment.scene.reference --write``). Any problem (unknown key, wrong type, NaN,
out-of-range value, dangling reference) raises :class:`SceneError` naming the file and the
dotted key, e.g. ``scenes/a.toml: cloth[0].material.nu: must be in (-1, 0.5), got 0.7``.

Layout: schema.py (how a key is declared), specs.py (the dataclasses and their keys),
table.py (reading one table against its keys), read.py (the entry points and the checks
across keys), reference.py (the generated reference).
"""

from garment.scene.read import ORTHOGONALITY_TOL, load_scene, loads_scene, parse_scene
from garment.scene.specs import (
    CORNERS,
    MESH_FORMATS,
    SEWING_MODES,
    SIDES,
    TIME_MODES,
    UP_AXES,
    ClothSpec,
    ContactSpec,
    GarmentSpec,
    LoadSpec,
    ObstacleSpec,
    OutputSpec,
    Perturbation,
    PinSpec,
    PlacementSpec,
    Scene,
    SewingSpec,
    Spin,
    TimeSpec,
)
from garment.scene.table import SceneError

__all__ = [
    "CORNERS",
    "MESH_FORMATS",
    "ORTHOGONALITY_TOL",
    "SEWING_MODES",
    "SIDES",
    "TIME_MODES",
    "UP_AXES",
    "ClothSpec",
    "ContactSpec",
    "GarmentSpec",
    "LoadSpec",
    "ObstacleSpec",
    "OutputSpec",
    "Perturbation",
    "PinSpec",
    "PlacementSpec",
    "Scene",
    "SceneError",
    "SewingSpec",
    "Spin",
    "TimeSpec",
    "load_scene",
    "loads_scene",
    "parse_scene",
]
