"""docs/scene-reference.md, generated from the scene schema (specs.py).

    python -m garment.scene.reference --write   # rewrite docs/scene-reference.md
    python -m garment.scene.reference           # print it
"""

from __future__ import annotations

import math
import sys
import typing
from pathlib import Path
from typing import Any

from garment.scene.schema import NO_DEFAULT, PER_SI, Key, Schema, rule, schema, strip_optional
from garment.scene.specs import Scene

PATH = Path(__file__).resolve().parents[2] / "docs" / "scene-reference.md"
COMMAND = "python -m garment.scene.reference --write"

HEADER = f"""\
# Scene file reference

<!-- Generated from garment/scene/specs.py by `{COMMAND}`; do not edit. -->

A scene file is TOML. Every table is optional except that a scene needs at least one
`[[cloth]]` or `[[garment]]`; a key left out takes the default below. Units are SI unless
the unit column says otherwise (a key ending in `_mm` is in millimetres). Bounds and
choices apply to each entry of an array. Examples: `assets/scenes/*.toml`.

Any problem (unknown key, wrong type, NaN or infinity, out-of-range value, dangling
reference) stops the run before anything is simulated with an error naming the file and
the dotted key, e.g. `scenes/a.toml: cloth[0].material.nu: must be in (-1, 0.5), got 0.7`.
"""


def render() -> str:
    """The reference, as Markdown."""
    out = [HEADER]
    seen: dict[int, str] = {}
    for k in schema(Scene).keys:
        _section(out, k, k.name, 2, seen)
    return "\n".join(out)


def _section(out: list[str], k: Key, dotted: str, level: int, seen: dict[int, str]) -> None:
    title = f"[[{dotted}]]" if k.array else f"[{dotted}]"
    out += [f"{'#' * level} `{title}`", "", _sentence(k.doc), ""]
    if id(k.sub) in seen:
        out += [f"The keys of `{seen[id(k.sub)]}`.", ""]
        return
    seen[id(k.sub)] = title
    leaves = [c for c in k.sub.keys if c.sub is None]
    if leaves:
        out += ["| key | type | unit | default | allowed | meaning |", "| --- | --- | --- | --- | --- | --- |"]
        out += [_row(c) for c in leaves]
        out.append("")
    for c in k.sub.keys:
        if c.sub is not None:
            _section(out, c, f"{dotted}.{c.name}", min(level + 1, 4), seen)


def _row(k: Key) -> str:
    meaning = _sentence(k.doc) + (f" Only for {' and '.join(k.kinds)}." if k.kinds else "")
    cells = (f"`{k.name}`", _type(k), k.unit, _default(k), _allowed(k), meaning)
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def _sentence(doc: str) -> str:
    return doc[0].upper() + doc[1:] + ("" if doc.endswith((".", "...")) else ".")


def _type(k: Key) -> str:
    text = _type_name(strip_optional(k.hint))
    return " or ".join([text, *(toml(a) for a in k.also)]) + (" or inf" if k.allow_inf else "")


def _type_name(hint: Any, plural: bool = False) -> str:
    if typing.get_origin(hint) is tuple:
        args = typing.get_args(hint)
        if args[-1] is Ellipsis:
            return f"array{'s' if plural else ''} of {_type_name(args[0], True)}"
        assert len(set(args)) == 1, f"no name for {hint}"
        return f"array{'s' if plural else ''} of {len(args)} {_type_name(args[0], True)}"
    name = {float: "number", int: "integer", bool: "boolean", str: "string", Path: "path"}[hint]
    return name + ("s" if plural else "")


def _default(k: Key) -> str:
    if k.required:
        return "required"
    if k.default_text is not None:
        return k.default_text
    return toml(k.default, PER_SI.get(k.unit, 1.0))


def toml(value: Any, scale: float = 1.0) -> str:
    """``value`` written as in a scene file (numbers times ``scale``: a field in metres of a
    key in millimetres)."""
    if value is None or value is NO_DEFAULT:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (str, Path)):
        return f'"{value}"'
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(toml(v, scale) for v in value) + "]"
    if isinstance(value, int):
        return str(value)
    value = value * scale if scale != 1.0 else value
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    short = f"{value:g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")
    return short if float(short) == value else repr(value)


def _allowed(k: Key) -> str:
    parts = []
    if k.choices:
        parts.append(" | ".join(toml(c) for c in k.choices))
    if k.bounds:
        parts.append(rule(**k.bounds))
    if k.plausible is not None:
        parts.append(f"plausible {rule(ge=k.plausible[0], le=k.plausible[1])}")
    if k.normalise:
        parts.append("non-zero; normalised")
    if k.exists:
        parts.append(f"an existing {k.exists}, relative to the scene file's folder")
    return "; ".join(parts)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--write"]:
        PATH.parent.mkdir(parents=True, exist_ok=True)
        PATH.write_text(render())
        print(f"wrote {PATH}")
    elif not argv:
        sys.stdout.write(render())
    else:
        print(__doc__, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
