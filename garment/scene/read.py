"""Reading a scene: the entry points, and the checks across keys that the schema's
per-key rules cannot make (a pin's cloth exists, axes are orthogonal, an obstacle is of
exactly one kind, ...)."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from sim.materials import MIN_CONTROL_POINTS, PRESETS, Material
from sim.newton import default_doublings
from garment.scene.schema import schema
from garment.scene.specs import (
    MOVING_KINDS,
    OBSTACLE_KINDS,
    RIGGED_KINDS,
    ClothSpec,
    ContactSpec,
    GarmentSpec,
    ObstacleSpec,
    PinSpec,
    PlacementSpec,
    Scene,
)
from garment.scene.table import SceneError, Table

# Largest |cos| of the angle between axis_u and axis_v.
ORTHOGONALITY_TOL = 1e-6
MAX_SCENE_BYTES = 16_000_000  # a larger file is something else given by mistake


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file."""
    return parse_scene(read_scene_data(path), path)


def read_scene_data(path: str | Path) -> dict:
    """A scene file's TOML document, not yet validated."""
    if Path(path).is_dir():
        raise SceneError(path, "<file>", "is a folder, not a scene file")
    try:
        if Path(path).stat().st_size > MAX_SCENE_BYTES:
            size = Path(path).stat().st_size / 1e6
            raise SceneError(path, "<file>", f"{size:.0f} MB is not a scene file (TOML of a few kB)")
        text = Path(path).read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise SceneError(path, "<file>", "no such file") from None
    except OSError as e:
        raise SceneError(path, "<file>", e.strerror or str(e)) from None
    except UnicodeDecodeError as e:
        problem = f"not valid UTF-8 ({e.reason} at byte {e.start})"
        raise SceneError(path, "<toml>", problem) from None
    return _toml(text, path)


def _toml(text: str, source: str | Path) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(source, "<toml>", str(e)) from None


def loads_scene(text: str, source: str | Path = "<string>") -> Scene:
    """Parse and validate a scene from TOML text; ``source`` only names it in errors."""
    return parse_scene(_toml(text, source), source)


def parse_scene(data: dict, source: str | Path = "<string>") -> Scene:
    """Validate an already-parsed TOML document. ``source`` names it in errors; unless it is
    a placeholder like ``"<string>"`` it also becomes :attr:`Scene.path`."""
    path = None if str(source).startswith("<") else Path(source)
    base = path.parent if path is not None else Path(".")
    root = Table(data, source, "", schema(Scene), base)
    info = root.table("scene").values()
    material = _read_material(root.table("material"), PRESETS["cotton"])
    garments = [_read_garment(t, i, material) for i, t in enumerate(root.tables("garment"))]
    cloths = _read_cloths(root, material, required=not garments)
    obstacles = [_read_obstacle(t, i) for i, t in enumerate(root.tables("obstacle"))]
    time_spec = root.table("time").build()
    for i, o in enumerate(obstacles):
        if o.raise_arms > 0.0 and time_spec.preroll <= 0.0:
            raise SceneError(source, f"obstacle[{i}].raise_arms", "raised arms are lowered during the pre-roll: "
                                                                 "set [time] preroll > 0")
        if o.inset > 0.0 and time_spec.preroll <= 0.0:
            raise SceneError(source, f"obstacle[{i}].inset", "an inset body grows out during the pre-roll: "
                                                            "set [time] preroll > 0")
        if o.blend is not None and o.blend > time_spec.preroll:
            raise SceneError(source, f"obstacle[{i}].blend", f"{o.blend:g} s is longer than the pre-roll "
                                                            f"([time] preroll = {time_spec.preroll:g} s)")
    contact = _read_contact(root, bool(obstacles))
    if time_spec.newton_extrapolate is None:
        friction = contact.mu if contact.enabled else 0.0
        time_spec.newton_extrapolate = default_doublings(friction, contact.eps_v)
    return Scene(
        name=info.get("name") or (path.stem if path else "scene"),
        path=path,
        cloths=cloths,
        pins=[_read_pin(t, cloths) for t in root.tables("pin")],
        load=root.table("load").build(),
        time=time_spec,
        output=root.table("output").build(),
        description=info.get("description", ""),
        obstacles=obstacles,
        contact=contact,
        garments=garments,
        sewing=root.table("sewing").build(),
    )


def _read_material(t: Table, base: Material) -> Material:
    """``base`` (or the table's preset) with the table's explicit keys applied."""
    values = t.values()
    preset = values.pop("preset", None)
    return (PRESETS[preset] if preset is not None else base).with_(**values)


def _read_garment(t: Table, index: int, scene_material: Material) -> GarmentSpec:
    values = t.values()
    placement = None
    if "placement" in t:
        pt = t.table("placement")
        placement = PlacementSpec(**pt.values())
        if values["source"].suffix.lower() != ".obj":
            pt.fail(pt.path, f"a placement needs a panel OBJ source (its vertex order), not {values['source'].name}")
    material = _read_material(t.table("material"), scene_material)
    return GarmentSpec(**{"name": f"garment{index}", **values, "material": material, "placement": placement})


def _read_cloths(root: Table, material: Material, required: bool = True) -> list[ClothSpec]:
    tables = root.tables("cloth")
    if not tables and required:
        root.fail("cloth", "the scene needs at least one [[cloth]] or [[garment]] table")
    cloths: list[ClothSpec] = []
    first_index: dict[str, int] = {}
    for i, t in enumerate(tables):
        cloth = _read_cloth(t, f"cloth{i}", material)
        if cloth.name in first_index:
            t.fail(
                t.key("name"),
                f"duplicate cloth name {cloth.name!r} (also cloth[{first_index[cloth.name]}])",
            )
        first_index[cloth.name] = i
        cloths.append(cloth)
    return cloths


def _read_cloth(t: Table, default_name: str, scene_material: Material) -> ClothSpec:
    material = _read_material(t.table("material"), scene_material)
    values = t.values()
    control_points = values["control_points"]
    minimum = MIN_CONTROL_POINTS[material.quadrature]
    if min(control_points) < minimum:
        t.fail(
            t.key("control_points"),
            f"quadrature {material.quadrature!r} needs at least {minimum} x {minimum} "
            f"control points, got {control_points[0]} x {control_points[1]}",
        )
    _check_axes(t, values.get("axis_u", ClothSpec.axis_u), values.get("axis_v", ClothSpec.axis_v))
    perturbation = t.table("perturbation").build() if "perturbation" in t else None
    return ClothSpec(**{"name": default_name, **values, "material": material, "perturbation": perturbation})


def _check_axes(t: Table, axis_u: tuple, axis_v: tuple) -> None:
    norms = {}
    for name, axis in (("axis_u", axis_u), ("axis_v", axis_v)):
        norms[name] = math.hypot(*axis)
        if norms[name] == 0.0:
            t.fail(t.key(name), "must be non-zero")
    cos = abs(float(np.dot(axis_u, axis_v))) / (norms["axis_u"] * norms["axis_v"])
    if cos > ORTHOGONALITY_TOL:
        t.fail(
            t.key("axis_v"),
            f"must be orthogonal to axis_u (|cos| = {cos:.3g} > {ORTHOGONALITY_TOL:g})",
        )


def _read_pin(t: Table, cloths: list[ClothSpec]) -> PinSpec:
    names = [c.name for c in cloths]
    values = t.values()
    cloth = values.get("cloth")
    if cloth is None:
        if len(names) > 1:
            t.fail(t.key("cloth"), f"required when there are several cloths ({', '.join(names)})")
        values["cloth"] = names[0]
    elif cloth not in names:
        t.fail(t.key("cloth"), f"unknown cloth {cloth!r} (cloths: {', '.join(names)})")
    if not (values.get("corners") or values.get("sides") or values.get("box")):
        t.fail(t.path, "needs at least one of corners, sides, box")
    if "box" in values:
        lo, hi = values["box"]
        for axis, label in enumerate("uv"):
            if lo[axis] > hi[axis]:
                t.fail(t.key("box"), f"{label}_min = {lo[axis]:g} > {label}_max = {hi[axis]:g}")
    return PinSpec(**values)


def _read_obstacle(t: Table, index: int) -> ObstacleSpec:
    kinds = [k for k in OBSTACLE_KINDS if k in t]
    if len(kinds) != 1:
        valid = ", ".join(repr(k) for k in OBSTACLE_KINDS)
        t.fail(t.path, f"needs exactly one of {valid}, got {kinds or 'none'}")
    kind = kinds[0]
    values = {"name": f"obstacle{index}", "kind": kind, **t.values(lambda k: not k.kinds or kind in k.kinds)}
    sub = t.schema[kind].sub
    if sub is not None and sub.cls is not None:  # skin, smpl: a sub-table of their own
        values[kind] = t.table(kind).build()
    elif sub is not None:  # sphere, plane: a sub-table filling the obstacle's fields
        values.update(t.table(kind).values())
    if kind in RIGGED_KINDS:
        _check_motion_range(t.table(kind), values[kind])
    if "spin" in t:
        if kind in MOVING_KINDS:
            t.fail(t.key("spin"), "an animated body already moves; spin applies to static obstacles")
        values["spin"] = t.table("spin").build()
    return ObstacleSpec(**values)


def _check_motion_range(t: Table, spec) -> None:
    if spec.end is not None and spec.end <= spec.start:
        t.fail(t.key("end"), f"must be after start ({spec.start:g} s), got {spec.end:g}")


def _read_contact(root: Table, has_obstacles: bool) -> ContactSpec:
    present = "contact" in root
    values = root.table("contact").values()
    values.setdefault("enabled", present or has_obstacles)
    if values.get("kappa") == "adaptive":
        del values["kappa"]
        values["adaptive_kappa"] = True
    return ContactSpec(**values)
