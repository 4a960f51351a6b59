"""Reading one TOML table against its schema: unknown keys, types, bounds, choices, finite
numbers, units and paths, each problem a :class:`SceneError` naming the file and the key."""

from __future__ import annotations

import difflib
import math
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from sim.errors import InputError
from garment.scene.schema import PER_SI, Key, Schema, rule, strip_optional, within
from garment.units import value_hint


class SceneError(InputError):
    """A scene file problem, formatted as ``"{file}: {key}: {problem}"``."""

    def __init__(self, file: str | Path, key: str, problem: str):
        self.file = file
        self.key = key
        self.problem = problem
        super().__init__(f"{file}: {key}: {problem}")

    def __reduce__(self):
        return type(self), (self.file, self.key, self.problem)


class Table:
    """One TOML table being read. It knows its file, its dotted key path and its schema, so
    every error names both, and it rejects unknown keys up front. ``base`` is the folder
    relative paths of existing files resolve against (the scene file's)."""

    def __init__(self, data: Any, file: str | Path, path: str, schema: Schema, base: Path = Path(".")):
        self.file = file
        self.path = path
        self.schema = schema
        self.base = base
        if not isinstance(data, dict):
            self.fail(path, f"must be a table, got {_kind(data)}")
        self.data = data
        for name in data:
            if name not in schema.names:
                self.fail(self.key(name), _unknown_key(name, schema.names))

    def __contains__(self, name: str) -> bool:
        return name in self.data

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def fail(self, key: str, problem: str) -> NoReturn:
        raise SceneError(self.file, key, problem)

    # --- sub-tables

    def table(self, name: str) -> Table:
        """The sub-table ``name``; an empty one when absent."""
        return Table(self.data.get(name, {}), self.file, self.key(name), self.schema[name].sub, self.base)

    def tables(self, name: str) -> list[Table]:
        """The array of tables ``[[name]]``; empty when absent."""
        value = self.data.get(name, [])
        key = self.key(name)
        if not isinstance(value, list):
            self.fail(key, f"must be an array of tables ([[{name}]]), got {_kind(value)}")
        sub = self.schema[name].sub
        return [Table(item, self.file, f"{key}[{i}]", sub, self.base) for i, item in enumerate(value)]

    # --- values

    def values(self, only: Callable[[Key], bool] | None = None) -> dict[str, Any]:
        """The checked values of the keys given (not sub-tables; those ``only`` accepts), by
        field name (a key that is no field: by its own); absent keys keep their defaults."""
        values = {}
        for k in self.schema.keys:
            if k.sub is not None or (only is not None and not only(k)):
                continue
            if k.name not in self.data:
                if k.required:
                    self.fail(self.key(k.name), "missing required key")
                continue
            values[k.field or k.name] = self.value(k)
        return values

    def build(self) -> Any:
        """The table's dataclass from its keys alone."""
        return self.schema.cls(**self.values())

    def value(self, k: Key) -> Any:
        """The checked value of key ``k``, present in the table."""
        value, key = self.data[k.name], self.key(k.name)
        if isinstance(value, str) and value in k.also:
            return value
        value = self._convert(k, strip_optional(k.hint), value, key)
        if k.normalise:
            norm = math.hypot(*value)
            if norm == 0.0:
                self.fail(key, "must be non-zero")
            value = tuple(x / norm for x in value)
        if k.exists:
            value = value if value.is_absolute() else self.base / value
            if k.exists == "file" and value.is_dir():
                self.fail(key, f"{value} is a folder, not a file")
            if not (value.is_file() if k.exists == "file" else value.exists()):
                self.fail(key, f"no such {k.exists}: {value}")
        return value

    def _convert(self, k: Key, hint: Any, value: Any, key: str) -> Any:
        if typing.get_origin(hint) is tuple:
            args = typing.get_args(hint)
            if args[-1] is Ellipsis:  # any length, distinct entries
                entries = self.as_array(value, key)
                items = tuple(self._convert(k, args[0], x, f"{key}[{i}]") for i, x in enumerate(entries))
                for i, item in enumerate(items):
                    if item in items[:i]:
                        self.fail(f"{key}[{i}]", f"duplicate {item!r}")
                return items
            entries = self.as_array(value, key, len(args))
            return tuple(self._convert(k, a, x, f"{key}[{i}]") for i, (a, x) in enumerate(zip(args, entries)))
        if hint is float:
            number = self.as_number(value, key, k.allow_inf, **k.bounds)
            if k.plausible is not None:
                self._check_plausible(number, key, k.unit, *k.plausible)
            return number / PER_SI[k.unit] if k.unit in PER_SI else number
        if hint is int:
            return self.as_integer(value, key, **k.bounds)
        if hint is bool:
            return self.as_bool(value, key)
        if hint is str:
            return self.as_choice(value, key, k.choices) if k.choices else self.as_string(value, key, k.allow_empty)
        if hint is Path:
            return Path(self.as_string(value, key))
        raise TypeError(f"{key}: no reader for {hint}")

    # --- value converters

    def as_number(self, value: Any, key: str, allow_inf: bool = False, **bounds) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f"must be a number, got {_kind(value)}")
        value = float(value)
        if math.isnan(value) or (math.isinf(value) and not allow_inf):
            self.fail(key, f"must be finite, got {value}")
        self._check_bounds(value, key, **bounds)
        return value

    def as_integer(self, value: Any, key: str, **bounds) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"must be an integer, got {_kind(value)}")
        self._check_bounds(value, key, **bounds)
        return value

    def as_bool(self, value: Any, key: str) -> bool:
        if not isinstance(value, bool):
            self.fail(key, f"must be true or false, got {_kind(value)}")
        return value

    def as_string(self, value: Any, key: str, allow_empty: bool = False) -> str:
        if not isinstance(value, str):
            self.fail(key, f"must be a string, got {_kind(value)}")
        if not value and not allow_empty:
            self.fail(key, "must not be empty")
        return value

    def as_choice(self, value: Any, key: str, choices: tuple[str, ...]) -> str:
        value = self.as_string(value, key)
        if value not in choices:
            valid = ", ".join(repr(c) for c in choices)
            self.fail(key, f"unknown name {value!r} (valid: {valid})")
        return value

    def as_array(self, value: Any, key: str, length: int | None = None) -> list:
        if not isinstance(value, list):
            self.fail(key, f"must be an array, got {_kind(value)}")
        if length is not None and len(value) != length:
            self.fail(key, f"must have {length} entries, got {len(value)}")
        return value

    def _check_bounds(self, value: float, key: str, **bounds) -> None:
        if not within(value, **bounds):
            self.fail(key, f"must be {rule(**bounds)}, got {value:g}")

    def _check_plausible(self, value: float, key: str, unit: str, lo: float | None, hi: float | None) -> None:
        if within(abs(value), ge=lo, le=hi):
            return
        unit = f" {unit}" if unit else ""
        limit = f"above {hi:g}{unit}" if hi is not None and abs(value) > hi else f"below {lo:g}{unit}"
        self.fail(key, f"{value:g}{unit} is {limit}, not a plausible value{value_hint(value, unit.strip(), lo, hi)}")


def _unknown_key(name: str, valid: tuple[str, ...]) -> str:
    close = difflib.get_close_matches(name, valid, n=1)
    hint = f"did you mean {close[0]!r}?" if close else f"valid keys: {', '.join(valid)}"
    return f"unknown key {name!r} ({hint})"


def _kind(value: Any) -> str:
    """A TOML-flavoured description of a value's type for error messages."""
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    for kind, name in ((int, "integer"), (float, "float"), (str, "string")):
        if isinstance(value, kind):
            return f"{name} {value!r}"
    if isinstance(value, list):
        return "array"
    if isinstance(value, dict):
        return "table"
    return type(value).__name__  # datetime, date, time
