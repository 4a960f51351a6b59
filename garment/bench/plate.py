"""Simply supported square plate under uniform load (docs/design.md section 7).

Bending only, quasi-static: one Newton step solves the (quadratic) problem. The reference
is the Navier series for the centre deflection of a simply supported Kirchhoff plate,
w = alpha q a^4 / D with alpha = 16 / pi^6 sum_{m,n odd} (-1)^((m+n)/2-1) / (m n (m^2+n^2)^2)
= 0.0040624 (the rounded 0.00406 of docs/design.md would bias errors below 0.1 %).
"""

from __future__ import annotations

import time

import numpy as np

from sim.embedding import interpolation_matrix
from garment.build import build_simulator

from .common import observed_orders, scene

COLUMNS = ("resolution", "dofs", "quadrature", "max_deflection_m", "analytic_m", "rel_error", "order", "seconds")


def navier_coefficient(terms: int = 401) -> float:
    m = np.arange(1, terms, 2, dtype=float)
    M, N = np.meshgrid(m, m, indexing="ij")
    sign = (-1.0) ** ((M + N) / 2 - 1)
    return float(16.0 / np.pi**6 * np.sum(sign / (M * N * (M**2 + N**2) ** 2)))


def solve(n: int, quadrature: str = "reduced") -> dict:
    sc = scene("plate", (n, n), quadrature)
    cloth = sc.cloths[0]
    start = time.perf_counter()
    sim = build_simulator(sc)
    sim.step()
    seconds = time.perf_counter() - start
    centre = np.array([(n - 2) / 2.0])
    W = interpolation_matrix(centre, centre, n, n, 0, sim.model.n_cp)
    w = abs(float((W @ (sim.C - sim.model.C0))[0] @ np.asarray(sc.load.pressure_direction)))
    a = cloth.size[0]
    analytic = navier_coefficient() * sc.load.pressure * a**4 / cloth.material.bending_stiffness
    return {
        "resolution": n, "dofs": sim.n_dofs, "quadrature": quadrature, "h": a / (n - 2),
        "max_deflection_m": w, "analytic_m": analytic, "rel_error": abs(w - analytic) / analytic,
        "seconds": seconds,
    }


def run(resolutions, steps=None, quadrature="reduced") -> list[dict]:
    cases = [solve(n, quadrature) for n in resolutions]
    observed_orders(cases, "rel_error")
    return cases
