"""Membrane locking (paper section 6.1, "Mitigated membrane locking"): a 1 m sheet held
flat at two diagonal corners, no bending, E_st from 2e4 to 2e10 Pa, hangs under gravity.
E_sh = r E_st with r = 5e-3 (cotton's ratio) and r = 1 (the paper's sphere locking
benchmark). A locking-free sheet folds along the free diagonal and its free corners hang
down (an inextensible sheet: sag 1/sqrt(2) = 0.707 m; stretching only adds to that);
locking stiffens it, so less sag is worse.

Both methods use the same number of unknowns (N^2 control points vs N^2 vertices on a
grid with alternating diagonals) and are measured at rest (static equilibrium): implicit
Euler from DT0, the step growing by DT_GROWTH per step up to DT_MAX (a large implicit
step is nearly a static solve, and its numerical damping stops the swinging), each step
solved to ||dC||_inf < STEP_TOL (the scenes' 1e-2 m/s criterion allows 1e-3 m per
0.1 s step, which at E_st >= 2e8 Pa leaves membrane forces 10^2-10^6 times the weight
unbalanced and keeps the sheet ringing). A run is at rest when, on REST_STEPS
consecutive converged steps, the largest control-point / vertex speed is below
REST_SPEED and the sag changes by less than REST_SAG; it stops there or at the step
cap. Each row reports, per run, `at_rest_*`, the final speed, the number of steps and
the simulated time it took, and `force_residual_*`: the largest nodal force of
elasticity plus gravity (inertia excluded) over that node's weight (0 in exact
equilibrium; at E_st = 2e10 Pa the STEP_TOL bound on Newton's step still leaves up to
about 1e-2, a force that moves the sheet by less than STEP_TOL).

Sag is the drop of the lowest point of the surface (B-spline: its embedded mesh) below
the pinned corners, with the free corners' drop and the membrane energy at rest. The
alternating grid has its own diagonals along one of the sheet's diagonals (for even N
the cells on the main diagonal are cut along it): held at those corners the linear sheet
can fold along mesh edges, a hinge with no membrane strain ("aligned"); held at the
other two corners no edge line joins the pins ("crossing"; the sheet then folds on the
two edge lines one cell either side of the diagonal). Both are reported.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from garment.scene import PinSpec
from sim.energies.membrane import MembraneEnergy
from garment.build import build_linear_simulator
from garment.build import build_simulator

from .common import scene

MODULI = (2e4, 2e5, 2e6, 2e7, 2e8, 2e9, 2e10)
RESOLUTION = 30
STEPS = 60  # step cap; at 30^2 rest takes 12-19 steps (up to 27 at 40^2)
SHEAR_RATIOS = (5e-3, 1.0)
# Time steps: DT0 * DT_GROWTH^k, capped at DT_MAX (s).
DT0 = 0.1
DT_GROWTH = 1.25
DT_MAX = 10.0
STEP_TOL = 1e-9  # m: Newton stops when its step ||dC||_inf is below this
MAX_NEWTON = 300  # per step; stiff linear sheets use all of them in the first steps
# Rest: speed and sag-change bounds held on REST_STEPS consecutive converged steps.
REST_SPEED = 1e-4  # m/s
REST_SAG = 1e-5  # m per step
REST_STEPS = 2


def locking_scene(E: float, n: int, steps: int, corners=("u0v0", "u1v1"), shear_ratio: float = 5e-3,
                  quadrature: str | None = None):
    sc = scene("hanging", (n, n))
    cloth = sc.cloths[0]
    mat = dataclasses.replace(cloth.material, E_st=E, E_sh=shear_ratio * E, E_bd=0.0)
    if quadrature is not None:
        mat = dataclasses.replace(mat, quadrature=quadrature)
    cloth = dataclasses.replace(cloth, origin=(-0.5, -0.5, 1.0), axis_u=(1, 0, 0), axis_v=(0, 1, 0), material=mat)
    pins = [PinSpec(cloth=cloth.name, corners=tuple(corners))]
    tm = dataclasses.replace(sc.time, dt=DT0, frames=steps, max_newton_iterations=MAX_NEWTON)
    return dataclasses.replace(sc, cloths=[cloth], pins=pins, time=tm)


def force_residual(sim, g: float) -> float:
    """Largest |elastic + gravity force| on a free point over its weight m g (inertia excluded)."""
    grad = np.zeros_like(sim.C)
    for e in sim.model.energies:
        if e is not sim.model.inertia:
            e.add_gradient(sim.C, grad)
    free = ~sim.model.pinned
    return float((np.linalg.norm(grad[free], axis=1) / (sim.model.mass[free] * g)).max(initial=0.0))


def membrane_energy(sim) -> float:
    return float(sum(e.value(sim.C) for e in sim.model.energies if isinstance(e, MembraneEnergy)))


def relax(sim, name: str, z0: float, g: float, steps: int, progress=None) -> dict:
    """Step `sim` with growing dt until it is at rest (see the module docstring) or
    `steps` steps are done; the measurements at the end."""
    start = time.perf_counter()
    iters, calm = 0, 0
    dt = DT0
    sag = np.nan
    st = None
    for k in range(steps):
        sim.set_dt(dt)
        sim.model.newton.tol = STEP_TOL / dt  # Newton's criterion is ||dC||_inf / dt < tol
        st = sim.step()
        iters += st.newton_iterations
        prev, sag = sag, float(z0 - sim.positions(name)[:, 2].min())
        speed = float(np.linalg.norm(sim.V, axis=1).max())
        calm = calm + 1 if (st.converged and speed < REST_SPEED and abs(sag - prev) < REST_SAG) else 0
        if progress is not None:
            progress(sim.model.n_cp, st)
        if calm >= REST_STEPS:
            break
        dt = min(dt * DT_GROWTH, DT_MAX)
    done, seconds = sim.step_count, time.perf_counter() - start
    return {"at_rest": calm >= REST_STEPS, "speed_mps": float(np.linalg.norm(sim.V, axis=1).max()),
            "force_residual": force_residual(sim, g), "sag_m": sag, "rest_steps": done, "rest_time_s": sim.t,
            "newton_iterations": iters / max(done, 1), "newton_converged": bool(st is not None and st.converged),
            "seconds": seconds, "seconds_per_step": seconds / max(done, 1),
            "membrane_energy_J": membrane_energy(sim)}


def free_corners(n: int, corners) -> np.ndarray:
    """Row-major indices of the two corners not pinned (N x N control points or vertices)."""
    main = ("u0v0", "u1v1")
    return np.array([(n - 1) * n, n - 1]) if tuple(corners) == main else np.array([0, n * n - 1])


def run_one(kind: str, E: float, n: int, corners, shear_ratio: float, steps: int = STEPS,
            quadrature: str | None = None, progress=None):
    """One relaxed sheet: kind "bspline" or "linear". Returns (measurements, simulator)."""
    sc = locking_scene(E, n, steps, corners, shear_ratio, quadrature)
    sim = build_simulator(sc) if kind == "bspline" else build_linear_simulator(sc, n)
    z0 = sc.cloths[0].origin[2]
    g = float(np.linalg.norm(sc.load.gravity))
    out = relax(sim, sc.cloths[0].name, z0, g, steps, progress)
    out["corner_sag_m"] = float(z0 - sim.C[free_corners(n, corners), 2].mean())
    return out, sim


def case(E: float, n: int = RESOLUTION, steps: int = STEPS, progress=None, shear_ratio: float = 5e-3) -> dict:
    out = {"case": "locking", "E_st": E, "E_sh_ratio": shear_ratio, "resolution": n, "linear_resolution": n,
           "steps": steps}
    main, anti = ("u0v0", "u1v1"), ("u1v0", "u0v1")
    aligned, crossing = (main, anti) if n % 2 == 0 else (anti, main)
    for label, kind, corners in (("bspline", "bspline", main), ("linear_aligned", "linear", aligned),
                                 ("linear_crossing", "linear", crossing)):
        res, _ = run_one(kind, E, n, corners, shear_ratio, steps, progress=progress)
        for key, value in res.items():
            out[f"{key}_{label}"] = value
    out["at_rest"] = all(out[f"at_rest_{k}"] for k in ("bspline", "linear_aligned", "linear_crossing"))
    # Simulated seconds until the slowest of the three came to rest (compare_plots labels with it).
    out["time_s"] = max(out[f"rest_time_s_{k}"] for k in ("bspline", "linear_aligned", "linear_crossing"))
    return out


def run(moduli=MODULI, n: int = RESOLUTION, steps: int = STEPS, progress=None,
        shear_ratios=SHEAR_RATIOS) -> list[dict]:
    return [case(E, n, steps, progress, r) for r in shear_ratios for E in moduli]
