"""The jobs of a batch: read from a manifest (CSV or TOML) or built from a glob of
patterns times a list of bodies, every input checked before anything runs.

CSV: a header with `pattern` and `body`, optionally `type` (the garment type the summary
groups by), and any other column is an override handed to the job as
`overrides[column] = value` (empty cell: not overridden; numbers and true/false are
converted). TOML: `[[job]]` tables with the same keys; other keys (tables too) are the
overrides. Relative paths resolve against the manifest's folder.

A job's id names its output folder: `<pattern stem>__<body stem>` (a GarmentCode
`_specification` suffix dropped), characters outside [A-Za-z0-9._-] replaced by `_`, and
`-2`, `-3`, ... appended to repeats in manifest order, so the same manifest always gives
the same ids.
"""

from __future__ import annotations

import csv
import glob
import io
import json
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from sim.errors import InputError, printable
from sim.files import input_file

REQUIRED = ("pattern", "body")
MAX_MANIFEST_BYTES = 64 * 2**20  # a million jobs' worth; larger is not a manifest


@dataclass(frozen=True)
class Job:
    """One garment on one body. pattern, body: absolute paths; type: the summary's group;
    overrides: column -> value, passed to the job as they are."""

    id: str
    pattern: Path
    body: Path
    type: str = "all"
    overrides: dict = field(default_factory=dict)

    def spec(self) -> dict:
        """What the job is, as JSON-able data (stored with its result, compared on resume)."""
        return {"id": self.id, "pattern": str(self.pattern), "body": str(self.body), "type": self.type,
                "overrides": self.overrides}

    @classmethod
    def from_spec(cls, d: dict) -> Job:
        return cls(d["id"], Path(d["pattern"]), Path(d["body"]), d.get("type", "all"), d.get("overrides", {}))


def read_manifest(path: str | Path) -> list[Job]:
    """Jobs of a `.csv` or `.toml` manifest; InputError naming the file (and line) otherwise."""
    path = input_file(path, "manifest")
    if path.stat().st_size > MAX_MANIFEST_BYTES:
        raise InputError(f"{path}: larger than {MAX_MANIFEST_BYTES >> 20} MB, not a manifest")
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not UTF-8 text (byte {e.start}); a manifest is a CSV or TOML file") from None
    rows = _toml_rows(path, text) if path.suffix.lower() == ".toml" else _csv_rows(path, text)
    if not rows:
        raise InputError(f"{path}: no jobs (a header line and at least one row are needed)")
    return _jobs(path.parent, rows)


def glob_jobs(patterns: list[str], bodies: list[str], type_: str = "all") -> list[Job]:
    """Every pattern matching the globs `patterns` on every body, in sorted order."""
    files = sorted({Path(p).absolute() for g in patterns for p in glob.glob(g, recursive=True)})
    if not files:
        raise InputError(f"--patterns {' '.join(map(repr, patterns))}: matches no file")
    rows = [(f"--patterns {p.name}", {"pattern": str(p), "body": b, "type": type_}) for p in files for b in bodies]
    return _jobs(Path.cwd(), rows)


def _csv_rows(path: Path, text: str) -> list[tuple[str, dict]]:
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader, None)
        if header is None:
            raise InputError(f"{path}: empty; a manifest starts with a header line: pattern,body[,type,...]")
        header = [h.strip() for h in header]
        _check_header(path, header)
        rows = []
        for values in reader:
            line = f"{path}:{reader.line_num}"
            if not any(v.strip() for v in values):
                continue  # blank lines
            if len(values) != len(header):
                raise InputError(f"{line}: {len(values)} values for {len(header)} columns ({', '.join(header)})")
            rows.append((line, {h: _value(v) for h, v in zip(header, values) if v.strip()}))
    except csv.Error as e:
        raise InputError(f"{path}:{reader.line_num}: not a readable CSV line ({e})") from None
    return rows


def _toml_rows(path: Path, text: str) -> list[tuple[str, dict]]:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path}: not valid TOML ({e})") from None
    jobs = data.get("job")
    if not isinstance(jobs, list) or not all(isinstance(j, dict) for j in jobs):
        raise InputError(f"{path}: expected [[job]] tables with pattern and body")
    rows = []
    for k, j in enumerate(jobs):
        missing = [c for c in REQUIRED if c not in j]
        if missing:
            raise InputError(f"{path}: job[{k}]: missing {' and '.join(missing)}")
        rows.append((f"{path}: job[{k}]", j))
    return rows


def _check_header(path: Path, header: list[str]) -> None:
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputError(f"{path}: missing column {' and '.join(map(repr, missing))} "
                         f"(the header has: {printable(', '.join(header), 200)}; required: {', '.join(REQUIRED)})")
    repeated = sorted({h for h in header if header.count(h) > 1})
    if repeated:
        raise InputError(f"{path}: column {', '.join(map(repr, repeated))} appears more than once")
    if "" in header:
        raise InputError(f"{path}: column {header.index('') + 1} of the header has no name")


def _value(text: str):
    """A CSV cell as the number or boolean it spells, else the string."""
    s = text.strip()
    if s.lower() in ("true", "false"):
        return s.lower() == "true"
    for kind in (int, float):
        try:
            return kind(s)
        except ValueError:
            pass
    return s


def _jobs(base: Path, rows: list[tuple[str, dict]]) -> list[Job]:
    jobs, used = [], set()
    for line, row in rows:
        for c in REQUIRED:
            if not isinstance(row.get(c), str) or not row[c]:
                raise InputError(f"{line}: {c} must be a file name, got {printable(row.get(c), 80)!r}")
        pattern, body = (_input(line, c, base, row[c]) for c in REQUIRED)
        type_ = str(row.get("type", "all")) or "all"
        overrides = {k: v for k, v in row.items() if k not in (*REQUIRED, "type")}
        try:
            json.dumps(overrides, allow_nan=False)
        except (TypeError, ValueError):  # TOML dates, NaN: not something to hand on
            raise InputError(f"{line}: overrides must be numbers, strings, booleans, lists or tables") from None
        stem = _readable(f"{_stem(pattern)}__{_stem(body)}")
        job_id, n = stem, 1
        while job_id in used:
            n += 1
            job_id = f"{stem}-{n}"
        used.add(job_id)
        jobs.append(Job(job_id, pattern, body, type_, overrides))
    return jobs


def _input(line: str, column: str, base: Path, name: str) -> Path:
    p = Path(name).expanduser()
    p = p if p.is_absolute() else base / p
    if not p.exists():
        raise InputError(f"{line}: {column} {printable(name, 200)!r}: no such file ({p})")
    if column == "pattern" and p.is_dir():
        raise InputError(f"{line}: pattern {printable(name, 200)!r}: is a folder, not a pattern file")
    return p.absolute()  # a body may be a folder of OBJ frames (a motion)


def _stem(p: Path) -> str:
    stem = p.stem if p.is_file() else p.name
    return stem.removesuffix("_specification") or stem


def _readable(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]", "_", text).lstrip(".")[:120] or "job"
