"""Small batches for the tests: pattern files that tell tests/garment/batch/jobs.py what
to do, a body file, and a manifest naming them."""

from __future__ import annotations

import csv
import hashlib
import json
import sqlite3
from pathlib import Path

JOB = "tests.garment.batch.jobs:run"


def write_batch(folder: Path, patterns: dict[str, dict], ledger: Path | None = None, types: dict | None = None,
                rrd: Path | None = None) -> Path:
    """folder/manifest.csv with one row per pattern name (behaviour dict), all on one body."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "body.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    rows = ["pattern,body,type"]
    for name, spec in patterns.items():
        spec = dict(spec)
        if ledger is not None:
            spec["ledger"] = str(ledger)
        if rrd is not None:
            spec["rrd"] = str(rrd)
        (folder / f"{name}.json").write_text(json.dumps(spec))
        rows.append(f"{name}.json,body.obj,{(types or {}).get(name, 'dress')}")
    manifest = folder / "manifest.csv"
    manifest.write_text("\n".join(rows) + "\n")
    return manifest


def read_results(outdir: Path) -> list[dict]:
    with open(outdir / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


def finished_ids(outdir: Path) -> list[str]:
    """Job ids with a result in the batch's SQLite record (read while it runs)."""
    path = outdir / "batch.sqlite"
    if not path.exists():
        return []
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=5) as db:
            return [r[0] for r in db.execute("SELECT id FROM results")]
    except sqlite3.OperationalError:  # the driver is still creating the tables
        return []


def output_hashes(outdir: Path) -> dict[str, str]:
    """SHA-256 of every file of every job folder (not the thumbnails, drawn by the driver)."""
    out = {}
    for f in sorted(outdir.glob("*/*")):
        if f.is_file() and f.name != "thumbnail.png":
            out[f"{f.parent.name}/{f.name}"] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


def ledger_lines(ledger: Path) -> list[str]:
    return ledger.read_text().splitlines() if ledger.exists() else []
