"""Logging cost of a ~20K-vertex mesh stays far below 5 % of its simulation time.

`python -m viz.overhead` measures the real ratio (100^2 hanging cloth: 4.4 s per frame of
simulation against 9-10 ms per frame of logging, README "Visualization"); this test keeps
the sink's side of it from regressing without running the slow simulation.
"""

from __future__ import annotations

import time

import numpy as np

from sim.embedding import grid_faces
from sim.sinks import Frame, MeshTopology
from sim.stats import StepStats
from viz.rerun_sink import RerunSink

# The 100^2 hanging cloth simulates in >= 1 s per frame even in its easy phase (README
# "Performance": 2-3 s per step at 100^2), so 5 % of it is >= 50 ms; keep a 2x margin for
# a shared, noisy 2-core machine.
BUDGET = 0.025  # s per frame


def test_logging_20k_vertices_per_frame(tmp_path):
    a = 141  # 141^2 = 19881 vertices: the default output mesh of a 100^2 control net
    faces = grid_faces(a, a)
    u, v = np.meshgrid(np.linspace(0, 1, a), np.linspace(0, 1, a), indexing="ij")
    mesh = MeshTopology("sheet", faces, np.c_[u.ravel(), v.ravel()], np.c_[u.ravel(), v.ravel()])
    frames = 40
    sink = RerunSink(tmp_path / "big.rrd")
    start = time.perf_counter()
    sink.open([mesh])
    for k in range(frames):
        z = 0.05 * np.sin(8 * u + 0.3 * k) * v
        x = np.column_stack([u.ravel(), z.ravel(), 1.0 - v.ravel()])
        steps = [StepStats(step=k, time=0.01 * k, newton_iterations=3, extra={"contact_count": 10.0})]
        sink.write(Frame(k, 0.01 * k, {"sheet": x}, steps))
    sink.close()  # waits until everything is encoded and written
    per_frame = (time.perf_counter() - start) / frames
    assert per_frame < BUDGET, f"{per_frame * 1e3:.1f} ms per frame"
    assert abs(sink.seconds / frames - per_frame) < 0.5 * per_frame  # the sink's own clock agrees
