"""A garment on the dancing body (issue 6): the bundled poncho (or, `--case dress`, the
dress_knife dress) sewn during its pre-roll and then carried by the Rumba dance, at
several knot spans. `resolution` is the
knot span in mm; seconds per step are measured after the pre-roll (the dance), with the
sewing steps reported apart. The paper's Hiphop scene: 65K DOFs, 30 s per step on 12 cores."""

from __future__ import annotations

import dataclasses
import time

from sim.simulator import Simulator

from .common import SCENES, step_summary

SCENES_BY_CASE = {"poncho": "poncho_rumba", "dress": "dress_rumba"}  # --case
COLUMNS = ("resolution", "dofs", "sew_steps", "sew_seconds_per_step", "steps", "seconds_per_step",
           "newton_iterations_per_step", "ccd_fraction", "line_search_fraction", "seam_gap_max_mm",
           "build_seconds")
DEFAULT_STEPS = 40


def run(resolutions, steps=None, quadrature=None, progress=None, case: str = "poncho") -> list[dict]:
    from garment.scene import load_scene

    if case not in SCENES_BY_CASE:
        raise SystemExit(f"garment bench garment: --case must be one of {', '.join(SCENES_BY_CASE)}, not {case!r}")
    cases = []
    for span_mm in resolutions:
        sc = load_scene(SCENES / f"{SCENES_BY_CASE[case]}.toml")
        garments = [dataclasses.replace(g, knot_span=span_mm / 1000.0) for g in sc.garments]
        if quadrature is not None:
            garments = [dataclasses.replace(g, material=dataclasses.replace(g.material, quadrature=quadrature))
                        for g in garments]
        start = time.perf_counter()
        sim = Simulator.from_scene(dataclasses.replace(sc, garments=garments))
        build = time.perf_counter() - start
        sew, dance = [], []
        for _ in range(round(sc.time.preroll / sc.time.dt)):
            sew.append(sim.step())
            if progress is not None:
                progress(span_mm, sew[-1])
        for _ in range(steps or DEFAULT_STEPS):
            dance.append(sim.step())
            if progress is not None:
                progress(span_mm, dance[-1])
        cases.append({
            "resolution": span_mm, "garment": case, "knot_span_mm": span_mm, "dofs": sim.n_dofs, "build_seconds": build,
            "sew_steps": len(sew), "sew_seconds_per_step": step_summary(sew)["seconds_per_step"],
            **step_summary(dance),
            "seam_gap_max_mm": 1e3 * max(s.extra.get("seam_gap_max", 0.0) for s in dance),
        })
    return cases
