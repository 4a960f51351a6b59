"""Garments for simulation: a patch file, or panels / a pattern conformed on the fly."""

from __future__ import annotations

import json

from garment.errors import InputError
from garment.model import PatchSet

from .patchfile import FORMAT, load_patchset


def load_garment(spec) -> PatchSet:
    """PatchSet of a garment.scene.GarmentSpec."""
    if spec.source.suffix.lower() == ".json" and _is_patch_file(spec.source):
        ps = load_patchset(spec.source)
    else:
        from conform.pipeline import ConformOptions, conform_all
        from garment.commands.conform import read_input

        panels, seams = read_input(spec.source, spacing=min(spec.knot_span / 6.0, 0.003))
        ps = conform_all(panels, seams, ConformOptions(knot_span=spec.knot_span))
    if ps.failures:
        names = ", ".join(f"{k} ({v})" for k, v in ps.failures.items())
        raise InputError(f"{spec.source}: garment {spec.name!r} has panels that did not conform: {names}")
    if not ps.patches:
        raise InputError(f"{spec.source}: garment {spec.name!r} has no patches")
    return ps


def _is_patch_file(path) -> bool:
    try:
        with open(path) as f:
            head = f.read(4096)
    except OSError as e:
        raise InputError(f"{path}: {e.strerror}") from None
    return f'"{FORMAT}"' in head or '"format"' in head and FORMAT in head
