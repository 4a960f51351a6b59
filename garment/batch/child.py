"""The process one attempt of a job runs in: `python -m garment.batch.child`, the
attempt's spec as JSON on stdin, its temporary output folder as working directory.

It imports the job function (`module:function`, garment.dress.job:dress by default),
calls it and writes what happened to `.result.json` in that folder: the report, or the
category and message of an InputError, or the traceback of any other exception. A
process that dies (a native crash, os._exit, the OOM killer) writes nothing, which is
how task.py tells a crash, worth retrying, from a failure that would only repeat.
"""

from __future__ import annotations

import ctypes
import importlib
import json
import os
import signal
import sys
import traceback
from pathlib import Path

from sim.errors import InputError, printable

RESULT = ".result.json"
PARENT = "GARMENT_BATCH_PARENT"  # the task's pid: the job dies with it


def load(target: str):
    """The function named by `module:function`."""
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name or "main")


def run(spec: dict) -> dict:
    """Call the job; {status, report} or {status, error[, exception]}; never raises."""
    job = spec["job"]
    try:
        fn = load(spec["target"])
        report = fn(Path(job["pattern"]), Path(job["body"]), Path.cwd(), dict(job["overrides"]) or None)
        if not isinstance(report, dict) or not isinstance(report.get("status"), str):
            return {"status": "crash", "exception": True,
                    "error": f"{spec['target']} returned {printable(report, 200)}, not a report with a status"}
        return {"status": report["status"], "report": report}
    except KeyboardInterrupt:  # stopped at the timeout (task.py reports it)
        return {"status": "timeout", "error": "stopped by SIGTERM"}
    except InputError as e:  # bad input: its own category, not retried
        return {"status": getattr(e, "category", None) or "input", "error": printable(e)}
    except Exception:  # a bug or an unexpected failure: would raise again, not retried
        text = traceback.format_exc()
        print(text, file=sys.stderr, flush=True)  # whole, in job.log
        return {"status": "crash", "exception": True, "error": printable(text, 4000)}


def _die_with_parent() -> None:
    """SIGKILL this process when the task's worker dies (cancelled, OOM-killed, node lost),
    so no job outlives its Ray task. Linux only; elsewhere the job may run to its end."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.environ.get(PARENT) and os.getppid() != int(os.environ[PARENT]):
        os._exit(1)  # the parent died before prctl took effect


def _stop_on_sigterm() -> None:
    """SIGTERM (the timeout) as KeyboardInterrupt, as `garment` does, so the job's
    `finally` blocks remove its temporary files."""
    def stop(signum, _frame):
        raise KeyboardInterrupt(signal.Signals(signum).name)

    signal.signal(signal.SIGTERM, stop)


def main() -> None:
    _die_with_parent()
    _stop_on_sigterm()
    spec = json.load(sys.stdin)
    result = run(spec)
    tmp = Path(f".{RESULT}.tmp")
    tmp.write_text(json.dumps(result, default=str))
    os.replace(tmp, RESULT)  # the task reads a whole result or none


if __name__ == "__main__":
    main()
