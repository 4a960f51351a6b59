"""The driver: runs jobs on Ray, one task per attempt (task.py), and records each result
the moment it arrives.

Ray schedules: a local instance started here by default (workers = cores / threads per
job), or an existing cluster joined by address. Each task asks for `threads` CPUs and
`memory` bytes, so Ray never overcommits a node. At most as many tasks are submitted as
the cluster has room for, so "running" means running and the timeout starts with the job.

Retries: an attempt whose process died (task.py's `retry`) or whose Ray worker died
(WorkerCrashedError, NodeDiedError, OutOfMemoryError, ...) runs again, up to `retries`
more times; a status the job returned, an InputError and a Python exception are final.
Ctrl-C / SIGTERM: running tasks are cancelled (their workers killed, the jobs with them)
and KeyboardInterrupt goes on up; every finished job is already in the store.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import signal
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from sim.errors import InputError
from sim.budget import format_bytes

from . import folders, task
from .manifest import Job
from .store import Store

DEFAULT_JOB = "garment.dress.job:dress"
PROBE_S = 5.0  # to connect to --address before handing it to Ray
CANCEL_WAIT_S = 5.0  # for cancelled tasks' workers to be killed
CAPACITY_EVERY_S = 10.0  # how often a cluster's room for tasks is looked up again (autoscaling)


@dataclass
class Options:
    """job: "module:function" run for each job; address: None (start Ray here), "auto"
    or "ray://host:port"; threads: CPUs per job; memory_bytes: memory per job (None: not
    reserved); workers: cap on jobs at once (None: as many as fit); timeout_s: wall
    clock per attempt; retries: extra attempts after a worker died; paths: folders the
    job's process imports from first (the driver's project root and working folder)."""

    job: str = DEFAULT_JOB
    address: str | None = None
    threads: int = 1
    memory_bytes: float | None = 2.0 * 2**30
    workers: int | None = None
    timeout_s: float = 600.0
    retries: int = 2
    paths: list[str] = field(default_factory=list)


def check_job(target: str) -> None:
    """InputError unless `target` names a function of a module that exists (not imported)."""
    module, sep, name = target.partition(":")
    if not sep or not module or not name.isidentifier():
        raise InputError(f"--job {target!r}: expected module:function")
    try:
        found = importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        raise InputError(f"--job {target!r}: no module {module} (is it installed, or on PYTHONPATH?)")


class Cluster:
    """Ray for one batch: `start()` starts a local instance or joins `options.address`
    (InputError when it cannot, or when no node has room for one job), `stop()` shuts
    down what start() started. An instance already running in this process (tests) is
    used as it is and left running."""

    def __init__(self, options: Options):
        self.options = options
        self.ray = None
        self.started = False

    def start(self) -> None:
        if self.ray is not None:
            return
        import ray

        self.started = _connect(ray, self.options)
        self.ray = ray
        self.room()

    def room(self) -> int:
        """Jobs the cluster can run at once: per alive node, CPUs / threads and memory /
        memory per job, whichever is less; InputError when no node fits one job."""
        o, room = self.options, 0
        for node in self.ray.nodes():
            if not node.get("Alive"):
                continue
            res = node.get("Resources", {})
            fit = int(res.get("CPU", 0) // o.threads)
            if o.memory_bytes:
                fit = min(fit, int(res.get("memory", 0) // o.memory_bytes))
            room += fit
        if room == 0:
            raise InputError(f"no node of the Ray cluster has {o.threads} CPUs and "
                             f"{format_bytes(o.memory_bytes or 0)} of memory free for one job: lower "
                             f"--threads-per-job or --memory-per-job")
        return min(room, o.workers) if o.workers else room

    def stop(self) -> None:
        if self.started:
            self.ray.shutdown()
        self.ray, self.started = None, False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
        return False


def run(jobs: list[Job], outdir: Path, store: Store, cluster: Cluster,
        on_result: Callable[[dict], None] = lambda r: None,
        on_state: Callable[[int, int], None] = lambda running, waiting: None,
        on_retry: Callable[[Job, int, str], None] = lambda job, attempt, error: None,
        stopped: Callable[[], bool] = lambda: False) -> None:
    """Run `jobs` on `cluster` (started here if it is not) to the end, calling
    on_result(result) as each finishes (after it is recorded), on_state(running, waiting)
    about twice a second, on_retry(job, next attempt, error) when a crashed job runs
    again. stopped(): True once a stop was asked for; checked every turn, since a library
    may swallow the KeyboardInterrupt (VTK's import machinery turns one into an
    ImportError)."""
    cluster.start()
    ray, options = cluster.ray, cluster.options
    running: dict = {}  # ObjectRef -> (job, attempt)
    try:
        remote = ray.remote(task.run_attempt).options(
            num_cpus=options.threads, memory=int(options.memory_bytes) if options.memory_bytes else None,
            max_retries=0)  # retries are ours: counted, and only for deaths
        queue = deque((job, 1) for job in jobs)
        room, looked = cluster.room(), time.monotonic()
        while queue or running:
            if stopped():
                raise KeyboardInterrupt
            if time.monotonic() - looked > CAPACITY_EVERY_S:
                room, looked = cluster.room(), time.monotonic()
            while queue and len(running) < room:
                job, attempt = queue.popleft()
                running[_submit(remote, _spec(job, attempt, outdir, options))] = (job, attempt)
            on_state(len(running), len(queue))
            ready, _ = ray.wait(list(running), num_returns=len(running), timeout=0.5)
            for ref in ready:
                job, attempt = running.pop(ref)
                result = _outcome(ray, ref, job)
                if result.pop("worker_died", False):
                    folders.remove_temporaries(outdir, job.id)  # the dead attempt's
                if result.pop("retry", False):
                    if attempt <= options.retries:
                        queue.appendleft((job, attempt + 1))
                        on_retry(job, attempt + 1, result["error"])
                        continue
                    folders.record_failure(outdir, job.id, {"status": "crash", "error": result["error"],
                                                            "attempts": attempt})
                result["attempts"] = attempt
                store.record(result)
                on_result(result)
    except BaseException:  # KeyboardInterrupt (Ctrl-C, SIGTERM) above all
        if running:
            _cancel(ray, list(running))
            folders.remove_temporaries(outdir)  # the cancelled jobs'
        raise


def _cancel(ray, refs: list) -> None:
    """Cancel running tasks: their workers are killed, and the jobs die with them."""
    for ref in refs:
        ray.cancel(ref, force=True)
    try:  # until the workers are gone, so none renames a folder after the caller's sweep
        ray.wait(refs, num_returns=len(refs), timeout=CANCEL_WAIT_S)
    except BaseException:  # a second Ctrl-C: stop waiting
        pass


def _connect(ray, options: Options) -> bool:
    """Start a local Ray instance or join `options.address`; True if started here (and so
    to be shut down here)."""
    if ray.is_initialized():
        return False
    quiet = {"include_dashboard": False, "log_to_driver": False, "logging_level": logging.ERROR}
    # Ray reports usage to its authors over the network unless told not to; a user can opt in.
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    # ray.init makes SIGTERM exit at once (sys.exit); keep the command's: stop like Ctrl-C.
    sigterm = signal.getsignal(signal.SIGTERM)
    try:
        if options.address:
            _reachable(options.address)
            try:
                ray.init(address=options.address, **quiet)
            except (ConnectionError, RuntimeError, ValueError) as e:
                raise InputError(f"--address {options.address}: cannot join the Ray cluster ({e})") from None
            return True
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        workers = options.workers or max(1, cores // options.threads)
        # The driver's import path, so local workers run this code (a cluster has it installed).
        path = os.pathsep.join(dict.fromkeys([*options.paths, *filter(None, [os.environ.get("PYTHONPATH")])]))
        # "local": a new instance of our own, never someone else's found in /tmp/ray
        ray.init(address="local", num_cpus=workers * options.threads, runtime_env={"env_vars": {"PYTHONPATH": path}},
                 **quiet)
        return True
    finally:
        if sigterm is not None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, sigterm)


def _reachable(address: str) -> None:
    """InputError at once when nothing listens at HOST:PORT (Ray itself retries for minutes,
    deaf to Ctrl-C); "auto" and other forms are left to Ray."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=PROBE_S).close()
    except OSError as e:
        raise InputError(f"--address {address}: nothing answers there ({e.strerror or e}); is the cluster's "
                         f"head running (`ray start --head`, port 6379 by default, 10001 for ray://)?") from None


def _spec(job: Job, attempt: int, outdir: Path, options: Options) -> dict:
    return {"job": job.spec(), "target": options.job, "outdir": str(outdir), "timeout_s": options.timeout_s,
            "threads": options.threads, "memory_bytes": options.memory_bytes, "attempt": attempt,
            "last": attempt > options.retries, "paths": options.paths}


def _submit(remote, spec: dict):
    try:
        return remote.remote(spec)
    except ModuleNotFoundError as e:  # Ray Client: the cluster pickles the task at once
        raise InputError(f"the Ray cluster cannot import {e.name} ({e}): install this project (the same version) "
                         f"on every node, see docs/batch.md") from None


def _outcome(ray, ref, job: Job) -> dict:
    """The task's result, or a crash (retried) when its worker or node died."""
    from ray.exceptions import RayError, RayTaskError

    try:
        return ray.get(ref)
    except RayTaskError as e:  # task.py itself raised (a full disk, say): would raise again
        return {"id": job.id, "status": "crash", "error": f"the batch task failed: {e}", "report": None}
    except RayError as e:  # the worker or its node died under the task
        return {"id": job.id, "status": "crash", "retry": True, "worker_died": True, "report": None,
                "error": f"the Ray worker died ({type(e).__name__}): {str(e).splitlines()[0] if str(e) else ''}"}
