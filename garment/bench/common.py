"""Shared pieces of the benchmarks: scene loading with overrides, and statistics."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from garment.scene import Scene, load_scene

SCENES = Path(__file__).resolve().parents[2] / "assets" / "scenes"


def scene(name: str, control_points: tuple[int, int] | None = None, quadrature: str | None = None,
          **time_overrides) -> Scene:
    """Bundled scene `name` with its (single) cloth resized and its time settings changed."""
    sc = load_scene(SCENES / f"{name}.toml")
    cloths = []
    for c in sc.cloths:
        mat = c.material if quadrature is None else dataclasses.replace(c.material, quadrature=quadrature)
        cloths.append(dataclasses.replace(c, control_points=control_points or c.control_points, material=mat))
    return dataclasses.replace(sc, cloths=cloths, time=dataclasses.replace(sc.time, **time_overrides))


def step_summary(stats) -> dict:
    """Mean cost per step and its split over a list of StepStats."""
    n = max(len(stats), 1)
    total = sum(s.t_total for s in stats)
    iters = sum(s.newton_iterations for s in stats)
    out = {
        "steps": len(stats),
        "seconds_per_step": total / n,
        "newton_iterations_per_step": iters / n,
        "factorizations_per_step": sum(s.factorizations for s in stats) / n,
        "pcg_iterations_per_step": sum(s.extra.get("pcg_iterations", 0) for s in stats) / n,
        "seconds_per_iteration": total / max(iters, 1),
    }
    for key in ("assembly", "factorization", "solve", "ccd", "line_search"):
        out[f"{key}_fraction"] = sum(getattr(s, f"t_{key}") for s in stats) / max(total, 1e-30)
    out["converged_fraction"] = float(np.mean([s.converged for s in stats])) if stats else 0.0
    return out


def observed_orders(cases: list[dict], key: str, h_key: str = "h") -> None:
    """Add `order` = log(e_k-1 / e_k) / log(h_k-1 / h_k) to consecutive cases."""
    for prev, cur in zip(cases, cases[1:]):
        if prev[key] > 0 and cur[key] > 0:
            cur["order"] = float(np.log(prev[key] / cur[key]) / np.log(prev[h_key] / cur[h_key]))
