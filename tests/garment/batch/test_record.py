"""The parts a batch's results pass through, without Ray: the job's child process, the
SQLite record, results.csv, the summary and the progress line."""

from __future__ import annotations

import io
import json

import pytest
from rich.console import Console

from garment.batch import child, results, store, summary
from garment.batch.manifest import Job
from garment.batch.progress import WIDTH, BatchProgress
from sim.errors import InputError

from .cases import JOB, read_results


def test_the_record_keeps_one_result_per_job_and_refuses_changed_jobs(tmp_path):
    jobs = [Job("a", tmp_path / "a.json", tmp_path / "b.obj"), Job("b", tmp_path / "b.json", tmp_path / "b.obj")]
    s = store.Store(tmp_path)
    s.add_jobs(jobs)
    assert s.record({"id": "a", "status": "ok", "attempts": 1, "wall_s": 1.0, "report": {"dofs": 3}})
    assert not s.record({"id": "a", "status": "crash", "attempts": 3})  # ends once
    s.close()
    s = store.Store(tmp_path)  # what --resume opens
    s.add_jobs(jobs[:1])
    assert list(s.jobs()) == ["a", "b"] and s.results()["a"]["status"] == "ok"
    with pytest.raises(InputError, match="job a was recorded with other inputs"):
        s.add_jobs([Job("a", tmp_path / "other.json", tmp_path / "b.obj")])
    s.close()


def test_input_error_without_a_category_is_input(tmp_path, monkeypatch):
    (tmp_path / "p.json").write_text(json.dumps({"behaviour": "bad_input", "category": None}))
    monkeypatch.chdir(tmp_path)
    spec = {"target": JOB, "job": Job("p", tmp_path / "p.json", tmp_path / "p.json").spec()}
    r = child.run(spec)
    assert r["status"] == "input" and "waistband" in r["error"]
    spec["target"] = "tests.garment.batch.jobs:missing_function"
    r = child.run(spec)
    assert r["status"] == "crash" and r["exception"] and "missing_function" in r["error"]


def test_results_and_summary_of_a_partly_finished_batch(tmp_path):
    jobs = {j.id: j for j in [Job("a", tmp_path / "a.json", tmp_path / "b.obj", "dress", {"E": 1}),
                              Job("b", tmp_path / "b.json", tmp_path / "b.obj", "skirt"),
                              Job("c", tmp_path / "c.json", tmp_path / "b.obj", "skirt")]}
    done = {"a": {"id": "a", "status": "ok", "attempts": 1, "wall_s": 2.0,
                  "report": {"status": "ok", "dofs": 9, "extra": "x", "nested": {"no": 1}}},
            "b": {"id": "b", "status": "crash", "attempts": 3, "wall_s": 4.0, "report": None,
                  "error": "Traceback (most recent call last):\n  ...\nValueError: bad seam"}}
    results.write(tmp_path, jobs, done)
    text = (tmp_path / "results.csv").read_text().splitlines()
    table = read_results(tmp_path)
    assert text[0] == ("id,pattern,body,type,E,status,attempts,wall_s,seam_gap_max_mm,crossings,dofs,seconds,"
                       "settle_time_s,extra,node,error")
    assert [r["id"] for r in table] == ["a", "b"]  # c has not run
    assert table[1]["error"].endswith("ValueError: bad seam") and table[0]["E"] == "1"
    md, _ = summary.write(tmp_path, jobs, done, {})
    body = md.read_text()
    assert "3 jobs: 2 finished, 1 ok, 1 failed; 1 not run yet (run again with --resume)" in body
    assert "| dress | 1 | 1 | 1 | 100% |" in body and "| skirt | 2 | 1 | 0 | 0% |" in body
    assert "| b | skirt | crash | 3 | ValueError: bad seam |" in body
    assert not list(tmp_path.glob(".*tmp"))


def test_the_live_line_fits_80_columns():
    console = Console(file=io.StringIO(), width=200, record=True)
    shown = BatchProgress(1000, False, console)
    shown.bar.update(shown.task, completed=999, running=16, failed=100)
    console.print(shown.bar.make_tasks_table(shown.bar.tasks))
    lines = console.export_text().splitlines()
    assert "999/1000 done" in lines[0] and "16 running, 100 failed" in lines[0] and "ETA" in lines[0]
    assert max(len(line.rstrip()) for line in lines) <= WIDTH


def test_thumbnails_stand_up_in_the_body_files_axes(tmp_path):
    from garment.batch import thumbnails

    assert thumbnails.up_axis(tmp_path) == (0.0, 0.0, 1.0)  # no report: the simulator's Z-up
    (tmp_path / "report.json").write_text(json.dumps({"status": "ok", "body_frame": "cm, Y-up"}))
    assert thumbnails.up_axis(tmp_path) == (0.0, 1.0, 0.0)
