"""`garment batch MANIFEST -o OUTDIR` (or `--patterns GLOB --body BODY`): dress many
garments on Ray (garment/batch/, docs/batch.md), resumable with `--resume`.

Writes OUTDIR/<job id>/ per job (run.rrd, garment.obj, report.json, job.log,
thumbnail.png), OUTDIR/results.csv, summary.md and summary.html, and the record
OUTDIR/batch.sqlite. Exit status: 0 when the batch ran, whatever the jobs' statuses (they
are in results.csv); 2 for bad input (nothing run); 130 when interrupted (finished jobs
are kept; --resume runs the rest).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import threading
from pathlib import Path

from rich.markup import escape

from sim.budget import parse_bytes
from sim.errors import InputError, Interrupted, printable
from sim.files import output_folder

from .console import err
from .options import number_option


def run(args) -> int:
    from garment.batch import folders, results, runner, store
    from garment.batch.summary import jobs_text

    options = _options(args)
    outdir = output_folder(args.output, "the output folder (-o)").absolute()
    jobs = _jobs(args, outdir)  # bad input stops here: nothing is written before this
    if store.holds_batch(outdir) and not args.resume:
        raise InputError(f"{outdir}: already holds a batch ({store.NAME}); pass --resume to finish it, or "
                         f"choose another output folder")
    with runner.Cluster(options) as cluster:
        if not store.holds_batch(outdir):
            cluster.start()  # an unreachable cluster, no room for a job: refused before OUTDIR is made
        try:
            outdir.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise InputError(f"{outdir}: cannot create the output folder ({e.strerror})") from None
        with folders.locked(outdir):
            total, done, interrupted = _batch(args, cluster, outdir, jobs)
    if interrupted:
        raise Interrupted(f"{len(done)} of {jobs_text(total)} finished (kept in {outdir}); "
                          f"run the same command with --resume to run the rest")
    if not args.quiet:
        ok = sum(r["status"] == "ok" for r in done.values())
        err.print(f"{jobs_text(len(done))}: {ok} ok, {len(done) - ok} failed\nwrote {escape(str(outdir))}/"
                  f"{{{results.NAME},summary.md,summary.html}}", highlight=False, soft_wrap=True)
    return 0


def _batch(args, cluster, outdir: Path, jobs) -> tuple[int, dict, bool]:
    """With OUTDIR locked: record the jobs, run those without a result, write results.csv
    and the summary. Returns (jobs in the batch, results by id, interrupted)."""
    from garment.batch import folders, results, store, summary

    record = store.Store(outdir)
    try:
        if jobs is not None:
            record.add_jobs(jobs)
        folders.remove_temporaries(outdir)  # of a run that was killed
        every = record.jobs()
        finished = record.results()
        todo = [j for j in (jobs if jobs is not None else every.values()) if j.id not in finished]
        notes: dict[str, str] = {}  # job id -> why it has no thumbnail
        interrupted = _run_jobs(args, cluster, outdir, record, every, todo, len(finished), notes)
        done = record.results()
        results.write(outdir, every, done)
        summary.write(outdir, every, done, notes)
    finally:
        record.close()
    return len(every), done, interrupted


def _run_jobs(args, cluster, outdir: Path, record, every: dict, todo: list, finished: int,
              notes: dict[str, str]) -> bool:
    """Run `todo` with the progress line, then draw the thumbnails earlier runs did not;
    True when stopped by a signal."""
    from garment.batch import runner, thumbnails
    from garment.batch.progress import BatchProgress
    from garment.batch.summary import jobs_text

    interrupted = False
    with _StopRequests() as stop, BatchProgress(len(todo), args.quiet, err) as shown:
        if finished:
            shown.note(f"resuming: {finished} of {jobs_text(len(every))} already finished, {len(todo)} to run")

        def on_result(result: dict) -> None:
            shown.finished(result)
            if not args.no_thumbnails and not stop.signal:
                with stop.deferred():
                    _thumbnail(outdir / result["id"], every[result["id"]].body, notes)

        try:
            if todo:
                runner.run(todo, outdir, record, cluster, on_result=on_result, on_state=shown.state,
                           on_retry=shown.retry, stopped=lambda: stop.signal is not None)
            for job_id in [] if args.no_thumbnails else record.results():
                if job_id not in notes and not (outdir / job_id / thumbnails.NAME).exists():
                    with stop.deferred():
                        _thumbnail(outdir / job_id, every[job_id].body, notes)
        except KeyboardInterrupt:
            interrupted = True
    return interrupted or stop.signal is not None  # even one a library swallowed


def _options(args):
    from garment.batch.runner import Options, check_job

    number_option("--threads-per-job", args.threads_per_job, ge=1, le=1024)
    number_option("--timeout", args.timeout, gt=0)
    number_option("--retries", args.retries, ge=0, le=100)
    if args.workers is not None:
        number_option("--workers", args.workers, ge=1)
    memory = None
    if args.memory_per_job.strip().lower() not in ("0", "none"):
        try:
            memory = parse_bytes(args.memory_per_job)
        except ValueError as e:
            raise InputError(f"--memory-per-job: {e}") from None
    check_job(args.job)
    root = str(Path(__file__).resolve().parents[2])
    return Options(job=args.job, address=args.address, threads=args.threads_per_job, memory_bytes=memory,
                   workers=args.workers, timeout_s=args.timeout, retries=args.retries,
                   paths=list(dict.fromkeys([root, os.getcwd()])))


def _jobs(args, outdir: Path):
    """The jobs asked for, or None: `--resume` alone runs the ones recorded in OUTDIR."""
    from garment.batch import manifest, store

    if args.manifest is not None and args.patterns:
        raise InputError("give either a MANIFEST or --patterns, not both")
    if args.body and not args.patterns:
        raise InputError("--body goes with --patterns (a manifest names each job's body)")
    if args.patterns:
        if not args.body:
            raise InputError("--patterns needs --body (the body or bodies to dress every pattern on)")
        return manifest.glob_jobs(args.patterns, args.body, args.type)
    if args.manifest is not None:
        return manifest.read_manifest(args.manifest)
    if args.resume and store.holds_batch(outdir):
        return None
    raise InputError("nothing to run: give a MANIFEST (CSV or TOML), or --patterns GLOB with --body BODY"
                     + ("" if not args.resume else f" ({outdir} holds no batch to resume)"))


class _StopRequests:
    """SIGINT, SIGTERM and SIGHUP during the batch: remembered in `signal`, and raised as
    KeyboardInterrupt (as garment.cli does) except inside `deferred()`, around native code
    that an exception must not cut short: a VTK import interrupted half way has crashed
    the next one (SIGSEGV). The runner checks `signal` too, in case a library swallows
    the exception."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self):
        self.signal: str | None = None
        self.previous = {}
        self.defer = False

    def _handle(self, signum, _frame):
        self.signal = signal.Signals(signum).name
        if not self.defer:
            raise KeyboardInterrupt(self.signal)

    @contextlib.contextmanager
    def deferred(self):
        self.defer = True
        try:
            yield
        finally:
            self.defer = False
        if self.signal:
            raise KeyboardInterrupt(self.signal)

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = {s: signal.signal(s, self._handle) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc):
        for s, handler in self.previous.items():
            signal.signal(s, handler)
        return False


def _thumbnail(folder: Path, body: Path | None, notes: dict[str, str]) -> None:
    """Draw the job's thumbnail; a failure is noted for the summary, never raised."""
    from garment.batch import thumbnails

    try:
        thumbnails.render(folder, body)
    except KeyboardInterrupt:
        raise
    except BaseException as e:  # a renderer problem must not stop the batch
        notes[folder.name] = f"thumbnail not rendered: {printable(e, 200)}"


def register(sub) -> None:
    b = sub.add_parser("batch", help="dress many garments on bodies with Ray: resumable, with a dataset report",
                       description="Run one dressing job per manifest row (or per pattern x body) on Ray. "
                                   "See docs/batch.md.")
    b.add_argument("manifest", type=Path, nargs="?", metavar="MANIFEST",
                   help="CSV with columns pattern, body[, type, overrides...] (or TOML [[job]] tables); "
                        "relative paths are relative to its folder")
    b.add_argument("-o", "--output", type=Path, required=True, metavar="OUTDIR",
                   help="folder for the jobs' outputs, results.csv and the summary")
    b.add_argument("--patterns", action="append", metavar="GLOB",
                   help="instead of a manifest: every pattern file matching GLOB (quote it; repeatable)")
    b.add_argument("--body", action="append", metavar="PATH",
                   help="with --patterns: the body (mesh, or motion) to dress each pattern on; repeatable")
    b.add_argument("--type", default="all", help="with --patterns: the garment type for the summary (default all)")
    b.add_argument("--resume", action="store_true",
                   help="finish the batch in OUTDIR: run only the jobs without a result")
    b.add_argument("--address", metavar="auto|ray://HOST:PORT",
                   help="join this Ray cluster (default: start a local Ray instance)")
    b.add_argument("--threads-per-job", type=int, default=1, metavar="N",
                   help="CPUs each job uses and asks Ray for (default 1: one job per core)")
    b.add_argument("--memory-per-job", default="2G", metavar="SIZE",
                   help="memory each job asks Ray for, e.g. 2G, 512M (default 2G; 0: none reserved)")
    b.add_argument("--workers", type=int, metavar="N", help="at most N jobs at once (default: as many as fit)")
    b.add_argument("--timeout", type=float, default=660.0, metavar="S",
                   help="wall-clock seconds per job attempt (default 660: `garment dress` stops itself at "
                        "600 s and writes its report first)")
    b.add_argument("--retries", type=int, default=2, metavar="N",
                   help="run a job again up to N times when its process dies (default 2)")
    b.add_argument("--no-thumbnails", action="store_true", help="do not render a thumbnail per garment")
    b.add_argument("--job", default="garment.dress.job:dress", help=argparse.SUPPRESS)  # tests inject jobs
    b.add_argument("-q", "--quiet", action="store_true")
    b.set_defaults(func=run)
