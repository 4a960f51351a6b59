"""A skinned mesh from MakeHuman-style files: an OBJ (its vertex order is what the
weights index), a rig JSON and a weights JSON, as MakeHuman and MPFB export them.

- Mesh OBJ: `v` lines and faces grouped by `g` (or `o`). Only the faces of `group` are the
  body (MakeHuman's base.obj also holds helper geometry: tights, hair and the joint
  cubes); the whole file's vertex numbering is what the rig and weights refer to.
- Rig JSON: {bone: {"parent": name or "", "head": {...}, "tail": {...}}}; a head or tail
  is located by "strategy": "CUBE" (the centroid of the vertices of the OBJ group
  `cube_name`, MakeHuman's joint cubes), "MEAN" (the centroid of `vertex_indices`) or
  "VERTEX" (`vertex_index`). The head is the joint the bone turns about.
- Weights JSON: {"weights": {bone: [[vertex, weight], ...]}}.

Everything is checked before use: finite numbers, vertex and bone references, one root,
no cycles, every body vertex weighted (rows are normalised to sum 1).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from sim.errors import InputError, printable
from sim.files import input_file

from .bodies import to_scene_frame
from .skinning import Rig, padded_weights

MAX_JSON_BYTES = 128 * 2**20
MAX_OBJ_BYTES = 512 * 2**20
MAX_BONES = 1000


def read_json(path, what: str) -> object:
    """A JSON document; InputError naming the file when it is not one."""
    path = input_file(path, what)
    size = path.stat().st_size
    if size > MAX_JSON_BYTES:
        raise InputError(f"{path}: {size / 2**20:.0f} MB is not a {what} (at most {MAX_JSON_BYTES // 2**20} MB)")
    try:
        return json.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not a {what} (byte {e.start} is not UTF-8)") from None
    except RecursionError:
        raise InputError(f"{path}: not a {what} (nested too deeply)") from None
    except ValueError as e:
        raise InputError(f"{path}: not a {what} (invalid JSON: {printable(e, 200)})") from None


def read_grouped_obj(path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Vertices (N, 3) of an OBJ in file order and its triangles (F, 3) per group
    (polygons fanned; faces before any `g`/`o` line belong to group "")."""
    path = input_file(path, "mesh OBJ")
    size = path.stat().st_size
    if size > MAX_OBJ_BYTES:
        raise InputError(f"{path}: {size / 2**20:.0f} MB is too large for a body mesh")
    v: list[tuple[float, float, float]] = []
    groups: dict[str, list] = {}
    current = groups.setdefault("", [])
    with open(path, "r", errors="backslashreplace") as f:
        for lineno, line in enumerate(f, 1):
            t = line.split()
            if not t:
                continue
            try:
                if t[0] == "v":
                    xyz = (float(t[1]), float(t[2]), float(t[3]))
                    if not all(map(math.isfinite, xyz)):
                        raise InputError(f"{path}:{lineno}: non-finite vertex coordinate (NaN or inf)")
                    v.append(xyz)
                elif t[0] in ("g", "o"):
                    current = groups.setdefault(" ".join(t[1:2]), [])
                elif t[0] == "f":
                    corners = [_index(c.split("/")[0], len(v), path, lineno) for c in t[1:]]
                    if len(corners) < 3:
                        raise InputError(f"{path}:{lineno}: a face needs at least 3 vertices")
                    current += [(corners[0], corners[a], corners[a + 1]) for a in range(1, len(corners) - 1)]
            except InputError:
                raise
            except (ValueError, IndexError):
                raise InputError(f"{path}:{lineno}: cannot read {printable(line.strip()[:60])!r}") from None
    if not v:
        raise InputError(f"{path}: no vertices")
    return np.asarray(v, float), {g: np.asarray(f, np.int64).reshape(-1, 3) for g, f in groups.items() if f}


def _index(token: str, count: int, path: Path, lineno: int) -> int:
    i = int(token)
    k = i - 1 if i > 0 else count + i
    if i == 0 or not 0 <= k < count:
        raise InputError(f"{path}:{lineno}: face index {token[:24]} is out of range ({count} vertices so far)")
    return k


def read_makehuman(mesh, group: str | None, rig_path, weights_path) -> Rig:
    """The rig in the files' own units and axes (see rig_to_scene)."""
    V, groups = read_grouped_obj(mesh)
    if group is None:
        if any(g.startswith("joint-") for g in groups):
            raise InputError(f"{mesh}: the OBJ holds MakeHuman helper groups (joint cubes, tights); give "
                             f"group = \"body\" (or the body's group) so only the body is a collider")
        faces = np.concatenate(list(groups.values()))
    elif group not in groups:
        raise InputError(f"{mesh}: no group {group!r} with faces (groups: {_names(groups)})")
    else:
        faces = groups[group]
    bones = _read_bones(rig_path, V, groups)
    names = list(bones)
    parents = np.array([names.index(b["parent"]) if b["parent"] else -1 for b in bones.values()])
    heads = np.array([b["head"] for b in bones.values()])
    tails = np.array([b["tail"] for b in bones.values()])
    vertex, joint, weight = _read_weights(weights_path, names, len(V))
    # The body: the vertices its faces use, renumbered in file order.
    used = np.unique(faces)
    new = np.full(len(V), -1)
    new[used] = np.arange(len(used))
    on_body = new[vertex] >= 0
    index, w, unweighted = padded_weights(new[vertex[on_body]], joint[on_body], weight[on_body], len(used))
    if len(unweighted):
        raise InputError(f"{weights_path}: {len(unweighted)} vertices of the body have no weight (first: vertex "
                         f"{int(used[unweighted[0]])} of {Path(mesh).name}); are the weights for this mesh?")
    return Rig(names, parents, heads, V[used], new[faces].astype(np.int32), index, w, tails)


def _names(groups) -> str:
    names = [repr(g) for g in groups]
    return ", ".join(names[:12]) + (f", ... ({len(names)} in all)" if len(names) > 12 else "")


def _read_bones(path, V: np.ndarray, groups: dict[str, np.ndarray]) -> dict[str, dict]:
    """{bone: {"parent", "head", "tail"}} with positions located, parents before children."""
    doc = read_json(path, "rig JSON")
    if not isinstance(doc, dict) or not doc or not all(isinstance(b, dict) for b in doc.values()):
        raise InputError(f"{path}: not a MakeHuman rig (expected an object of bones, each with parent, head "
                         "and tail)")
    if len(doc) > MAX_BONES:
        raise InputError(f"{path}: {len(doc)} bones; a body rig has fewer than {MAX_BONES}")
    bones = {}
    for name, b in doc.items():
        parent = b.get("parent")
        if parent is None:
            parent = ""
        if not isinstance(parent, str):
            raise InputError(f"{path}: bone {printable(name[:40])!r}: parent must be a bone name or \"\"")
        if parent and parent not in doc:
            raise InputError(f"{path}: bone {printable(name[:40])!r}: unknown parent {printable(parent[:40])!r}")
        bones[name] = {"parent": parent, "head": _locate(path, name, "head", b.get("head"), V, groups),
                       "tail": _locate(path, name, "tail", b.get("tail"), V, groups)}
    roots = [n for n, b in bones.items() if not b["parent"]]
    if len(roots) != 1:
        raise InputError(f"{path}: the rig needs exactly one root bone (parent \"\"), it has "
                         f"{len(roots)}{': ' + ', '.join(roots[:5]) if roots else ''}")
    order, frontier = [], roots
    while frontier:
        order += frontier
        frontier = [n for n, b in bones.items() if b["parent"] in frontier]
    if len(order) < len(bones):
        lost = next(n for n in bones if n not in order)
        raise InputError(f"{path}: bone {printable(lost[:40])!r} is not connected to the root "
                         f"{roots[0]!r} (its parents form a cycle)")
    return {n: bones[n] for n in order}


def _locate(path, bone: str, end: str, spec, V: np.ndarray, groups: dict[str, np.ndarray]) -> np.ndarray:
    where = f"{path}: bone {printable(bone[:40])!r} {end}"
    if not isinstance(spec, dict):
        raise InputError(f"{where}: missing (an object with a strategy)")
    strategy = spec.get("strategy")
    if strategy == "CUBE":
        cube = spec.get("cube_name")
        if not isinstance(cube, str) or cube not in groups:
            raise InputError(f"{where}: joint cube {printable(str(cube)[:40])!r} is not a group of the mesh OBJ "
                             "(is it MakeHuman's base mesh with its helper groups?)")
        return V[np.unique(groups[cube])].mean(axis=0)
    if strategy in ("MEAN", "VERTEX"):
        ids = spec.get("vertex_indices") if strategy == "MEAN" else [spec.get("vertex_index")]
        if not isinstance(ids, list) or not ids or not all(isinstance(i, int) and not isinstance(i, bool)
                                                           for i in ids):
            raise InputError(f"{where}: {strategy} needs vertex indices (integers)")
        bad = [i for i in ids if not 0 <= i < len(V)]
        if bad:
            raise InputError(f"{where}: vertex {bad[0]} is out of range (the mesh has {len(V)} vertices)")
        return V[ids].mean(axis=0)
    raise InputError(f"{where}: unknown strategy {printable(str(strategy)[:40])!r} (CUBE, MEAN or VERTEX)")


def _read_weights(path, names: list[str], n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertex, bone, weight) triples of a MakeHuman weights JSON, checked."""
    doc = read_json(path, "weights JSON")
    table = doc.get("weights") if isinstance(doc, dict) else None
    if not isinstance(table, dict):
        raise InputError(f"{path}: not MakeHuman weights (expected {{\"weights\": {{bone: [[vertex, weight], "
                         "...]}}})")
    vertex, joint, weight = [], [], []
    for bone, pairs in table.items():
        if bone not in names:
            raise InputError(f"{path}: weights for bone {printable(bone[:40])!r}, which the rig does not have "
                             "(are the weights for this rig?)")
        if pairs == []:
            continue
        try:
            a = np.asarray(pairs, dtype=float)
        except (ValueError, TypeError):
            a = None
        if a is None or a.ndim != 2 or a.shape[1] != 2 or (a.size and not np.isfinite(a).all()):
            raise InputError(f"{path}: bone {bone!r}: expected a list of [vertex, weight] number pairs")
        ids = a[:, 0]
        bad = (ids != np.round(ids)) | (ids < 0) | (ids >= n_vertices)
        if bad.any():
            raise InputError(f"{path}: bone {bone!r} weights vertex {ids[bad][0]:g}, but the mesh has "
                             f"{n_vertices} vertices (0 to {n_vertices - 1})")
        if (a[:, 1] < 0).any():
            raise InputError(f"{path}: bone {bone!r}: negative weight {a[a[:, 1] < 0, 1][0]:g}")
        vertex.append(ids.astype(np.int64))
        joint.append(np.full(len(a), names.index(bone)))
        weight.append(a[:, 1])
    if not vertex:
        raise InputError(f"{path}: no weights")
    return np.concatenate(vertex), np.concatenate(joint), np.concatenate(weight)


def rig_to_scene(rig: Rig, scale: float, up: str, translate) -> Rig:
    """The rig scaled, turned Z-up and moved like any obstacle file (bodies.to_scene_frame)."""
    tails = None if rig.tails is None else to_scene_frame(rig.tails, scale, up, translate)
    return replace(rig, joints=to_scene_frame(rig.joints, scale, up, translate),
                   vertices=to_scene_frame(rig.vertices, scale, up, translate), tails=tails)
