"""Plausible sizes. Scenes, garments and bodies are in metres (knot spans in millimetres);
a size far outside what cloth or a person is was almost always written in other units,
and the error says which ones and what to write instead."""

from __future__ import annotations

# Other units a number in `unit` may have been written in: (name, factor to `unit`).
_OTHER_UNITS = {
    "m": (("centimetres", 0.01), ("millimetres", 0.001)),
    "mm": (("metres", 1000.0), ("centimetres", 10.0)),
}

# Largest extent (m) of a body, a static obstacle mesh, a panel or a patch after scaling.
LARGEST_M = 5.0


def other_unit(value: float, unit: str, lo: float | None, hi: float | None) -> tuple[str, float] | None:
    """(name, factor) of the first other unit that puts `value` in [lo, hi] when
    multiplied by factor, or None."""
    for name, factor in _OTHER_UNITS.get(unit, ()):
        v = abs(value) * factor
        if (lo is None or v >= lo) and (hi is None or v <= hi):
            return name, factor
    return None


def value_hint(value: float, unit: str, lo: float | None, hi: float | None) -> str:
    """'; looks like centimetres: write 0.6' for a number outside [lo, hi], or ''."""
    guess = other_unit(value, unit, lo, hi)
    if guess is None:
        return ""
    name, factor = guess
    return f"; looks like {name}: write {value * factor:.6g}"


def scale_hint(extent: float, scale: float = 1.0) -> str:
    """For a file `extent` m across after `scale`: 'looks like centimetres: set scale =
    0.01', or a plain request to give its unit."""
    guess = other_unit(extent, "m", None, LARGEST_M)
    if guess is None:
        return "set `scale` to convert the file to metres"
    name, factor = guess
    return f"looks like {name}: set scale = {scale * factor:g}"
