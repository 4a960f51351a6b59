"""Membrane locking (paper section 6.1, "Mitigated membrane locking"): a 1 m sheet held
flat at two diagonal corners, no bending, E_st from 2e4 to 2e10 Pa, falls under
gravity. E_sh = r E_st with r = 5e-3 (cotton's ratio) and r = 1 (the paper's sphere
locking benchmark). A locking-free sheet folds along the free diagonal
and its free corners hang down; locking stiffens it, so less sag is worse.

Both methods use the same number of unknowns (N^2 control points vs N^2 vertices on a
grid with alternating diagonals) and are measured after the same simulated time (6 s in
0.1 s steps, whose numerical damping brings the sheet close to rest): sag is the drop of
the lowest point of the surface below the pinned corners, averaged over the last 10
steps (the residual swing), with the free corners' drop and the final largest speed. The alternating grid has its own diagonals along one of the sheet's diagonals
(for even N the cells on the main diagonal are cut along it): held at those corners the
linear sheet folds along mesh edges, a hinge with no membrane strain ("aligned"); held
at the other two corners the fold crosses the edges ("crossing"). Both are reported.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from garment.scene import PinSpec
from sim.linear import LinearSimulator
from sim.simulator import Simulator

from .common import scene

MODULI = (2e4, 2e5, 2e6, 2e7, 2e8, 2e9, 2e10)
RESOLUTION = 30
STEPS = 60
DT = 0.1  # large implicit-Euler steps damp the swinging, so the sheet is near rest at the end
SHEAR_RATIOS = (5e-3, 1.0)


def locking_scene(E: float, n: int, steps: int, corners=("u0v0", "u1v1"), shear_ratio: float = 5e-3):
    sc = scene("hanging", (n, n))
    cloth = sc.cloths[0]
    mat = dataclasses.replace(cloth.material, E_st=E, E_sh=shear_ratio * E, E_bd=0.0)
    cloth = dataclasses.replace(cloth, origin=(-0.5, -0.5, 1.0), axis_u=(1, 0, 0), axis_v=(0, 1, 0), material=mat)
    pins = [PinSpec(cloth=cloth.name, corners=tuple(corners))]
    return dataclasses.replace(sc, cloths=[cloth], pins=pins, time=dataclasses.replace(sc.time, dt=DT, frames=steps))


def _measure(sim, sc, steps: int, free: np.ndarray, progress=None) -> dict:
    z0 = sc.cloths[0].origin[2]
    start = time.perf_counter()
    iters = 0
    sags = []
    for _ in range(steps):
        st = sim.step()
        iters += st.newton_iterations
        sags.append(float(z0 - sim.positions(sc.cloths[0].name)[:, 2].min()))
        if progress is not None:
            progress(sim.n_cp, st)
    return {"seconds_per_step": (time.perf_counter() - start) / steps, "newton_iterations": iters / steps,
            "sag_m": float(np.mean(sags[-10:])), "sag_final_m": sags[-1],
            "corner_sag_m": float(z0 - sim.C[free, 2].mean()), "speed_mps": float(np.abs(sim.V).max())}


def case(E: float, n: int = RESOLUTION, steps: int = STEPS, progress=None, shear_ratio: float = 5e-3) -> dict:
    out = {"case": "locking", "E_st": E, "E_sh_ratio": shear_ratio, "resolution": n, "linear_resolution": n,
           "steps": steps, "time_s": steps * DT}
    # Row-major N x N grids on both: the free corners of each pinned diagonal.
    main, anti = ("u0v0", "u1v1"), ("u1v0", "u0v1")
    free = {main: np.array([(n - 1) * n, n - 1]), anti: np.array([0, n * n - 1])}
    aligned, crossing = (main, anti) if n % 2 == 0 else (anti, main)
    sc = locking_scene(E, n, steps, main, shear_ratio)
    for key, value in _measure(Simulator.from_scene(sc), sc, steps, free[main], progress).items():
        out[f"{key}_bspline"] = value
    for label, corners in (("aligned", aligned), ("crossing", crossing)):
        sc = locking_scene(E, n, steps, corners, shear_ratio)
        for key, value in _measure(LinearSimulator.from_scene(sc, n), sc, steps, free[corners], progress).items():
            out[f"{key}_linear_{label}"] = value
    out["seconds_per_step_linear"] = out["seconds_per_step_linear_crossing"]
    out["speedup"] = out["seconds_per_step_linear"] / out["seconds_per_step_bspline"]
    return out


def run(moduli=MODULI, n: int = RESOLUTION, steps: int = STEPS, progress=None,
        shear_ratios=SHEAR_RATIOS) -> list[dict]:
    return [case(E, n, steps, progress, r) for r in shear_ratios for E in moduli]
