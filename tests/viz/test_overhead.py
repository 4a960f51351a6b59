"""`garment bench viz-overhead` (garment/bench/viz_overhead.py) measures what Rerun logging costs next to
the simulation; the figures live in that benchmark (docs/performance.md), not in a timed
test. Here: a small run of it, its JSON and its arithmetic."""

from __future__ import annotations

import json

from garment.bench import BENCHMARKS
from garment.cli import main


def test_bench_viz_overhead_reports_logging_against_simulation(capsys):
    assert "viz-overhead" in BENCHMARKS
    assert main(["bench", "viz-overhead", "--resolution", "10", "--steps", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["benchmark"] == "viz-overhead"
    (case,) = out["cases"]
    assert case["resolution"] == 10 and case["sim_frames"] == 2 and case["log_frames"] == 200
    assert case["vertices"] >= 100 and case["rrd_megabytes"] > 0.0
    lo, hi = case["log_wall_seconds_per_frame"]
    assert 0.0 < lo <= hi
    assert abs(case["overhead_percent"] - 100.0 * hi / case["sim_seconds_per_frame"]) < 1e-9 * case["overhead_percent"]
    assert abs(case["target_ratio"] - case["overhead_percent"] / 5.0) < 1e-9 * case["target_ratio"]
