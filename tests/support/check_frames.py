"""Check exported frames with the independent intersection test (tests/support/intersections.py).

    python -m tests.support.check_frames out/dress

Reads a `--mesh-dir` folder of `npz` frames (`<name>_<frame>.npz`; obstacles are the files
without `uv`) and prints, per frame: non-finite vertices, cloth-obstacle intersecting
triangle pairs, and cloth-cloth intersecting pairs. The cloth pieces are checked as one
mesh whose vertices at the very same position are one vertex: once sewn, panels share
their seam vertices bit for bit (sim/seams/mesh.py), and triangles sharing a vertex are
not tested against each other. Exits 1 if any frame has NaN or an intersecting pair.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from tests.support.intersections import intersecting_triangles, shared_vertices

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


def check_frame(meshes: dict[str, dict]) -> dict:
    cloth = [m for m in meshes.values() if m["cloth"]]
    obstacles = [m for m in meshes.values() if not m["cloth"]]
    off = np.cumsum([0] + [len(m["verts"]) for m in cloth])
    X = np.concatenate([m["verts"] for m in cloth])
    T = np.concatenate([m["faces"] + o for m, o in zip(cloth, off)])
    finite = bool(np.isfinite(X).all())
    body = sum(len(intersecting_triangles(X, T, o["verts"], o["faces"])) for o in obstacles) if finite else -1
    shared = len(X) - len(np.unique(X, axis=0))
    cloth_pairs = len(intersecting_triangles(*shared_vertices(X, T))) if finite else -1
    return {"time": cloth[0]["time"], "finite": finite, "body": body, "self": cloth_pairs, "shared": shared}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    args = ap.parse_args(argv)
    bad = 0
    print(f"{'frame':>5} {'time':>7} {'finite':>6} {'body':>5} {'self':>5} {'shared':>6}")
    for k, meshes in frames(args.folder).items():
        r = check_frame(meshes)
        ok = r["finite"] and r["body"] == 0 and r["self"] == 0
        bad += not ok
        print(f"{k:5d} {r['time']:7.3f} {str(r['finite']):>6} {r['body']:5d} {r['self']:5d} {r['shared']:6d}"
              + ("" if ok else "  FAIL"), flush=True)
    print(f"{bad} failing frame(s)")
    return int(bad > 0)


if __name__ == "__main__":
    sys.exit(main())
