"""Stand-in dressing jobs for the batch tests, called as garment.dress.job:dress would be.

The pattern file is JSON that says what to do: {"behaviour": "ok" | "crash" | "kill_worker" |
"sleep" | "bad_input", "delay": s, "rrd": template recording, "ledger": file}. Each job appends
"start NAME" / "end NAME" to the ledger (NAME: the pattern's stem), so a test can count
how often a job ran."""

from __future__ import annotations

import json
import os
import shutil
import signal
import time
from pathlib import Path

from sim.errors import InputError

REPORT = {"seam_gap_max_mm": 0.4, "crossings": 0, "dofs": 12, "seconds": 0.5, "settle_time_s": 0.25}


def run(pattern: Path, body: Path, outdir: Path, overrides: dict | None = None) -> dict:
    spec = json.loads(pattern.read_text())
    _ledger(spec, f"start {pattern.stem}")
    time.sleep(spec.get("delay", 0.0))
    behaviour = spec["behaviour"]
    if behaviour == "crash":
        os._exit(1)  # as a segfault in native code would: no exception, no result
    if behaviour == "kill_worker":  # the Ray worker running the task dies (OOM killer, lost node)
        os.kill(os.getppid(), signal.SIGKILL)
        time.sleep(60)  # killed with it
    if behaviour == "sleep":
        time.sleep(3600)
    if behaviour == "bad_input":
        e = InputError(f"{pattern}: the waistband is longer than the body's waist")
        e.category = spec.get("category", "conform")
        raise e
    report = {"status": "ok", **REPORT, "overrides": overrides or {}}
    if spec.get("rrd"):  # a real recording, copied so that every run's bytes are equal
        shutil.copyfile(spec["rrd"], outdir / "run.rrd")
    (outdir / "garment.obj").write_text(OBJ)
    (outdir / "report.json").write_text(json.dumps(report, indent=1) + "\n")
    _ledger(spec, f"end {pattern.stem}")
    return report


def _ledger(spec: dict, line: str) -> None:
    if spec.get("ledger"):
        with open(spec["ledger"], "a") as f:
            f.write(line + "\n")


# A small tube (a sleeve) standing along z: 8 around, 3 rings.
def _tube() -> str:
    import math

    rings, around = 3, 8
    v = [f"v {0.1 * math.cos(2 * math.pi * k / around):.6f} {0.1 * math.sin(2 * math.pi * k / around):.6f} "
         f"{0.15 * r:.6f}" for r in range(rings) for k in range(around)]
    f = []
    for r in range(rings - 1):
        for k in range(around):
            a, b = r * around + k + 1, r * around + (k + 1) % around + 1
            f += [f"f {a} {b} {b + around}", f"f {a} {b + around} {a + around}"]
    return "\n".join(v + f) + "\n"


OBJ = _tube()
