"""Physics against analytic results (docs/design.md section 7), small enough for every run."""

from __future__ import annotations

import csv
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from garment.bench import conform_garments, plate, wrinkle
from garment.bench import garment as bench
from garment.bench.conform_garments import panel_seconds
from garment.bench.garment import SCENES, case_scene
from garment.build import build_simulator
from garment.cli import main
from garment.scene import load_scene
from sim.recovery import StepFailure


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


def test_bench_garment_cases_set_the_papers_hiphop_parameters():
    sc = case_scene("dress-hiphop", 0.016, "gauss2")
    (g,) = sc.garments
    assert (g.material.E_st, g.material.E_sh, g.material.E_bd, g.material.quadrature) == (5e5, 2.5e3, 8e2, "gauss2")
    assert (sc.contact.dhat, sc.contact.mu, sc.contact.eps_v, g.knot_span) == (3e-4, 0.1, 1e-3, 0.016)
    assert sc.time.newton_extrapolate == 0
    assert case_scene("dress-frictionless", 0.04).contact.mu == 0.0
    dress = case_scene("dress", 0.04)
    assert (case_scene("dress-band", 0.04).contact.seams, dress.contact.seams) == ("band", "merge")
    assert (dress.contact.mu, dress.contact.eps_v, dress.time.newton_extrapolate) == (0.2, 1e-2, 4)
    # The scene's nets are graded at the tucks by default; the bench times uniform ones
    # (a seam span at the knot span).
    assert load_scene(SCENES / "dress_rumba.toml").garments[0].seam_span is None
    assert dress.garments[0].seam_span == dress.garments[0].knot_span == 0.04
    with pytest.raises(SystemExit, match="dress-hiphop"):
        case_scene("hiphop", 0.04)


@pytest.mark.slow
def test_bench_garment_refines_before_the_preroll_ends(monkeypatch):
    # The hand-over's settling (finer contact mesh, closer contacts) belongs to the
    # pre-roll, not to the timed dance: the last SETTLE of it runs at the fine span.
    scene = bench.case_scene

    def short_preroll(*args):
        sc = scene(*args)
        return dataclasses.replace(sc, time=dataclasses.replace(sc.time, preroll=0.03))

    starts = []  # (time, DOFs, Newton's cap) at each step the benchmark asks for
    step = bench.step_with_recovery

    def recorded(sim, **kwargs):
        starts.append((round(sim.t, 9), sim.n_dofs, sim.model.newton.max_iterations))
        return step(sim, **kwargs)

    monkeypatch.setattr(bench, "case_scene", short_preroll)
    monkeypatch.setattr(bench, "SETTLE", 0.02)
    monkeypatch.setattr(bench, "step_with_recovery", recorded)
    (case,) = bench.run((20,), steps=1, refine=1)
    # One sewing step at the coarse span, two settling steps at the fine one from
    # t = 0.01 s (the hand-over's transient may take SETTLE_ITERATIONS), then the dance
    # from the end of the pre-roll at the scene's cap. A step that recovery splits
    # reports each half, so the settling reports at least its two steps.
    coarse, fine = case["sewn_at_dofs"], case["dofs"]
    cap, settle = 100, bench.SETTLE_ITERATIONS
    assert starts == [(0.0, coarse, cap), (0.01, fine, settle), (0.02, fine, settle), (0.03, fine, cap)]
    assert (case["sew_steps"], case["steps"]) == (1, 1) and case["settle_steps"] >= 2
    assert case["sewn_at_dofs"] < case["dofs"] and case["sewn_at_span_mm"] == 40
    assert case["settle_seconds_per_step"] > 0.0 and len(case["settle_iterations"]) == case["settle_steps"]
    assert case["settle_newton_iterations_per_step"] == np.mean(case["settle_iterations"]) >= 1


def test_bench_conform_garments_times_whole_panels():
    """The split pencil dress: its skirt_back's time is its five pieces together."""
    (case,) = conform_garments.run((20,), case="dress_pencil")
    assert (case["panels"], case["patches"]) == (6, 10)
    assert case["target_ratio"] == pytest.approx(case["max_panel_seconds"] / 2.0)
    assert 0 < case["max_panel_seconds"] < case["total_seconds"]
    assert case["worst_fit_ratio"] < 1 and case["max_area_error_pct"] < 0.1 and case["min_jacobian_ratio"] > 0.5
    with pytest.raises(SystemExit, match="dress_knife"):
        conform_garments.run((20,), case="skirt")


def test_panel_seconds_sums_the_pieces_of_a_split_panel():
    ps = SimpleNamespace(splits={"skirt": {"patches": ["skirt.0", "skirt.1"], "seconds": 0.7}},
                         quality={"skirt.0": {"seconds": 0.3}, "skirt.1": {"seconds": 0.4}, "band": {"seconds": 0.2}})
    assert panel_seconds(ps) == {"skirt": 0.7, "band": 0.2}


def test_bundled_hanging_sheet_is_seeded_and_factorizations_are_counted():
    # Unseeded, every control point keeps y = 0 (no wrinkles, 3x fewer Newton iterations):
    # the benchmark would measure an easier problem than the paper's.
    from garment.bench.common import scene as bundled

    sim = build_simulator(bundled("hanging", (10, 10)))
    assert np.abs(sim.C[:, 1]).max() > 5e-4  # the 1 mm seed
    stats = [sim.step() for _ in range(3)]
    assert sum(s.factorizations for s in stats) == sim.model.potential.solver.n_factorizations > 0
    assert sum(s.factorizations for s in stats) >= sum(s.newton_iterations for s in stats)


def test_the_cloth_benchmark_reports_the_sheets_shape():
    # The shape the paper's code is compared with: the seed's mean offset ((2/pi)^2 of
    # 1 mm over the sheet, a little less at the control points, which include the edges)
    # and the flat sheet's centroid height (0.5 m) before anything moves.
    from garment.bench import cloth
    from garment.bench.common import scene as bundled

    sc = bundled("hanging", (40, 40))
    got = cloth.shape(build_simulator(sc), sc)
    assert 0.85 < got["out_of_plane_mm"] / (4.0 / np.pi**2) < 1.0
    assert abs(got["centroid_height_mm"] - 500.0) < 1e-6
    case = cloth.runner("hanging")([8], steps=2)[0]
    assert case["centroid_height_mm"] < 500.0  # it falls
    assert set(cloth.COLUMNS) <= set(case)


def test_the_kept_seed777_designs_read_as_a_corpus(monkeypatch):
    """assets/garments/garmentcode_seed777 (the unseen rate's 25 designs) runs through
    `garment bench corpus` with GARMENT_CORPUS: every pattern reads with the panels and
    stitches its manifest gives, on a body that exists."""
    from garment.bench import corpus
    from garment.io.garments import read_pattern

    folder = corpus.ROOT / "assets" / "garments" / "garmentcode_seed777"
    monkeypatch.setenv("GARMENT_CORPUS", str(folder))
    rows = corpus.designs("upper_garment,skirt,pants,dress,jumpsuit")
    assert len(rows) == 25
    with open(folder / "manifest.csv", newline="") as f:
        counts = {r["name"]: (int(r["panels"]), int(r["stitches"])) for r in csv.DictReader(f)}
    for row in rows:
        panels, seams = read_pattern(row["pattern"], 0.04)
        assert (len(panels), len(seams)) == counts[row["design"]], row["design"]
        if not row["body"].is_file():
            pytest.skip(f"no shared bodies here ({row['body']})")
        assert row["body"].stem == ("mean_all_apart" if row["type"] in ("pants", "jumpsuit") else "mean_all")


def test_a_failed_step_in_bench_garment_is_an_error_not_a_traceback(monkeypatch, capsys):
    # The dress refined to 61K DOFs can fail its hand-over (Newton at its cap down to the
    # split floor): the benchmark says so in one line and exits 3, as `garment simulate`.
    def fail(sim, **kwargs):
        raise StepFailure(0.5, "Newton hit its iteration cap (100)")

    monkeypatch.setattr(bench, "step_with_recovery", fail)
    assert main(["bench", "garment", "--resolution", "80", "--steps", "1", "--json"]) == 3
    err = capsys.readouterr().err
    assert "error: garment bench garment --case poncho, 80 mm" in err and "t = 0.5 s" in err
    assert "Traceback" not in err
