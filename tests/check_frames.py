"""Check exported frames with the independent intersection test (tests/intersections.py).

    python -m tests.check_frames out/dress [--band 2.5]

Reads a `--mesh-dir` folder of `npz` frames (`<name>_<frame>.npz`; obstacles are the files
without `uv`) and prints, per frame: non-finite vertices, cloth-obstacle intersecting
triangle pairs, and cloth-cloth pairs. Cloth-cloth pairs with both triangles within
`band` mesh spacings (mean edge lengths) of their own panel's boundary are counted apart
as seam crossings: the simulator switches contact off within 2.5 spacings of a seam
(sim/seams.py), where panels sewn edge to edge by springs meet by construction. Exits 1
if any frame has NaN, a cloth-obstacle pair or any other cloth-cloth pair. `reach`: how
far in from the boundary (spacings) the seam crossings go; 0 is the seam line itself.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from tests.intersections import intersecting_triangles

_NAME = re.compile(r"^(?P<name>.+)_(?P<frame>\d+)\.npz$")


def frames(folder: Path) -> dict[int, dict[str, dict]]:
    """{frame: {name: {"verts", "faces", "cloth"}}} of every npz in the folder."""
    out: dict[int, dict[str, dict]] = defaultdict(dict)
    for f in sorted(folder.glob("*.npz")):
        m = _NAME.match(f.name)
        if m is None:
            continue
        with np.load(f) as d:
            out[int(m["frame"])][m["name"]] = {"verts": d["verts"], "faces": d["faces"].astype(np.int64),
                                               "cloth": len(d["uv"]) > 0, "time": float(d["time"])}
    return dict(sorted(out.items()))


def boundary_vertices(faces: np.ndarray) -> np.ndarray:
    """Vertices on edges used by one triangle only."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    return np.unique(uniq[count == 1])


def check_frame(meshes: dict[str, dict], band: float) -> dict:
    cloth = [m for m in meshes.values() if m["cloth"]]
    obstacles = [m for m in meshes.values() if not m["cloth"]]
    V, F, near, off = [], [], [], 0
    for m in cloth:
        X, T = m["verts"], m["faces"]
        b = boundary_vertices(T)
        d, _ = cKDTree(X[b]).query(X)
        spacing = np.linalg.norm(X[T[:, 1]] - X[T[:, 0]], axis=1).mean()
        near.append(d[T].min(axis=1) / spacing)  # triangle-to-boundary distance, spacings
        V.append(X)
        F.append(T + off)
        off += len(X)
    X, T, reach = np.concatenate(V), np.concatenate(F), np.concatenate(near)
    near = reach <= band
    finite = bool(np.isfinite(X).all())
    body = sum(len(intersecting_triangles(X, T, o["verts"], o["faces"])) for o in obstacles) if finite else -1
    pairs = intersecting_triangles(X, T) if finite else np.zeros((0, 2), int)
    at_seams = near[pairs[:, 0]] & near[pairs[:, 1]]
    # How far in from the boundary seam crossings reach: 0 = along the seam line itself.
    depth = reach[pairs[at_seams]].max(axis=1).max(initial=0.0)
    return {"time": cloth[0]["time"], "finite": finite, "body": body,
            "self": int((~at_seams).sum()), "seam": int(at_seams.sum()), "seam_depth": float(depth)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--band", type=float, default=2.5,
                    help="seam band around panel boundaries, in mesh spacings (2.5)")
    args = ap.parse_args(argv)
    bad = 0
    print(f"{'frame':>5} {'time':>7} {'finite':>6} {'body':>5} {'self':>5} {'seam':>5} {'reach':>5}")
    for k, meshes in frames(args.folder).items():
        r = check_frame(meshes, args.band)
        ok = r["finite"] and r["body"] == 0 and r["self"] == 0
        bad += not ok
        print(f"{k:5d} {r['time']:7.3f} {str(r['finite']):>6} {r['body']:5d} {r['self']:5d} {r['seam']:5d} "
              f"{r['seam_depth']:5.2f}"
              + ("" if ok else "  FAIL"), flush=True)
    print(f"{bad} failing frame(s)")
    return int(bad > 0)


if __name__ == "__main__":
    sys.exit(main())
