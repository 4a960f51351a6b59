"""The patch file: conformed B-spline patches with their seams, as one JSON document.

    {
      "format": "bspline-garment/patches", "version": 1, "units": "m",
      "source": "path of the input pattern or mesh",
      "patches": [
        {
          "name": "panel0",
          "control_points": [n, m],
          "knots_u": [0, 0, 0, 1, ..., n-2, n-2, n-2], "knots_v": [...],   # quadratic, open
          "rest":  n x m x 2 nested lists: control point X_ij of the flat rest shape, m,
          "world": n x m x 3 nested lists: initial 3D control point C_ij, m,
          "provenance": {
            "source", "panel",
            "corner_vertex_ids": ids of the 4 corner vertices in the input (meshes) or null,
            "corner_positions": 4 rest positions, corners (0,0), (n-2,0), (n-2,m-2), (0,m-2),
            "sides": {"v0": {...}, "u1": {...}, "v1": {...}, "u0": {...}} with, per side,
              "boundary_vertex_ids": the input boundary vertices it covers, in order
              (meshes: the input boundary edges are consecutive pairs), and/or
              "outline_range": the first and last outline point (outline inputs), and
              "pattern_edges": the pattern edges it covers, in order (GarmentCode)
          },
          "quality": {the report of conform.quality: boundary_error_mm, min/max
                      jacobian ratio, corner angles, area errors, seconds, ...}
        }, ...
      ],
      "seams": [
        {"name": "...",
         "a": {"patch": "panel0", "uv": K x 2 parameters,
               "intervals": [{"side": "v0", "t0": 0.0, "t1": 12.0}, ...]},
         "b": {...},    # a.uv[k] is sewn to b.uv[k]
         "after": ["seam", ...]}  # optional: tucks of a folded pleat that close first
      ],
      "failures": {"panel or patch name": "why it was not converted"},
      "splits": {"panel name": {      # panels cut into several patches (conform/split.py)
         "patches": ["skirt_back.0", ...], "cuts": [{"from", "to", "dart", "length_mm"}],
         "seconds", "area_error_gauss2_pct", "area_error_reduced_pct": the patches together
         against the panel}}
    }

A patch cut from a split panel is named `panel.k`; its provenance adds "patch", "piece",
"pieces" and its "cuts" (rest positions from the dart tip to the outline), its sides'
"outline_range" are the parent's outline points (-1: a point the split added, a cut's end
or a point along it) and a side along a cut has "cut": true. The cuts and the darts are ordinary seams between the pieces.

Parameters: X(u, v) = sum N_i(u) N_j(v) X_ij over the domain [0, n-2] x [0, m-2]; side v0 is
v = 0, u1 is u = n-2, v1 is v = m-2, u0 is u = 0; an interval's t is u on v0/v1 and v on
u0/u1, from t0 to t1 (t0 > t1 runs backwards).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from sim.errors import InputError, printable
from sim.files import atomic_write, input_file
from sim.patches import Patch, PatchSet
from sim.seams.spec import BoundaryInterval, PatchSeam

FORMAT = "bspline-garment/patches"
VERSION = 1


def _knots(n: int) -> list[float]:
    return [float(min(max(j - 2, 0), n - 2)) for j in range(n + 3)]


def _clean(obj):
    """JSON-safe copy: numpy scalars and arrays to Python, non-finite floats to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def to_dict(ps: PatchSet) -> dict:
    patches = []
    for p in ps.patches:
        n, m = p.shape
        patches.append({
            "name": p.name,
            "control_points": [n, m],
            "knots_u": _knots(n),
            "knots_v": _knots(m),
            "rest": p.rest.tolist(),
            "world": p.world.tolist(),
            "provenance": ps.provenance.get(p.name, {}),
            "quality": ps.quality.get(p.name, {}),
        })
    seams = []
    for s in ps.seams:
        seams.append({
            "name": s.name,
            "a": {"patch": s.patch_a, "uv": s.uv_a.tolist(),
                  "intervals": [vars(iv) for iv in s.intervals_a]},
            "b": {"patch": s.patch_b, "uv": s.uv_b.tolist(),
                  "intervals": [vars(iv) for iv in s.intervals_b]},
            **({"after": list(s.after)} if s.after else {}),
        })
    return _clean({"format": FORMAT, "version": VERSION, "units": "m", "source": ps.source,
                   "patches": patches, "seams": seams, "failures": ps.failures, "splits": ps.splits})


def save_patchset(path, ps: PatchSet) -> Path:
    """Write the patch file atomically; returns its path."""
    path = Path(path)
    text = json.dumps(to_dict(ps), separators=(",", ":"), allow_nan=False)
    with atomic_write(path) as tmp:
        tmp.write_text(text)
    return path


def load_patchset(path) -> PatchSet:
    """Read a patch file (InputError naming the file and the bad entry): finite numbers,
    shapes that match the control-point counts, seams between patches of the file."""
    path = input_file(path, "patch file")
    try:
        doc = json.loads(path.read_bytes().decode("utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as e:
        raise InputError(f"{path}: not JSON ({printable(e, 200)})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"{path}: not a patch file (format must be {FORMAT!r})")
    if doc.get("version") != VERSION:
        raise InputError(f"{path}: version {printable(repr(doc.get('version')), 40)} is not supported "
                         f"(expected {VERSION})")
    patches, prov, quality = [], {}, {}
    for k, d in enumerate(_entries(doc, "patches", path)):
        where = f"{path}: patches[{k}]"
        try:
            n, m = (int(x) for x in d["control_points"])
            if not (3 <= n <= MAX_COUNT and 3 <= m <= MAX_COUNT):
                raise ValueError(f"control_points {n} x {m}: each must be 3 to {MAX_COUNT}")
            rest = _finite(d["rest"], (n, m, 2), "rest")
            world = _finite(d["world"], (n, m, 3), "world")
            if d.get("knots_u", _knots(n)) != _knots(n) or d.get("knots_v", _knots(m)) != _knots(m):
                raise ValueError("only open uniform integer knot vectors are supported")
            patches.append(Patch(str(d["name"]), rest, world))
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as e:
            raise InputError(f"{where}: {printable(e, 300)}") from None
        prov[patches[-1].name] = d.get("provenance", {})
        quality[patches[-1].name] = d.get("quality", {})
    names = [p.name for p in patches]
    if len(set(names)) != len(names):
        raise InputError(f"{path}: patch names repeat: {printable(sorted({n for n in names if names.count(n) > 1}))}")
    shapes = {p.name: p.shape for p in patches}
    seams = []
    for k, d in enumerate(_entries(doc, "seams", path)):
        try:
            ends = []
            for key in ("a", "b"):
                e = d[key]
                if e["patch"] not in shapes:
                    raise ValueError(f"{key}.patch {printable(repr(e['patch']), 80)} is not a patch in this file")
                uv = _finite(e["uv"], (-1, 2), f"{key}.uv")
                n, m = shapes[e["patch"]]
                top = np.array([n - 2, m - 2]) + UV_TOL
                if uv.size and ((uv.min(axis=0) < -UV_TOL).any() or (uv.max(axis=0) > top).any()):
                    raise ValueError(f"{key}.uv lies outside the parameter domain [0, {n - 2}] x [0, {m - 2}]")
                ivs = [BoundaryInterval(str(i["side"]), float(i["t0"]), float(i["t1"])) for i in e["intervals"]]
                ends.append((e["patch"], uv, ivs))
            if ends[0][1].shape != ends[1][1].shape:
                raise ValueError("a.uv and b.uv must have the same number of samples")
            seams.append(PatchSeam(str(d["name"]), ends[0][0], ends[1][0], ends[0][1], ends[1][1],
                                   ends[0][2], ends[1][2], tuple(str(a) for a in d.get("after", ()))))
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as e:
            raise InputError(f"{path}: seams[{k}]: {printable(e, 300)}") from None
    try:
        extras = dict(doc.get("failures", {})), str(doc.get("source", "")), dict(doc.get("splits", {}))
    except (TypeError, ValueError) as e:
        raise InputError(f"{path}: failures, source or splits: {printable(e, 200)}") from None
    return PatchSet(patches, seams, prov, quality, *extras)


# Control points along one side of a patch at most: a 2 m panel at 0.5 mm knot spans.
MAX_COUNT = 4000
UV_TOL = 1e-6  # seam parameters may overshoot the domain by round-off


def _entries(doc: dict, key: str, path: Path) -> list[dict]:
    value = doc.get(key, [])
    if not isinstance(value, list) or not all(isinstance(d, dict) for d in value):
        raise InputError(f"{path}: {key} must be a list of objects")
    return value


def _finite(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """`value` as a float array of `shape` (-1: any) with finite entries, or ValueError."""
    a = np.asarray(value, float)  # null (a NaN written by an old version) becomes nan
    if a.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, a.shape)):
        want = " x ".join("N" if s < 0 else str(s) for s in shape)
        raise ValueError(f"{what} has shape {a.shape}, expected {want}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} holds non-finite numbers (NaN, inf or null)")
    return a
