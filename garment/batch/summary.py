"""The dataset's report, OUTDIR/summary.md and OUTDIR/summary.html, written from the
store after every run: success rate per garment type (the manifest's `type` column, else
`all`), time per job, the failure list and a thumbnail per garment. Both files hold the
same tables; images are linked by relative path, so the folder can be moved whole."""

from __future__ import annotations

import html
import statistics
from pathlib import Path

from sim.files import atomic_write

from . import thumbnails
from .manifest import Job

THUMBNAILS_PER_ROW = 4
ERROR_CHARS = 160


def tables(jobs: dict[str, Job], results: dict[str, dict]) -> list[tuple[str, list[str], list[list[str]]]]:
    """(title, header, rows) of every table but the thumbnails."""
    finished = [(jobs[i], r) for i, r in results.items() if i in jobs]
    by_type: dict[str, list] = {}
    for job in jobs.values():
        by_type.setdefault(job.type, [])
    for job, r in finished:
        by_type[job.type].append(r)
    total = {t: sum(j.type == t for j in jobs.values()) for t in by_type}
    rate = [[t, str(total[t]), str(len(rs)), str(sum(r["status"] == "ok" for r in rs)), _percent(rs)]
            for t, rs in sorted(by_type.items())]
    rate.append(["**all**", str(len(jobs)), str(len(finished)), str(sum(r["status"] == "ok" for _, r in finished)),
                 _percent([r for _, r in finished])])

    statuses: dict[str, list[float]] = {}
    for _, r in finished:
        statuses.setdefault(r["status"], []).append(r.get("wall_s") or 0.0)
    times = [[s, str(len(ts)), f"{statistics.median(ts):.1f}", f"{statistics.fmean(ts):.1f}", f"{max(ts):.1f}",
              f"{sum(ts) / 3600:.3g}"] for s, ts in sorted(statuses.items())]
    if len(statuses) > 1:
        every = [t for ts in statuses.values() for t in ts]
        times.append(["**all**", str(len(every)), f"{statistics.median(every):.1f}", f"{statistics.fmean(every):.1f}",
                      f"{max(every):.1f}", f"{sum(every) / 3600:.3g}"])

    failures = [[job.id, job.type, r["status"], str(r["attempts"]), error_line(r.get("error"))]
                for job, r in finished if r["status"] != "ok"]
    return [
        ("Success rate per garment type", ["type", "jobs", "finished", "ok", "success rate"], rate),
        ("Time per job (wall clock, s)", ["status", "jobs", "median", "mean", "max", "job-hours"], times),
        ("Failures", ["job", "type", "status", "attempts", "error"], failures),
    ]


def gallery(outdir: Path, jobs: dict[str, Job], results: dict[str, dict], notes: dict[str, str]) -> list[tuple]:
    """(job id, status, thumbnail path relative to outdir or None, note) per finished job
    with a final mesh (the others are in the failure list)."""
    out = []
    for job in jobs.values():
        r = results.get(job.id)
        if r is None or thumbnails.mesh_of(outdir / job.id) is None:
            continue
        png = outdir / job.id / thumbnails.NAME
        if png.is_file():
            out.append((job.id, r["status"], f"{job.id}/{thumbnails.NAME}", ""))
        else:
            out.append((job.id, r["status"], None, notes.get(job.id) or "thumbnail not rendered"))
    return out


def write(outdir: Path, jobs: dict[str, Job], results: dict[str, dict], notes: dict[str, str]) -> tuple[Path, Path]:
    """Write summary.md and summary.html; notes: job id -> why it has no thumbnail."""
    head = _headline(jobs, results)
    parts = tables(jobs, results)
    pictures = gallery(outdir, jobs, results, notes)
    md, page = outdir / "summary.md", outdir / "summary.html"
    with atomic_write(md) as tmp:
        tmp.write_text(_markdown(outdir, head, parts, pictures))
    with atomic_write(page) as tmp:
        tmp.write_text(_html(outdir, head, parts, pictures))
    return md, page


def _headline(jobs, results) -> str:
    done = sum(i in jobs for i in results)
    ok = sum(r["status"] == "ok" for i, r in results.items() if i in jobs)
    text = f"{jobs_text(len(jobs))}: {done} finished, {ok} ok, {done - ok} failed"
    if done < len(jobs):
        text += f"; {len(jobs) - done} not run yet (run again with --resume)"
    return text


def _markdown(outdir, head, parts, pictures) -> str:
    lines = [f"# garment batch: {outdir.name}", "", head + ".", ""]
    for title, header, rows in parts:
        lines += [f"## {title}", ""]
        if not rows:
            lines += ["None.", ""]
            continue
        lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in rows]
        lines.append("")
    lines += ["## Garments", ""]
    if not pictures:
        lines += ["None with a final mesh yet.", ""]
    for k in range(0, len(pictures), THUMBNAILS_PER_ROW):
        row = pictures[k:k + THUMBNAILS_PER_ROW]
        lines.append("| " + " | ".join(f"![{i}]({p})" if p else f"({_md_cell(n)})" for i, _, p, n in row) + " |")
        if k == 0:
            lines.append("|" + "---|" * len(row))
        lines.append("| " + " | ".join(f"{_md_cell(i)}: {s}" for i, s, _, _ in row) + " |")
    lines.append("")
    return "\n".join(lines)


def _html(outdir, head, parts, pictures) -> str:
    e = html.escape
    out = ["<!doctype html>", "<meta charset='utf-8'>", f"<title>garment batch: {e(outdir.name)}</title>",
           "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
           "td,th{border:1px solid #ccc;padding:.25em .6em;text-align:left;vertical-align:top}"
           "figure{display:inline-block;margin:.5em;text-align:center;font-size:small}"
           ".fail{color:#b35000}</style>",
           f"<h1>garment batch: {e(outdir.name)}</h1>", f"<p>{e(head)}.</p>"]
    for title, header, rows in parts:
        out.append(f"<h2>{e(title)}</h2>")
        if not rows:
            out.append("<p>None.</p>")
            continue
        out.append("<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in header) + "</tr>")
        out += ["<tr>" + "".join(f"<td>{e(c.strip('*'))}</td>" for c in row) + "</tr>" for row in rows]
        out.append("</table>")
    out.append("<h2>Garments</h2>")
    for job_id, status, png, note in pictures:
        picture = (f"<a href='{e(job_id)}/'><img src='{e(png)}' width='{thumbnails.SIZE[0]}' alt='{e(job_id)}'></a>"
                   if png else f"<div style='width:{thumbnails.SIZE[0]}px'>({e(note)})</div>")
        css = "" if status == "ok" else " class='fail'"
        out.append(f"<figure>{picture}<figcaption{css}>{e(job_id)}: {e(status)}</figcaption></figure>")
    return "\n".join(out) + "\n"


def jobs_text(n: int) -> str:
    return f"{n} job" if n == 1 else f"{n} jobs"


def _percent(rs: list[dict]) -> str:
    return f"{100 * sum(r['status'] == 'ok' for r in rs) / len(rs):.0f}%" if rs else "-"


def error_line(text: str | None) -> str:
    """One line of an error: the first, or a traceback's last (the exception itself)."""
    lines = [s for s in (text or "").strip().splitlines() if s.strip()]
    line = (lines[-1] if lines[0].startswith("Traceback") else lines[0]).strip() if lines else ""
    return line if len(line) <= ERROR_CHARS else line[:ERROR_CHARS - 3] + "..."


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")
