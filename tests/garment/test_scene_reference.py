"""docs/scene-reference.md is generated from the scene schema and says what the reader does."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

from garment.scene import Scene, parse_scene
from garment.scene.reference import COMMAND, PATH, render, toml
from garment.scene.schema import NO_DEFAULT, schema

from tests.support.paths import ASSETS
MESH = str(ASSETS / "bodies" / "mean_all.obj")
MH = ASSETS / "bodies" / "makehuman_cmu"
SKIN = {"mesh": str(MH / "body.obj"), "rig": str(MH / "rig.cmu_mb.json"), "weights": str(MH / "weights.cmu_mb.json"),
        "motion": str(MH / "01_01.bvh")}
OBJ = str(ASSETS / "garments" / "dress_knife.obj")

# A valid scene holding every table (absent keys take their defaults), and where each
# table is in it.
BASE = {
    "scene": {},
    "material": {},
    "cloth": [{"size": [1, 1], "control_points": [5, 5], "material": {}}],
    "pin": [{"box": [[0, 0], [1, 1]]}],
    "load": {},
    "time": {},
    "output": {},
    "obstacle": [{"mesh": MESH}, {"sphere": {"radius": 1.0}, "spin": {"speed": 1.0}}, {"plane": {}},
                 {"skin": SKIN}, {"smpl": {"model": MESH, "motion": MESH}}],
    "contact": {},
    "garment": [{"source": OBJ, "material": {}, "placement": {"file": OBJ}}],
    "sewing": {},
}
WHERE = {  # the first of an array of tables otherwise
    "obstacle.sphere": ("obstacle", 1, "sphere"),
    "obstacle.spin": ("obstacle", 1, "spin"),
    "obstacle.plane": ("obstacle", 2, "plane"),
    "obstacle.skin": ("obstacle", 3, "skin"),
    "obstacle.smpl": ("obstacle", 4, "smpl"),
}


def _tables(s, dotted=""):
    for k in s.keys:
        if k.sub is not None:
            name = f"{dotted}.{k.name}" if dotted else k.name
            yield name, k
            yield from _tables(k.sub, name)


def _find(data: dict, table: str) -> dict:
    if table in WHERE:
        for part in WHERE[table]:
            data = data[part]
        return data
    for part in table.split("."):
        data = data[part]
        data = data[0] if isinstance(data, list) else data
    return data


def _defaults():
    """(table, key name, default as written) of every key whose default the reference
    writes as a TOML value."""
    for dotted, table in _tables(schema(Scene)):
        for k in table.sub.keys:
            if k.sub is None and not k.required and k.default_text is None and k.default not in (None, NO_DEFAULT):
                yield pytest.param(dotted, k.name, toml(k.default, 1000.0 if k.unit == "mm" else 1.0),
                                   id=f"{dotted}.{k.name}")


def test_reference_is_current():
    assert PATH.read_text() == render(), (
        f"docs/scene-reference.md is out of date with garment/scene/specs.py: regenerate it with `{COMMAND}`"
    )


@pytest.mark.parametrize(("table", "name", "default"), list(_defaults()))
def test_documented_default_is_the_default(table, name, default):
    data = copy.deepcopy(BASE)
    where = _find(data, table)
    assert name not in where, f"{table}.{name} is set in the base scene"
    where[name] = tomllib.loads(f"value = {default}")["value"]
    assert parse_scene(data) == parse_scene(BASE)


def test_every_table_and_key_is_in_the_reference():
    text = render()
    for dotted, table in _tables(schema(Scene)):
        assert (f"`[[{dotted}]]`" if table.array else f"`[{dotted}]`") in text
        for k in table.sub.keys:
            assert k.sub is not None or f"| `{k.name}` |" in text
