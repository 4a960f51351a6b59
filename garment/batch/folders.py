"""Each job's output folder, OUTDIR/<job id>/, appears whole or not at all.

A job writes into OUTDIR/.<id>.tmp-<pid> (pid of the process that made it), which is
renamed to OUTDIR/<id> when the job has ended, with its report.json. A folder left by a
job whose result was never recorded (the driver was killed between the two) is replaced
by the job's next run. Temporary folders of killed runs are removed when a batch starts, under a lock that keeps
a second driver off the same folder.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from sim.errors import InputError
from sim.files import atomic_write

REPORT = "report.json"
LOG = "job.log"
LOCK = ".batch.lock"
_TEMPORARY = re.compile(r"^\.(.+)\.(tmp|old)-\d+$")


def temporary(outdir: Path, job_id: str) -> Path:
    """A fresh, empty temporary folder for `job_id` owned by this process."""
    tmp = outdir / f".{job_id}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    return tmp


def finish(tmp: Path, outdir: Path, job_id: str) -> Path:
    """Move the temporary folder `tmp` to OUTDIR/<job id>, replacing an older one."""
    final = outdir / job_id
    for leftover in tmp.glob(".*.tmp*"):  # a killed job's half-written files (sim.files names)
        if leftover.is_file():
            leftover.unlink(missing_ok=True)
    if final.exists():
        old = outdir / f".{job_id}.old-{os.getpid()}"
        os.replace(final, old)
        os.replace(tmp, final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, final)
    return final


def write_report(folder: Path, report: dict) -> None:
    """report.json of a job that could not write its own (bad input, crash, timeout)."""
    with atomic_write(folder / REPORT) as tmp:
        tmp.write_text(json.dumps(report, indent=1, default=str) + "\n")


def record_failure(outdir: Path, job_id: str, report: dict) -> Path:
    """OUTDIR/<job id>/ holding only `report`, for a job whose worker never came back."""
    tmp = temporary(outdir, job_id)
    write_report(tmp, report)
    return finish(tmp, outdir, job_id)


def remove_temporaries(outdir: Path, job_id: str | None = None) -> list[Path]:
    """Remove the temporary folders of jobs whose process is gone (a stopped batch, a dead
    worker): every job's, or only `job_id`'s (one attempt of a job runs at a time)."""
    gone = []
    if outdir.is_dir():
        for p in outdir.iterdir():
            m = _TEMPORARY.match(p.name)
            if m and (job_id is None or m[1] == job_id) and p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
                gone.append(p)
    return gone


@contextmanager
def locked(outdir: Path) -> Iterator[None]:
    """Hold OUTDIR/.batch.lock: one driver per output folder (a second one is refused)."""
    f = open(outdir / LOCK, "a+")
    try:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"{outdir}: another garment batch is running on this folder; wait for it to end "
                             f"or stop it (Ctrl-C), then --resume") from None
        yield
    finally:
        f.close()
