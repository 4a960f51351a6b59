"""The scene schema: every key of a scene file declared once.

A spec dataclass (specs.py) declares each of its keys as field metadata with :func:`key`:
meaning, unit, bounds, choices. The field's type is the key's TOML type, the field's
default its default. What is not a field of its own (a material preset, the scene-wide
``[material]``, the ``[obstacle.sphere]`` table that fills several fields, the keys of a
dataclass defined elsewhere) is declared on the class with :func:`declare`.
:func:`schema` assembles a class's keys in order; the reader (table.py) and the generated
reference (reference.py) both work from it.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from dataclasses import dataclass
from typing import Any

# Units a key is written in while its field holds SI: the TOML name gets the unit as a
# suffix (field knot_span, key knot_span_mm) and the value is divided by the factor.
PER_SI = {"mm": 1000.0}
NO_DEFAULT = object()  # Key.default of a field without one


@dataclass(frozen=True)
class Key:
    """One key of a scene table. Bounds, choices and the unit conversion apply to each number
    or name of an array. ``table`` puts a field's key into the sub-table of that name
    (declared on the class); ``kinds`` limits it to the obstacle kinds named; ``after``
    lists it after another key of its table."""

    doc: str
    unit: str = ""
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    allow_inf: bool = False
    # (low, high) a sensible value lies in, in the key's unit (None: open); outside it the
    # value is refused as written in other units, with the likely ones (garment/units.py).
    plausible: tuple[float | None, float | None] | None = None
    choices: tuple[str, ...] = ()
    also: tuple[str, ...] = ()  # strings accepted in place of the value (kappa = "adaptive")
    required: bool = False
    allow_empty: bool = False
    normalise: bool = False  # a non-zero vector, scaled to unit length
    exists: str | None = None  # "file" | "file or directory": resolved against the scene's folder
    table: str | None = None
    kinds: tuple[str, ...] = ()
    after: str | None = None
    toml: str | None = None  # the TOML name when it is not the field's
    default_text: str | None = None  # the reference's default when the field's does not say it
    hint: Any = None  # the type of a declared key that is not a field
    # Filled in by schema():
    name: str = ""  # TOML name
    field: str | None = None  # dataclass field; None for a key that is not one
    default: Any = NO_DEFAULT
    sub: Schema | None = None  # the keys of a sub-table
    array: bool = False  # an array of tables, [[name]]

    @property
    def bounds(self) -> dict[str, float]:
        return {b: v for b in ("gt", "ge", "lt", "le") if (v := getattr(self, b)) is not None}


@dataclass(frozen=True, eq=False)
class Schema:
    """The keys of one table, in order; ``cls`` is the dataclass it fills (None for a
    sub-table whose keys fill fields of the parent's)."""

    cls: type | None
    keys: tuple[Key, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(k.name for k in self.keys)

    def __getitem__(self, name: str) -> Key:
        return next(k for k in self.keys if k.name == name)


def key(default: Any = dataclasses.MISSING, *, default_factory: Any = dataclasses.MISSING, **options: Any) -> Any:
    """A dataclass field that is a scene key; ``options`` are :class:`Key`'s."""
    return dataclasses.field(default=default, default_factory=default_factory, metadata={"key": Key(**options)})


_DECLARED: dict[type, dict[str, Key]] = {}


def declare(**keys: Key):
    """Class decorator adding keys that are not field metadata: a sub-table named by fields'
    ``table`` (its Key gives the doc), a key that is no field (``hint`` gives its type), or
    the key of a field of a class defined elsewhere (``declare(...)(Material)``)."""

    def add(cls: type) -> type:
        _DECLARED.setdefault(cls, {}).update(keys)
        return cls

    return add


@functools.cache
def schema(cls: type) -> Schema:
    """The keys of the table that fills ``cls``: keys that are no field first (unless placed
    by ``after``), then the fields' keys in field order, a sub-table at its first field."""
    hints = typing.get_type_hints(cls)
    declared = dict(_DECLARED.get(cls, {}))
    groups = {n: [] for n, k in declared.items() if k.hint is None and n not in hints}
    keys = [_bind(k, n, k.hint, NO_DEFAULT) for n, k in declared.items() if k.hint is not None]
    for f in dataclasses.fields(cls):
        k = f.metadata.get("key") or declared.get(f.name)
        if k is None:
            continue
        k = _bind(k, f.name, hints[f.name], _default(f), f.name)
        if k.table is None:
            keys.append(k)
            continue
        if not groups[k.table]:
            keys.append(k.table)  # placeholder, replaced below
        groups[k.table].append(k)
    keys = [
        dataclasses.replace(declared[k], name=k, sub=Schema(None, tuple(groups[k]))) if isinstance(k, str) else k
        for k in keys
    ]
    for k in [k for k in keys if k.after]:
        keys = [a for a in keys if a is not k]
        keys.insert(next(i for i, a in enumerate(keys) if a.name == k.after) + 1, k)
    return Schema(cls, tuple(keys))


def _bind(k: Key, name: str, hint: Any, default: Any, field: str | None = None) -> Key:
    inner = strip_optional(hint)
    array = typing.get_origin(inner) is list
    if array:
        inner = typing.get_args(inner)[0]
    toml = k.toml or (f"{name}_{k.unit}" if k.unit in PER_SI else name)
    sub = schema(inner) if dataclasses.is_dataclass(inner) else None
    return dataclasses.replace(k, name=toml, field=field, hint=hint, default=default, sub=sub, array=array)


def _default(f: dataclasses.Field) -> Any:
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return NO_DEFAULT if f.default is dataclasses.MISSING else f.default


def strip_optional(hint: Any) -> Any:
    """``X`` of ``X | None``; other types unchanged."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return hint


def rule(gt: float | None = None, ge: float | None = None, lt: float | None = None, le: float | None = None) -> str:
    """The bounds in words: ``> 0``, ``>= 1``, ``in (-1, 0.5)``, ``in [0, 1]``; "" without any."""
    lower = gt if gt is not None else ge
    upper = lt if lt is not None else le
    if lower is not None and upper is not None:
        left, right = ("(" if gt is not None else "["), (")" if lt is not None else "]")
        return f"in {left}{lower:g}, {upper:g}{right}"
    if lower is not None:
        return f"{'>' if gt is not None else '>='} {lower:g}"
    if upper is not None:
        return f"{'<' if lt is not None else '<='} {upper:g}"
    return ""


def within(value: float, gt=None, ge=None, lt=None, le=None) -> bool:
    return (
        (gt is None or value > gt)
        and (ge is None or value >= ge)
        and (lt is None or value < lt)
        and (le is None or value <= le)
    )
