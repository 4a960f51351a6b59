"""Rest control nets graded towards short seams (conform/grading.py)."""

from __future__ import annotations

import numpy as np
import pytest

from conform import ConformOptions
from conform.grading import RATIO, Request, grade
from conform.pipeline import conform_all
from sim.seams.spec import PanelSeam

from tests.support.panels import polygon_panel

RECT = np.array([[0.0, 0.0], [0.4, 0.0], [0.4, 0.2], [0.0, 0.2]])
LENGTHS = np.array([0.4, 0.2, 0.4, 0.2])


def test_a_grading_without_requests_is_the_uniform_chord_length_map():
    g = grade([], LENGTHS, 0, 0.04, 3)
    assert g.spans == 10 and g.is_uniform
    f = np.linspace(0, 1, 17)
    np.testing.assert_allclose(g.parameter(f, 12), 10 * f, atol=1e-14)
    np.testing.assert_allclose(g.span(np.linspace(0, 10, 7), 12, 0.4), 0.04, rtol=1e-12)


def test_a_grading_packs_spans_at_a_short_seam_and_grows_them_gently():
    req = [Request(0, 0.19, 0.21, 0.008)]
    gu, gv = grade(req, LENGTHS, 0, 0.04, 3), grade(req, LENGTHS, 1, 0.04, 3)
    # Along the side: spans of about the seam's size over the seam ...
    widths = 0.4 * np.diff(gu.t)
    at_seam = (gu.t[1:] > 0.19 / 0.4) & (gu.t[:-1] < 0.21 / 0.4)
    assert widths[at_seam].max() == pytest.approx(0.008, rel=0.15)
    # ... neighbours within RATIO of each other, and the panel's span far away.
    ratio = widths[1:] / widths[:-1]
    assert np.maximum(ratio, 1 / ratio).max() <= RATIO + 0.05
    assert widths.max() <= 0.04 + 1e-12 and widths.max() > 0.03
    # Across the side: fine rows next to it, coarse at the far side.
    rows = 0.2 * np.diff(gv.t)
    assert 0.008 <= rows[0] <= RATIO * 0.008 and rows[-1] > 0.03
    # parameter and fraction are inverse maps, at any count (knot insertion, refits).
    f = np.linspace(0, 1, 101)
    for n in (gu.spans + 2, 2 * gu.spans + 2, gu.spans + 7):
        np.testing.assert_allclose(gu.fraction(gu.parameter(f, n), n), f, atol=1e-12)
    np.testing.assert_allclose(gu.reversed().reversed().t, gu.t)


def _tucked(seam_span):
    """A 40 x 20 cm panel with a 2 cm tuck in its bottom edge (both legs on the panel)."""
    panel = polygon_panel("p", RECT, spacing=0.002)
    x = np.linspace(0.17, 0.19, 6)
    tuck = PanelSeam("tuck", "p", "p", np.stack([x, 0 * x], 1), np.stack([0.4 - x, 0 * x], 1))
    return conform_all([panel], [tuck], ConformOptions(knot_span=0.04, seam_span=seam_span))


def test_a_tucked_panel_conforms_to_a_graded_net():
    uniform, graded = _tucked(None), _tucked(0.008)
    assert uniform.patches[0].shape == (12, 7)
    X = graded.patches[0].rest
    n, m = X.shape[:2]
    assert n >= 20 and m > 7
    rep = graded.quality["p"]
    # Straight sides stay straight whatever the parametrisation; nothing inverts.
    assert rep["boundary_error_mm"] < 1e-6 and rep["inverted_points"] == 0 and rep["mips_converged"]
    assert abs(rep["area_error_gauss2_pct"]) < 1e-6
    # Control points along the tucked edge are about 8 mm apart at the tuck, 4 cm far away.
    du = np.linalg.norm(np.diff(X[:, 0], axis=0), axis=1)
    at = (X[1:, 0, 0] > 0.17) & (X[:-1, 0, 0] < 0.23)
    assert du[at][1:-1].max() == pytest.approx(0.008, rel=0.25)
    assert np.diff(X[:, -1, 0]).max() > 0.02
    # The tuck maps onto the bottom side (v0) at the fine parameters.
    seam = graded.seams[0]
    assert {i.side for i in seam.intervals_a + seam.intervals_b} == {"v0"}
    assert abs(seam.intervals_a[0].t1 - seam.intervals_a[0].t0) > 2.0  # spans cut by one leg
