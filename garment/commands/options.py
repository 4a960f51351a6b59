"""Numbers given on the command line, checked before any work as the scene file checks
them: an option that overrides a scene key (`--frames`, `--knot-span`) goes through that
key's declaration (bounds, finite, plausible units); the others must be finite and within
their bounds. Problems are InputErrors worded like the scene's: `--frames: must be >= 1,
got 0`."""

from __future__ import annotations

import math

from sim.errors import InputError
from garment.scene.schema import Schema, rule, schema, within
from garment.scene.table import SceneError, Table


def scene_option(option: str, value, cls: type, name: str):
    """`value` of `option` checked and converted (mm -> m) as scene key `name` of `cls`."""
    k = schema(cls)[name]
    try:
        return Table({k.name: value}, option, "", Schema(None, (k,))).value(k)
    except SceneError as e:
        raise InputError(f"{option}: {e.problem}") from None


def number_option(option: str, value: float, **bounds):
    """`value` if finite and within `bounds` (gt, ge, lt, le); InputError otherwise."""
    if not math.isfinite(value):
        raise InputError(f"{option}: must be a finite number, got {value}")
    if not within(value, **bounds):
        raise InputError(f"{option}: must be {rule(**bounds)}, got {value:g}")
    return value
