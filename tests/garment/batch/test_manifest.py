"""Manifests, job ids and the command line's bad input: exit 2 before Ray starts and before
the output folder is made."""

from __future__ import annotations


import pytest

from garment.batch import manifest, store
from garment.cli import main
from sim.errors import InputError

from .cases import JOB, write_batch


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
