"""`garment bench compare`: the B-spline cloth against the linear FEM baseline
(sim/linear) on one machine in one run (paper section 6; issue 7).

Cases (`--case`, comma-separated; default: plate, locking and the smallest hanging pair):

- hanging, drape, shear: the paper's resolution pairs, B-spline N^2 control points vs
  linear M^2 vertices (grid, alternating diagonals), seconds per step of each and the
  speedup, with shape measures between the two final states (compare_shape.py) so the
  pairing is measured (the bundled hanging sheet carries a 1 mm seed). `--resolution N`
  runs one pair (M from the paper's table, else
  1.5 N). Both runs are preceded by a tiny warm-up run so JIT loading is not timed.
- sphere: cloth on sphere with contact, B-spline 75^2 vs linear 85^2 (slow).
- plate: error vs runtime (compare_plate.py).
- locking: sag against E_st (compare_locking.py); `--resolution` sets N.
- ablation: time per Newton iteration, variants A-E (compare_ablation.py).

Every case row carries "case"; pair rows carry resolution, linear_resolution,
seconds_per_step_bspline, seconds_per_step_linear and speedup. The
rows are also written to `out` (default out/compare) as compare.json, compare.md
(tables) and PNG plots.
"""

from __future__ import annotations

import json
import time
from pathlib import Path


from garment.build import build_linear_simulator
from garment.build import build_simulator

from . import compare_ablation, compare_locking, compare_plate, compare_plots
from .common import scene
from .common import step_summary
from .compare_shape import compare as shape_measures

PAIRS = {
    "hanging": ((75, 115), (100, 175), (125, 200)),
    "drape": ((100, 150), (125, 175)),
    "shear": ((100, 125), (125, 150)),
    "sphere": ((75, 85),),
}
# Line of material points the fold count follows: the hanging sheet's wrinkle layers
# cross its vertical centre line; drape and shear wrinkles run across the diagonal.
FOLD_LINE = {"hanging": "centre", "drape": "diagonal", "shear": "diagonal", "sphere": "diagonal"}
CASES = ("hanging", "drape", "shear", "sphere", "plate", "locking", "ablation")
DEFAULT_CASES = ("plate", "locking", "hanging")
DEFAULT_STEPS = {"hanging": 20, "drape": 20, "shear": 20, "sphere": 10}
DEFAULT_OUT = Path("out/compare")

COLUMNS = ("case", "method", "variant", "E_st", "E_sh_ratio", "resolution", "linear_resolution", "dofs",
           "dofs_linear", "steps",
           "seconds_per_step_bspline", "seconds_per_step_linear", "speedup", "newton_iterations_bspline",
           "newton_iterations_linear", "hausdorff_mm", "material_rms_mm", "folds_bspline", "folds_linear",
           "max_dihedral_deg_bspline", "max_dihedral_deg_linear", "rel_error", "seconds",
           "sag_m_bspline", "sag_m_linear_aligned", "sag_m_linear_crossing", "at_rest",
           "seconds_per_iteration", "assembly_seconds", "factorization_seconds", "solve_seconds",
           "line_search_seconds")


def _warm_up(name: str) -> None:
    """Load every JIT kernel the case uses, on a tiny version of it."""
    sc = scene(name, (8, 8))
    build_simulator(sc).step()
    build_linear_simulator(sc, 8).step()


def pair(name: str, n: int, m: int, steps: int, quadrature=None, progress=None) -> dict:
    """One B-spline n^2 vs linear m^2 run of scene `name` for `steps` steps."""
    _warm_up(name)
    row = {"case": name, "resolution": n, "linear_resolution": m, "steps": steps}
    sims = {}
    for label, build, res in (("bspline", lambda: build_simulator(scene(name, (n, n), quadrature)), n),
                              ("linear", lambda: build_linear_simulator(scene(name), m), m)):
        start = time.perf_counter()
        sim = build()
        row[f"build_seconds_{label}"] = time.perf_counter() - start
        stats = []
        for _ in range(steps):
            stats.append(sim.step())
            if progress is not None:
                progress(res, stats[-1])
        s = step_summary(stats)
        row[f"dofs_{label}"] = sim.n_dofs
        for key in ("seconds_per_step", "seconds_per_iteration", "converged_fraction"):
            row[f"{key}_{label}"] = s[key]
        row[f"newton_iterations_{label}"] = s["newton_iterations_per_step"]
        row[f"factorization_fraction_{label}"] = s["factorization_fraction"]
        sims[label] = sim
    row["dofs"] = row["dofs_bspline"]
    row["speedup"] = row["seconds_per_step_linear"] / row["seconds_per_step_bspline"]
    normal = scene(name).cloths[0].normal
    row.update(shape_measures(sims["bspline"], sims["linear"], normal, FOLD_LINE[name]))
    return row


def run(resolutions=(), steps=None, quadrature=None, progress=None, case=None, out=DEFAULT_OUT) -> list[dict]:
    """Rows of the cases named in `case` (comma-separated); written to `out` unless None."""
    names = tuple(case.split(",")) if case else DEFAULT_CASES
    unknown = set(names) - set(CASES)
    if unknown:
        raise ValueError(f"unknown compare case(s) {sorted(unknown)}; choose from {', '.join(CASES)}")
    rows: list[dict] = []
    for name in names:
        if name in PAIRS:
            table = dict(PAIRS[name])
            ns = resolutions or (tuple(table) if case else (PAIRS[name][0][0],))
            for n in ns:
                m = table.get(n, int(round(1.5 * n)))
                rows.append(pair(name, n, m, steps or DEFAULT_STEPS[name], quadrature, progress))
        elif name == "plate":
            rows += compare_plate.run()
        elif name == "locking":
            rows += compare_locking.run(n=resolutions[0] if resolutions else compare_locking.RESOLUTION,
                                        steps=steps or compare_locking.STEPS, progress=progress)
        elif name == "ablation":
            rows += compare_ablation.run(n=resolutions[0] if resolutions else compare_ablation.RESOLUTION,
                                         steps=steps or compare_ablation.STEPS, progress=progress)
    if out is not None:
        write(rows, Path(out))
    return rows


def write(rows: list[dict], folder: Path) -> list[Path]:
    """compare.json, compare.md (one markdown table per case) and PNG plots in `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "compare.json").write_text(json.dumps({"benchmark": "compare", "cases": rows}, indent=1))
    lines = []
    for name in dict.fromkeys(r["case"] for r in rows):
        group = [r for r in rows if r["case"] == name]
        cols = [c for c in dict.fromkeys(k for r in group for k in r) if c != "case"]
        lines += [f"### {name}", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        lines += ["| " + " | ".join(_fmt(r.get(c, "")) for c in cols) + " |" for r in group]
        lines.append("")
    (folder / "compare.md").write_text("\n".join(lines))
    return [folder / "compare.json", folder / "compare.md"] + compare_plots.write(rows, folder)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def tables(rows: list[dict]) -> list[tuple[str, list[str], list[dict]]]:
    """(title, columns, rows) per case, with the columns the case's rows carry."""
    out = []
    for name in dict.fromkeys(r["case"] for r in rows):
        group = [r for r in rows if r["case"] == name]
        cols = [c for c in COLUMNS if c != "case" and any(c in r for r in group)]
        out.append((name, cols, group))
    return out



