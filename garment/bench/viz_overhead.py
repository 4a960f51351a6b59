"""What Rerun logging costs next to the simulation it records (viz/overhead.py): the
upright hanging cloth at resolution^2 control points, its output mesh logged 200 times.
Target: logging below 5 % of the simulation time."""

from __future__ import annotations

COLUMNS = ("resolution", "vertices", "sim_seconds_per_frame", "log_wall_ms_per_frame", "log_cpu_ms_per_frame",
           "overhead_percent", "target_ratio", "rrd_megabytes")
TARGET = 0.05  # logging / simulation


def run(resolutions, steps=None, quadrature=None) -> list[dict]:
    from viz.overhead import measure

    cases = []
    for n in resolutions:
        m = measure(n, sim_frames=steps or 10)
        worst = m["overhead_fraction"][1]
        cases.append({**m, "log_wall_ms_per_frame": 1e3 * m["log_wall_seconds_per_frame"][1],
                      "log_cpu_ms_per_frame": 1e3 * m["log_cpu_seconds_per_frame"][1],
                      "overhead_percent": 100.0 * worst, "target_ratio": worst / TARGET})
    return cases
