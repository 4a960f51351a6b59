"""Manifests, job ids, the record and the reports, without Ray: bad input exits 2 before
Ray starts, so these run in a blink."""

from __future__ import annotations

import json

import pytest

from garment.batch import child, manifest, results, store, summary
from garment.batch.manifest import Job
from garment.cli import main
from sim.errors import InputError

from .cases import JOB, read_results, write_batch


def test_csv_manifest_resolves_paths_types_and_overrides(tmp_path):
    (tmp_path / "corpus" / "dress_01").mkdir(parents=True)
    pattern = tmp_path / "corpus" / "dress_01" / "dress_01_specification.json"
    pattern.write_text("{}")
    (tmp_path / "bodies").mkdir()
    (tmp_path / "bodies" / "mean all.obj").write_text("")
    m = tmp_path / "jobs.csv"
    m.write_text("pattern,body,type,material.E_st,friction,label\n"
                 "corpus/dress_01/dress_01_specification.json,bodies/mean all.obj,dress,2.5e5,0.3,soft\n"
                 "\n"
                 "corpus/dress_01/dress_01_specification.json,bodies/mean all.obj,,,true,\n")
    a, b = manifest.read_manifest(m)
    assert a.pattern == pattern and a.body == tmp_path / "bodies" / "mean all.obj"
    assert a.id == "dress_01__mean_all" and b.id == "dress_01__mean_all-2"  # readable, repeats numbered
    assert a.type == "dress" and b.type == "all"
    assert a.overrides == {"material.E_st": 2.5e5, "friction": 0.3, "label": "soft"}
    assert b.overrides == {"friction": True}  # empty cells: not overridden
    assert [j.id for j in manifest.read_manifest(m)] == [a.id, b.id]  # stable


def test_toml_manifest_and_the_glob_form(tmp_path, monkeypatch):
    for name in ("a", "b"):
        (tmp_path / f"{name}_specification.json").write_text("{}")
    (tmp_path / "body.obj").write_text("")
    m = tmp_path / "jobs.toml"
    m.write_text('[[job]]\npattern = "a_specification.json"\nbody = "body.obj"\ntype = "shirt"\n'
                 '[job.material]\nE_st = 1e5\n')
    (job,) = manifest.read_manifest(m)
    assert (job.id, job.type, job.overrides) == ("a__body", "shirt", {"material": {"E_st": 1e5}})
    monkeypatch.chdir(tmp_path)
    jobs = manifest.glob_jobs(["*_specification.json"], ["body.obj"])
    assert [j.id for j in jobs] == ["a__body", "b__body"] and jobs[0].body == tmp_path / "body.obj"
    with pytest.raises(InputError, match="matches no file"):
        manifest.glob_jobs(["nothing/*.json"], ["body.obj"])


@pytest.mark.parametrize("text, message", [
    ("pattern,bdy\np.json,body.obj\n", "missing column 'body' (the header has: pattern, bdy"),
    ("pattern,body\nmissing.json,body.obj\n", "manifest.csv:2: pattern 'missing.json': no such file"),
    ("pattern,body\np.json,nobody.obj\n", "manifest.csv:2: body 'nobody.obj': no such file"),
    ("pattern,body\np.json,body.obj,extra\n", "manifest.csv:2: 3 values for 2 columns"),
    ("pattern,body,body\np.json,body.obj,body.obj\n", "column 'body' appears more than once"),
    ("pattern,body\n", "no jobs"),
    ("", "empty"),
])
def test_bad_manifest_exits_2_before_anything_runs(tmp_path, capsys, text, message):
    (tmp_path / "p.json").write_text("{}")
    (tmp_path / "body.obj").write_text("")
    m = tmp_path / "manifest.csv"
    m.write_text(text)
    out = tmp_path / "out"
    assert main(["batch", str(m), "-o", str(out), "--job", JOB]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("args, message", [
    (["MISSING"], "no such file"),
    (["--patterns", "*.json"], "--patterns needs --body"),
    (["--body", "body.obj"], "--body goes with --patterns"),
    ([], "nothing to run"),
    (["MANIFEST", "--job", "no_such_module:run"], "no module no_such_module"),
    (["MANIFEST", "--job", "nocolon"], "expected module:function"),
    (["MANIFEST", "--memory-per-job", "lots"], "--memory-per-job: not an amount of memory"),
    (["MANIFEST", "--timeout", "0"], "--timeout: must be > 0"),
    (["MANIFEST", "--threads-per-job", "0"], "--threads-per-job: must be in [1, 1024], got 0"),
    (["MANIFEST", "--address", "127.0.0.1:1"], "--address 127.0.0.1:1: nothing answers there"),
])
def test_bad_command_line_exits_2(tmp_path, capsys, monkeypatch, args, message):
    manifest_path = write_batch(tmp_path, {"ok": {"behaviour": "ok"}})
    monkeypatch.chdir(tmp_path)
    args = [str(manifest_path) if a == "MANIFEST" else str(tmp_path / "missing.csv") if a == "MISSING" else a
            for a in args]
    if "--job" not in args:
        args += ["--job", JOB]
    assert main(["batch", *args, "-o", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_folder_holding_a_batch_needs_resume(tmp_path, capsys):
    manifest_path = write_batch(tmp_path, {"ok": {"behaviour": "ok"}})
    out = tmp_path / "out"
    out.mkdir()
    store.Store(out).close()
    assert main(["batch", str(manifest_path), "-o", str(out), "--job", JOB]) == 2
    err = capsys.readouterr().err
    assert "already holds a batch" in err and "--resume" in err


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
