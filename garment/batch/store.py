"""The batch's record: one SQLite file, OUTDIR/batch.sqlite, in WAL mode.

It holds every job of the batch (its spec, in manifest order) and, as each job finishes,
its result, committed before the next one is looked at: a driver killed at any moment
(SIGKILL included) loses no finished job, and `--resume` runs only the jobs without a
result. A job's result is inserted once and never replaced, so each job ends exactly
once. Readers (a test, a user's script) may open the file while the batch runs.
"""

from __future__ import annotations

import json
import sqlite3
import time
from pathlib import Path

from sim.errors import InputError

from .manifest import Job

NAME = "batch.sqlite"
VERSION = 1

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS jobs (seq INTEGER NOT NULL, id TEXT PRIMARY KEY, spec TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS results (
    id TEXT PRIMARY KEY REFERENCES jobs(id),
    status TEXT NOT NULL,
    attempts INTEGER NOT NULL,
    wall_s REAL,
    report TEXT NOT NULL,
    error TEXT,
    node TEXT,
    finished REAL NOT NULL
);
"""


def holds_batch(outdir: Path) -> bool:
    return (outdir / NAME).exists()


class Store:
    """Jobs and results of the batch in `outdir` (created when missing)."""

    def __init__(self, outdir: Path):
        self.path = outdir / NAME
        try:
            # autocommit mode: each statement (or explicit transaction) is durable when it returns
            self.db = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute("PRAGMA synchronous=FULL")  # one fsync per finished job is nothing next to a job
            self.db.executescript(_SCHEMA)
            self.db.execute("INSERT OR IGNORE INTO meta VALUES ('version', ?)", (str(VERSION),))
            version = self.db.execute("SELECT value FROM meta WHERE key = 'version'").fetchone()[0]
        except sqlite3.DatabaseError as e:
            raise InputError(f"{self.path}: not a batch record ({e}); choose another output folder") from None
        if version != str(VERSION):
            raise InputError(f"{self.path}: written by another version of garment batch (format {version}, "
                             f"this one reads {VERSION}); choose another output folder")

    def close(self) -> None:
        self.db.close()

    def add_jobs(self, jobs: list[Job]) -> None:
        """Record `jobs`; a job id already recorded must be the same job (same inputs)."""
        known = self.jobs()
        for job in jobs:
            old = known.get(job.id)
            if old is not None and old.spec() != job.spec():
                raise InputError(f"{self.path.parent}: job {job.id} was recorded with other inputs "
                                 f"({_difference(old.spec(), job.spec())}); to run the new manifest choose "
                                 f"another output folder")
        start = len(known)
        with self.db:
            self.db.execute("BEGIN")
            self.db.executemany("INSERT OR IGNORE INTO jobs VALUES (?, ?, ?)",
                                [(start + k, j.id, json.dumps(j.spec())) for k, j in enumerate(jobs)
                                 if j.id not in known])

    def jobs(self) -> dict[str, Job]:
        """Every recorded job by id, in manifest order."""
        rows = self.db.execute("SELECT spec FROM jobs ORDER BY seq").fetchall()
        jobs = [Job.from_spec(json.loads(s)) for (s,) in rows]
        return {j.id: j for j in jobs}

    def record(self, result: dict) -> bool:
        """Store one finished job's result; False (and nothing changed) if it has one."""
        cur = self.db.execute(
            "INSERT OR IGNORE INTO results VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (result["id"], result["status"], result["attempts"], result.get("wall_s"),
             json.dumps(result.get("report") or {}, default=str), result.get("error"), result.get("node"),
             time.time()))
        return cur.rowcount == 1

    def results(self) -> dict[str, dict]:
        """Finished jobs' results by id (the dicts given to `record`)."""
        out = {}
        for id_, status, attempts, wall, report, error, node, _ in self.db.execute("SELECT * FROM results"):
            out[id_] = {"id": id_, "status": status, "attempts": attempts, "wall_s": wall,
                        "report": json.loads(report), "error": error, "node": node}
        return out


def _difference(old: dict, new: dict) -> str:
    keys = [k for k in new if old.get(k) != new.get(k)]
    return "; ".join(f"{k} was {old.get(k)!r}, now {new.get(k)!r}" for k in keys)
