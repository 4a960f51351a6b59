"""Physics against analytic results (DESIGN.md section 7), small enough for every run."""

from __future__ import annotations

import numpy as np
import pytest

from garment.bench import plate, wrinkle


def test_navier_coefficient():
    # Timoshenko & Woinowsky-Krieger, table 8: alpha = 0.00406 for a square plate.
    assert plate.navier_coefficient() == pytest.approx(0.0040624, abs=5e-8)


def test_plate_converges_at_second_order():
    cases = plate.run((8, 16, 32))
    errors = [c["rel_error"] for c in cases]
    assert errors[2] < 5e-3  # the bar at 32^2 with the reduced rule
    assert cases[2]["order"] >= 1.9 and cases[1]["order"] >= 1.9


def test_plate_gauss_rules_agree():
    for quadrature in ("gauss2", "gauss3"):
        (case,) = plate.run((16,), quadrature=quadrature)
        assert case["rel_error"] < 5e-3


@pytest.mark.slow
def test_wrinkle_deflection_approaches_reference():
    # Measured: 2.25 mm at 30 x 72, 2.79 mm at 40 x 97 control points (reference 3.45 mm).
    coarse, fine = wrinkle.solve(30), wrinkle.solve(40)
    assert coarse["max_deflection_mm"] < fine["max_deflection_mm"] < 1.1 * wrinkle.REFERENCE_MM
    assert fine["max_deflection_mm"] > 0.7 * wrinkle.REFERENCE_MM
