"""Garments for simulation: a patch file, or panels / a pattern conformed on the fly."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from conform.pipeline import ConformOptions, conform_all
from sim.errors import InputError
from sim.patches import PatchSet

from .bodies import to_scene_frame
from .garmentcode import read_garmentcode
from .panels import read_panels
from .patchfile import FORMAT, load_patchset


def read_pattern(path: Path, knot_span: float):
    """Panels and seams of a panel mesh or a GarmentCode pattern conformed at `knot_span`
    (m); pattern outlines are sampled at a sixth of a span, at most 3 mm apart."""
    if path.suffix.lower() == ".json":
        return read_garmentcode(path, spacing=min(knot_span / 6.0, 0.003))
    return read_panels(path)


def load_garment(spec) -> PatchSet:
    """PatchSet of a garment.scene.GarmentSpec."""
    if spec.source.suffix.lower() == ".json" and _is_patch_file(spec.source):
        ps = load_patchset(spec.source)
    else:
        seam_span = "auto" if spec.seam_span is None else spec.seam_span
        options = ConformOptions(knot_span=spec.knot_span, seam_span=seam_span, fold_pleats=spec.fold_pleats)
        panels, seams = read_pattern(spec.source, options.finest_span)
        if spec.placement is not None:
            place_panels(panels, spec.placement)
        ps = conform_all(panels, seams, options)
    if ps.failures:
        names = ", ".join(f"{k} ({v})" for k, v in ps.failures.items())
        raise InputError(f"{spec.source}: garment {spec.name!r} has panels that did not conform: {names}")
    if not ps.patches:
        raise InputError(f"{spec.source}: garment {spec.name!r} has no patches")
    return ps


# A placement whose edges are on median this much longer or shorter than the panels' rest
# edges is the wrong file or scale (a drape stretches cloth by a few per cent, not 20 %).
PLACEMENT_STRAIN = 0.2


def place_panels(panels, placement) -> None:
    """Replace each panel's 3D layout by the placement file's positions of its vertices."""
    path = placement.file
    try:
        with open(path) as f:
            rows = [line.split()[1:4] for line in f if line.startswith("v ")]
        V = np.asarray(rows, float).reshape(-1, 3)
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: cannot read the placement's vertices ({e})") from None
    need = 1 + max(int(p.vertex_ids.max()) for p in panels)
    if V.shape[0] < need:
        raise InputError(f"{path}: the placement has {V.shape[0]} vertices but the panels use {need} "
                         "(it must list the source mesh's vertices first, in the same order)")
    V = to_scene_frame(V[:need], placement.scale, placement.up, placement.translate)
    if not np.all(np.isfinite(V)):
        raise InputError(f"{path}: the placement has non-finite vertex positions")
    for p in panels:
        world = V[p.vertex_ids]
        e = np.concatenate([p.faces[:, [0, 1]], p.faces[:, [1, 2]], p.faces[:, [2, 0]]])
        rest = np.linalg.norm(p.rest[e[:, 0]] - p.rest[e[:, 1]], axis=1)
        ratio = float(np.median(np.linalg.norm(world[e[:, 0]] - world[e[:, 1]], axis=1) / rest))
        if abs(ratio - 1.0) > PLACEMENT_STRAIN:
            raise InputError(f"{path}: panel {p.name}'s placed edges are {ratio:.3g} x their rest length "
                             "(median): a different mesh or a wrong `scale`?")
        p.world = world


def source_head(path) -> str:
    """The first 4 kB of a garment source as text, to tell its kind."""
    try:
        with open(path, "rb") as f:
            return f.read(4096).decode("utf-8", "replace")  # binary garbage: the reader says what it is
    except OSError as e:
        raise InputError(f"{path}: {e.strerror}") from None


def _is_patch_file(path) -> bool:
    head = source_head(path)
    return f'"{FORMAT}"' in head or '"format"' in head and FORMAT in head
