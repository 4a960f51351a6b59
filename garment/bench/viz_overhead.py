"""`garment bench viz-overhead`: what Rerun logging costs next to the simulation it
records. Target: logging below 5 % of the simulation time.

    python -m garment.bench.viz_overhead [--resolution 100] [--sim-frames 10] [--log-frames 200] [--repeats 3]

1. Simulates the upright hanging cloth (`assets/scenes/hanging.toml`) at resolution^2
   control points for `sim-frames` frames (one 0.01 s step each) and keeps the frames;
   at 100^2 the default output mesh has 141^2 = 19881 vertices.
2. Logs `log-frames` frames of that mesh (the simulated frames, cycled, with their step
   statistics) through `RerunSink` into a temporary `.rrd`, `repeats` times, timing
   open + write + close (close waits until everything is encoded and on disk) in wall-clock
   and process CPU seconds (CPU includes rerun's encoder threads).
3. Reports seconds per frame of each and the ratio logging / simulation.

The simulation cost depends on how hard the steps are (the first frames, while the pins
move, take the most Newton iterations), so the ratio is an estimate for that phase.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from garment.bench.common import scene
from garment.build import build_simulator
from sim.sinks import Frame
from viz.render import FrameBuffer
from viz.rerun_sink import RerunSink

COLUMNS = ("resolution", "vertices", "sim_seconds_per_frame", "log_wall_ms_per_frame", "log_cpu_ms_per_frame",
           "overhead_percent", "target_ratio", "rrd_megabytes")
TARGET = 0.05  # logging / simulation


class _StepKeeper(FrameBuffer):
    """FrameBuffer that also keeps each frame's step statistics."""

    def open(self, meshes) -> None:
        super().open(meshes)
        self.steps: list[list] = []

    def write(self, frame: Frame) -> None:
        super().write(frame)
        self.steps.append(frame.steps)


def simulate(resolution: int, frames: int) -> tuple[_StepKeeper, float]:
    """Hanging cloth at resolution^2 control points: (kept frames, wall-clock s per frame)."""
    sim = build_simulator(scene("hanging", (resolution, resolution), frames=frames))
    keep = _StepKeeper()
    start = time.perf_counter()
    sim.run(frames, 1, [keep])
    return keep, (time.perf_counter() - start) / frames


def log_frames(keep: _StepKeeper, n_frames: int, path: Path, dt: float = 0.01) -> dict:
    """Log n_frames frames (cycling through the kept ones) to `path`; timings in s."""
    frames = keep.frames()[1:] or keep.frames()  # frame 0 has no steps
    steps = keep.steps[1:] or keep.steps
    wall, cpu = time.perf_counter(), time.process_time()
    sink = RerunSink(path)
    sink.open(keep.meshes)
    for k in range(n_frames):
        _, _, positions = frames[k % len(frames)]
        sink.write(Frame(k, k * dt, positions, steps[k % len(steps)]))
    sink.close()
    return {"wall": time.perf_counter() - wall, "cpu": time.process_time() - cpu,
            "bytes": path.stat().st_size}


def measure(resolution: int = 100, sim_frames: int = 10, n_log_frames: int = 200, repeats: int = 3) -> dict:
    keep, sim_per_frame = simulate(resolution, sim_frames)
    vertices = sum(len(x) for x in keep.frames()[0][2].values())
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeats):
            runs.append(log_frames(keep, n_log_frames, Path(tmp) / f"run{r}.rrd"))
    wall = np.array([r["wall"] for r in runs]) / n_log_frames
    cpu = np.array([r["cpu"] for r in runs]) / n_log_frames
    return {
        "resolution": resolution,
        "vertices": vertices,
        "sim_frames": sim_frames,
        "sim_seconds_per_frame": sim_per_frame,
        "log_frames": n_log_frames,
        "log_wall_seconds_per_frame": [float(wall.min()), float(wall.max())],
        "log_cpu_seconds_per_frame": [float(cpu.min()), float(cpu.max())],
        "overhead_fraction": [float(wall.min() / sim_per_frame), float(wall.max() / sim_per_frame)],
        "rrd_megabytes": runs[0]["bytes"] / 1e6,
    }


def run(resolutions, steps=None, quadrature=None) -> list[dict]:
    cases = []
    for n in resolutions:
        m = measure(n, sim_frames=steps or 10)
        worst = m["overhead_fraction"][1]
        cases.append({**m, "log_wall_ms_per_frame": 1e3 * m["log_wall_seconds_per_frame"][1],
                      "log_cpu_ms_per_frame": 1e3 * m["log_cpu_seconds_per_frame"][1],
                      "overhead_percent": 100.0 * worst, "target_ratio": worst / TARGET})
    return cases


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m garment.bench.viz_overhead", description=__doc__.split("\n\n")[0])
    p.add_argument("--resolution", type=int, default=100)
    p.add_argument("--sim-frames", type=int, default=10)
    p.add_argument("--log-frames", type=int, default=200)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args(argv)
    print(json.dumps(measure(a.resolution, a.sim_frames, a.log_frames, a.repeats), indent=1))


if __name__ == "__main__":
    main()
