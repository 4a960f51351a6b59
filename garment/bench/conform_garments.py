"""Conforming whole garments: time per input panel against the 2 s target (issue 5), with
the quality figures that must hold at that speed.

The bundled garments (assets/garments/): dress_knife (14 triangle-mesh panels), the
GarmentCode shirt (8 outline panels) and pencil dress (its skirt_back split at four darts
into five patches). `resolution` is the knot span in mm. A split panel's time is that of
all its pieces together: the target is per panel the user hands in.
"""

from __future__ import annotations

import time
from pathlib import Path

from conform.pipeline import ConformOptions, conform_all
from garment.io.garments import read_pattern

GARMENTS = Path(__file__).resolve().parents[2] / "assets" / "garments"
CASES = {"dress_knife": "dress_knife.obj", "shirt_mean": "shirt_mean.json", "dress_pencil": "dress_pencil.json"}
TARGET_SECONDS = 2.0

COLUMNS = ("garment", "resolution", "panels", "patches", "max_panel_seconds", "slowest_panel", "target_ratio",
           "total_seconds", "worst_fit_ratio", "max_area_error_pct", "min_jacobian_ratio")


def panel_seconds(ps) -> dict[str, float]:
    """Seconds per input panel: a split panel's pieces summed."""
    pieces = {n for s in ps.splits.values() for n in s["patches"]}
    out = {name: s["seconds"] for name, s in ps.splits.items()}
    out.update({name: q["seconds"] for name, q in ps.quality.items() if name not in pieces})
    return out


def measure(name: str, span_mm: int) -> dict:
    span = 1e-3 * span_mm
    panels, seams = read_pattern(GARMENTS / CASES[name], span)
    start = time.perf_counter()
    ps = conform_all(panels, seams, ConformOptions(knot_span=span))
    total = time.perf_counter() - start
    if ps.failures:
        raise RuntimeError(f"{name}: panels did not conform: {ps.failures}")
    seconds = panel_seconds(ps)
    slowest = max(seconds, key=seconds.get)
    q = ps.quality.values()
    return {
        "garment": name, "resolution": span_mm, "panels": len(panels), "patches": len(ps.patches),
        "max_panel_seconds": seconds[slowest], "slowest_panel": slowest,
        "target_ratio": seconds[slowest] / TARGET_SECONDS, "total_seconds": total,
        "worst_fit_ratio": max(r["boundary_error_mm"] / r["tolerance_mm"] for r in q),
        "max_area_error_pct": max(abs(r["area_error_reduced_pct"]) for r in q),
        "min_jacobian_ratio": min(r["min_jacobian_ratio"] for r in q),
    }


def run(resolutions, steps=None, quadrature=None, case: str | None = None) -> list[dict]:
    names = case.split(",") if case else list(CASES)
    unknown = [n for n in names if n not in CASES]
    if unknown:
        raise SystemExit(f"garment bench conform-garments: --case must be among {', '.join(CASES)}, "
                         f"not {', '.join(unknown)}")
    return [measure(n, r) for r in resolutions for n in names]
