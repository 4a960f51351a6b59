"""The membrane-locking bench (garment/bench/compare_locking.py) measures sheets at rest."""

from __future__ import annotations

import numpy as np

from garment.bench import compare_locking

KINDS = ("bspline", "linear_aligned", "linear_crossing")


def test_locking_rows_report_rest_and_a_cut_short_run_is_not_at_rest():
    (row,) = compare_locking.run((2e6,), n=8, shear_ratios=(5e-3,))
    assert row["at_rest"]
    for k in KINDS:
        assert row[f"at_rest_{k}"]
        assert row[f"speed_mps_{k}"] < compare_locking.REST_SPEED
        assert row[f"rest_steps_{k}"] < compare_locking.STEPS
        # Static equilibrium: elasticity balances gravity at every free node.
        assert row[f"force_residual_{k}"] < 1e-3
        assert 0.3 < row[f"sag_m_{k}"] < 0.9  # folded about the free diagonal (0.707 m if inextensible)
    # Two steps (0.225 s) leave the sheets falling: not at rest, and the row says so.
    (short,) = compare_locking.run((2e6,), n=8, steps=2, shear_ratios=(5e-3,))
    assert not short["at_rest"] and not any(short[f"at_rest_{k}"] for k in KINDS)


def test_stiff_linear_sheet_hinges_on_its_diagonal_edges():
    # With the pins on the diagonal the alternating grid cuts along, the linear sheet can
    # fold on those edges with no strain: at rest it hangs 1/sqrt(2) m, whatever E_st.
    res, _ = compare_locking.run_one("linear", 2e10, 8, ("u0v0", "u1v1"), 1.0)
    assert res["at_rest"]
    assert abs(res["sag_m"] - np.sqrt(0.5)) < 1e-3
    assert res["membrane_energy_J"] < 1e-6
