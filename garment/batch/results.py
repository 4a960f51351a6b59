"""OUTDIR/results.csv: one row per finished job, in manifest order, rewritten whole
(sim.files.atomic_write) from the store after every run, interrupted ones included.

Columns: id, pattern, body, type, the manifest's override columns, status, attempts,
wall_s (the attempt's wall-clock seconds), the report's fields (seam_gap_max_mm,
crossings, dofs, seconds, settle_time_s, then any others the job reports, sorted),
node (the machine it ran on) and error (empty when none)."""

from __future__ import annotations

import csv
from pathlib import Path

from sim.files import atomic_write

from .manifest import Job

NAME = "results.csv"
REPORT_FIELDS = ("seam_gap_max_mm", "crossings", "dofs", "seconds", "settle_time_s")


def rows(jobs: dict[str, Job], results: dict[str, dict]) -> list[dict]:
    """The rows of results.csv (finished jobs only)."""
    out = []
    for job in jobs.values():
        r = results.get(job.id)
        if r is None:
            continue
        row = {"id": job.id, "pattern": str(job.pattern), "body": str(job.body), "type": job.type,
               **{k: _cell(v) for k, v in job.overrides.items()},
               "status": r["status"], "attempts": r["attempts"], "wall_s": r["wall_s"]}
        for k, v in (r.get("report") or {}).items():
            if k not in row and k not in ("status", "error", "attempts", "wall_s") and _scalar(v):
                row[k] = v
        row.update(node=r.get("node") or "", error=(r.get("error") or "").strip())
        out.append(row)
    return out


def columns(jobs: dict[str, Job], table: list[dict]) -> list[str]:
    overrides = list(dict.fromkeys(k for j in jobs.values() for k in j.overrides))
    fixed = ["id", "pattern", "body", "type", *overrides, "status", "attempts", "wall_s", *REPORT_FIELDS]
    extra = sorted({k for r in table for k in r} - set(fixed) - {"node", "error"})
    return [*fixed, *extra, "node", "error"]


def write(outdir: Path, jobs: dict[str, Job], results: dict[str, dict]) -> Path:
    table = rows(jobs, results)
    path = outdir / NAME
    with atomic_write(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, columns(jobs, table), restval="")
        w.writeheader()
        w.writerows(table)
    return path


def _scalar(v) -> bool:
    return isinstance(v, (str, int, float, bool)) or v is None


def _cell(v):
    return v if _scalar(v) else repr(v)
