"""`garment bench corpus`: every design of the public GarmentCode corpus, plus the bundled
shirt_mean and dress_pencil, dressed by `garment dress` with its defaults, each in its own
process. Success: status "ok" (seams below 1 mm after settling, 0 crossings by the
independent check on every exported frame, no NaN, under the 10-minute timeout).

The corpus is `../shared/assets/garmentcode_corpus/` next to the repository (or
$GARMENT_CORPUS): `manifest.csv` gives each design's type and body; pants and jumpsuits go
on `mean_all_apart.obj`, the rest on `mean_all.obj` (`patterns_garmentcode/` beside it, or
the shared one). `GARMENT_CORPUS=assets/garments/garmentcode_seed777 garment bench corpus
--case upper_garment,skirt,pants,dress,jumpsuit` dresses the 25 designs kept for the
unseen rate (their README).
Outputs are kept in `out/bench-corpus/<design>/` (or --out).
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from sim.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
COLUMNS = ("design", "type", "status", "seam_gap_max_mm", "crossings", "dofs", "seconds", "settle_time_s")


SHARED = ROOT.parent / "shared" / "assets"


def corpus_dir() -> Path:
    return Path(os.environ.get("GARMENT_CORPUS", SHARED / "garmentcode_corpus"))


def designs(case: str | None = None) -> list[dict]:
    """[{design, type, pattern, body}] of the corpus and the bundled patterns."""
    folder = corpus_dir()
    bodies = folder.parent / "patterns_garmentcode"
    if not bodies.is_dir():  # a corpus kept apart from the bodies (assets/garments/garmentcode_seed777)
        bodies = SHARED / "patterns_garmentcode"
    if not (folder / "manifest.csv").is_file():
        raise InputError(f"{folder}: no GarmentCode corpus (manifest.csv); set GARMENT_CORPUS to its folder")
    with open(folder / "manifest.csv", newline="") as f:
        rows = [{"design": r["name"], "type": r["type"],
                 "pattern": folder / f"{r['name']}_specification.json",
                 "body": bodies / f"{r['body_mesh']}.obj"} for r in csv.DictReader(f)]
    rows += [{"design": name, "type": "bundled", "pattern": ROOT / "assets" / "garments" / f"{name}.json",
              "body": ROOT / "assets" / "bodies" / "mean_all.obj"} for name in ("shirt_mean", "dress_pencil")]
    if case:
        wanted = set(case.split(","))
        rows = [r for r in rows if r["design"] in wanted or r["type"] in wanted]
        if not rows:
            raise InputError(f"--case {case}: no such design or type in the corpus")
    return rows


def dress_one(row: dict, out: Path) -> dict:
    """`garment dress` in its own process; the report it wrote (or a crash row)."""
    target = out / row["design"]
    cmd = [sys.executable, "-m", "garment.cli", "dress", str(row["pattern"]), "--body", str(row["body"]),
           "-o", str(target), "-q"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    report_file = target / "report.json"
    report = json.loads(report_file.read_text()) if report_file.is_file() else {}
    if proc.returncode not in (0, 3) or not report:
        report = {"status": "crash", "error": (proc.stderr or "").strip()[-400:], "exit_code": proc.returncode}
    return {"design": row["design"], "type": row["type"], **report}


def run(resolutions=(), steps=None, quadrature=None, case: str | None = None, out: str | None = None,
        progress=None, jobs: int = 1) -> list[dict]:
    out = Path(out or "out/bench-corpus")
    rows = designs(case)
    with ThreadPoolExecutor(max(jobs, 1)) as pool:
        cases = list(pool.map(lambda r: dress_one(r, out), rows))
    ok = sum(c["status"] == "ok" for c in cases)
    cases.append({"design": "success rate", "type": f"{ok}/{len(cases)}", "status": f"{ok / len(cases):.0%}"})
    return cases
