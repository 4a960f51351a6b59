"""`garment batch` on Ray: statuses, retries, the timeout, interruption and --resume.

One local Ray instance (2 CPUs) serves the module; the interrupted run starts its own, as
a user's would, and the resumed run joins this module's by address, as on a cluster. The
jobs are stand-ins (jobs.py) that take a fraction of a second."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time

import pytest

from garment.cli import main
from tests.support.paths import ROOT

from .cases import JOB, finished_ids, ledger_lines, output_hashes, read_results, write_batch


@pytest.fixture(scope="module")
def ray_address():
    import ray

    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    sigterm = signal.getsignal(signal.SIGTERM)  # ray.init replaces it with sys.exit
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             logging_level=logging.ERROR, runtime_env={"env_vars": {"PYTHONPATH": str(ROOT)}})
    signal.signal(signal.SIGTERM, sigterm)
    yield ray.get_runtime_context().gcs_address
    ray.shutdown()


@pytest.fixture(scope="module")
def rrd(tmp_path_factory):
    """A small real recording; the ok job copies it, so its bytes repeat from run to run."""
    import numpy as np
    import rerun as rr

    path = tmp_path_factory.mktemp("rrd") / "template.rrd"
    rec = rr.RecordingStream("garment-batch-test", recording_id="batch-test")
    rec.save(str(path))
    rec.set_time("frame", sequence=0)
    rec.log("garment", rr.Mesh3D(vertex_positions=np.eye(3), triangle_indices=[[0, 1, 2]]))
    rec.flush()
    del rec
    return path


def cli(*args: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    return subprocess.Popen([sys.executable, "-m", "garment.cli", "batch", *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_ok_crash_timeout_and_bad_input(tmp_path, ray_address, rrd, capsys):
    ledger = tmp_path / "ledger.txt"
    manifest = write_batch(tmp_path / "in", {
        "fine": {"behaviour": "ok"}, "segfault": {"behaviour": "crash"}, "stuck": {"behaviour": "sleep"},
        "short": {"behaviour": "bad_input", "category": "conform"}, "lost": {"behaviour": "kill_worker"}},
        ledger=ledger, types={"stuck": "skirt", "short": "skirt", "lost": "shirt"}, rrd=rrd)
    out = tmp_path / "out"
    retries = 2
    t0 = time.monotonic()
    assert main(["batch", str(manifest), "-o", str(out), "--job", JOB, "--timeout", "3",
                 "--retries", str(retries)]) == 0
    elapsed = time.monotonic() - t0
    rows = {r["id"]: r for r in read_results(out)}
    assert {i: r["status"] for i, r in rows.items()} == {
        "fine__body": "ok", "segfault__body": "crash", "stuck__body": "timeout", "short__body": "conform",
        "lost__body": "crash"}
    for name in ("segfault", "lost"):  # the job's process died; the Ray worker under it died
        assert rows[f"{name}__body"]["attempts"] == str(retries + 1)
        assert ledger_lines(ledger).count(f"start {name}") == retries + 1  # it really ran again
    assert "WorkerCrashedError" in rows["lost__body"]["error"]
    assert all(rows[i]["attempts"] == "1" for i in ("fine__body", "stuck__body", "short__body"))  # not retried
    assert "waistband" in rows["short__body"]["error"] and "timeout" in rows["stuck__body"]["error"]
    assert "died" in rows["segfault__body"]["error"]
    assert float(rows["fine__body"]["seam_gap_max_mm"]) == 0.4 and rows["fine__body"]["type"] == "dress"
    assert 3.0 <= float(rows["stuck__body"]["wall_s"]) < 6.0 and elapsed < 30

    for job_id in rows:  # every job has its folder and report; no temporary folder is left
        assert (out / job_id / "report.json").is_file()
    assert {p.name for p in (out / "fine__body").iterdir()} >= {"run.rrd", "garment.obj", "report.json"}
    assert not [p for p in out.iterdir() if ".tmp-" in p.name]
    text = (out / "summary.md").read_text()
    assert "| dress | 2 | 2 | 1 | 50% |" in text and "| skirt | 2 | 2 | 0 | 0% |" in text
    assert "| segfault__body | dress | crash | 3 |" in text
    assert "fine__body/thumbnail.png" in text and (out / "fine__body" / "thumbnail.png").is_file()
    assert "fine__body/thumbnail.png" in (out / "summary.html").read_text()
    err = capsys.readouterr().err
    assert "retry" in err and "5 jobs: 1 ok, 4 failed" in err


def test_interrupted_batch_resumes_to_the_same_outputs(tmp_path, ray_address, rrd):
    jobs = {name: {"behaviour": "ok", "delay": 1.5} for name in ("a", "b", "c", "d")}
    clean = tmp_path / "clean"
    assert main(["batch", str(write_batch(tmp_path / "in1", jobs, rrd=rrd)), "-o", str(clean), "--job", JOB,
                 "-q", "--no-thumbnails"]) == 0

    ledger = tmp_path / "ledger.txt"
    manifest = write_batch(tmp_path / "in2", jobs, ledger=ledger, rrd=rrd)
    out = tmp_path / "out"
    proc = cli(str(manifest), "-o", str(out), "--job", JOB, "--workers", "2")  # a local Ray of its own
    deadline = time.monotonic() + 60
    while not finished_ids(out) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "--resume" in err and "Traceback" not in err
    before = finished_ids(out)
    assert 1 <= len(before) < 4
    assert not [p for p in out.iterdir() if ".tmp-" in p.name]  # nothing half-written
    for folder in (p for p in out.iterdir() if p.is_dir()):  # what is there is whole
        assert {"report.json", "garment.obj", "run.rrd"} <= {f.name for f in folder.iterdir()}
    assert len(read_results(out)) == len(before)

    # Resume on this module's Ray instance, joined by address as a cluster would be.
    proc = cli(str(manifest), "-o", str(out), "--job", JOB, "--resume", "--address", ray_address)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert f"resuming: {len(before)} of 4 jobs already finished" in err
    rows = read_results(out)
    assert sorted(r["id"] for r in rows) == ["a__body", "b__body", "c__body", "d__body"]  # each once
    assert {r["status"] for r in rows} == {"ok"}
    assert sorted(finished_ids(out)) == sorted(r["id"] for r in rows)
    for job_id in before:  # finished jobs were not run again
        assert ledger_lines(ledger).count(f"start {job_id.split('__')[0]}") == 1
    assert output_hashes(out) == output_hashes(clean)
