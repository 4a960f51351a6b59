"""One attempt of one job, as a Ray task: runs the job in a child process (child.py) in
the job's temporary folder, under the wall-clock timeout, and hands back its result.

The job gets a process of its own so that a native crash, a leak or the OOM killer
takes only that process, and a timeout is a kill of its process group, whatever the job
is doing (inside numba or CHOLMOD a Python-level timeout would never fire): SIGTERM first,
so the job can clean up, SIGKILL GRACE_S later. The Ray
worker that runs this task stays light and is reused.

Outcome: the job's status; `timeout` when killed at the limit; `crash` when the process
died without a result. A crash is handed back with `retry` unless this is the last
attempt: the driver (runner.py) runs it again. On any other outcome the temporary
folder becomes OUTDIR/<id> with report.json (the job's own, or one written here).
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from . import folders
from .child import PARENT, RESULT

LOG_TAIL = 1500  # characters of job.log quoted in a crash's error
GRACE_S = 10.0  # from SIGTERM to SIGKILL at the timeout: native code runs on until it returns


def run_attempt(spec: dict) -> dict:
    """spec: job (Job.spec()), target ("module:function"), outdir, timeout_s, threads,
    memory_bytes (None: no limit), attempt (1, 2, ...), last (no retry after this one),
    paths (folders the child imports from, first).
    Returns {id, status, report, error, wall_s, node, retry}."""
    job_id, outdir = spec["job"]["id"], Path(spec["outdir"])
    tmp = folders.temporary(outdir, job_id)
    start = time.monotonic()
    timed_out = False
    with open(tmp / folders.LOG, "wb") as log:
        proc = subprocess.Popen([sys.executable, "-m", "garment.batch.child"], stdin=subprocess.PIPE, stdout=log,
                                stderr=subprocess.STDOUT, cwd=tmp, env=_environment(spec), start_new_session=True)
        try:
            try:
                proc.stdin.write(json.dumps(spec).encode())
                proc.stdin.close()
            except BrokenPipeError:  # died before reading its spec: a crash, told by its exit status
                pass
            proc.wait(timeout=spec["timeout_s"])
        except subprocess.TimeoutExpired:
            timed_out = True
            _stop(proc)
        except BaseException:
            _kill_group(proc, signal.SIGKILL)
            raise
        code = proc.wait()
    wall = time.monotonic() - start
    out = {"id": job_id, "wall_s": round(wall, 3), "node": platform.node(), "report": None, "error": None,
           "retry": False}
    result_file = tmp / RESULT
    if timed_out:
        out.update(status="timeout", error=f"stopped after the {spec['timeout_s']:g} s timeout (--timeout)")
        _mark_report(tmp / folders.REPORT, out)  # a report the job wrote while stopping says so
    elif result_file.exists():
        result = json.loads(result_file.read_text())
        out.update(status=result["status"], report=result.get("report"), error=result.get("error"))
    else:
        out.update(status="crash", error=f"the job's process died ({_how(code)}){_tail(tmp / folders.LOG)}")
        if not spec["last"]:
            shutil.rmtree(tmp, ignore_errors=True)
            out["retry"] = True
            return out
    result_file.unlink(missing_ok=True)
    if not (tmp / folders.REPORT).exists():
        report = dict(out["report"] or {"status": out["status"]})
        if out["error"]:
            report["error"] = out["error"]
        report.setdefault("attempts", spec["attempt"])
        report.setdefault("wall_s", out["wall_s"])
        folders.write_report(tmp, report)
    folders.finish(tmp, outdir, job_id)
    return out


def _environment(spec: dict) -> dict:
    """The child's environment: the worker's, with the job's thread counts and memory
    (the job's own memory check then refuses what would not fit in the reservation)."""
    env = dict(os.environ)
    threads = str(spec["threads"])
    for name in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "GARMENT_CHOLMOD_THREADS"):
        env[name] = threads
    if spec.get("memory_bytes"):
        env["GARMENT_MEMORY_LIMIT"] = str(int(spec["memory_bytes"]))
    # This package's own root first, so the child runs the code this task runs.
    root = str(Path(__file__).resolve().parents[2])
    paths = [p for p in (root, *spec.get("paths", ())) if os.path.isdir(p)]
    env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys([*paths, *filter(None, [env.get("PYTHONPATH")])]))
    env[PARENT] = str(os.getpid())
    return env


def _stop(proc: subprocess.Popen) -> None:
    """SIGTERM to the job's process group (child.py turns it into KeyboardInterrupt, so the
    job's own clean-up runs), SIGKILL after GRACE_S if it has not ended."""
    _kill_group(proc, signal.SIGTERM)
    try:
        proc.wait(timeout=GRACE_S)
    except subprocess.TimeoutExpired:
        pass
    _kill_group(proc, signal.SIGKILL)  # anything it started that is still there


def _kill_group(proc: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(proc.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _mark_report(path: Path, out: dict) -> None:
    try:
        report = json.loads(path.read_text())
    except (OSError, ValueError):
        return
    if isinstance(report, dict):
        folders.write_report(path.parent, {**report, "status": out["status"], "error": out["error"]})


def _how(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code} without a result"


def _tail(log: Path) -> str:
    try:
        text = log.read_bytes()[-LOG_TAIL:].decode("utf-8", "replace").strip()
    except OSError:
        return ""
    return f"; the end of {log.name}:\n{text}" if text else ""
