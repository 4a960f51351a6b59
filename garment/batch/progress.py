"""What `garment batch` shows while it runs, on the rich console it is given (the
command's stderr, garment.commands.console.err): one live line (done / running / failed
and an ETA, at most 80 columns) and one line per finished or retried job above it."""

from __future__ import annotations

from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from .manifest import Job
from .summary import error_line

WIDTH = 80


class BatchProgress:
    """Context manager: `state(running, waiting)`, `finished(result)`, `retry(...)`."""

    def __init__(self, total: int, quiet: bool, console):
        self.quiet = quiet
        self.failed = 0
        # bar 20 + "1000/1000 done" + "16 running, 100 failed" + "ETA 0:10:00" fit in 80 columns
        self.bar = Progress(
            TextColumn("[bold]batch"), BarColumn(bar_width=20), TextColumn("{task.completed}/{task.total} done"),
            TextColumn("{task.fields[running]} running, {task.fields[failed]} failed"), TextColumn("ETA"),
            TimeRemainingColumn(), console=console, disable=quiet, transient=False)
        self.task = self.bar.add_task("batch", total=total, running=0, failed=0)

    def __enter__(self):
        self.bar.__enter__()
        return self

    def __exit__(self, *exc):
        self.bar.update(self.task, running=0)
        return self.bar.__exit__(*exc)

    def state(self, running: int, waiting: int) -> None:
        self.bar.update(self.task, running=running)

    def finished(self, result: dict) -> None:
        ok = result["status"] == "ok"
        self.failed += not ok
        self.bar.update(self.task, advance=1, failed=self.failed)
        if self.quiet:
            return
        what = f"{result.get('wall_s') or 0:.1f} s"
        if result.get("attempts", 1) > 1:
            what += f", {result['attempts']} attempts"
        if result.get("error"):
            what += f": {error_line(result['error'])}"
        self._line(f"{result['status']:<12} {result['id']}  {what}", ok)

    def retry(self, job: Job, attempt: int, error: str) -> None:
        if not self.quiet:
            self._line(f"{'retry':<12} {job.id}  attempt {attempt}: {error_line(error)}", False)

    def note(self, text: str) -> None:
        if not self.quiet:
            self.bar.console.print(escape(text), highlight=False, soft_wrap=True)

    def _line(self, text: str, ok: bool) -> None:
        if len(text) > WIDTH:
            text = text[: WIDTH - 3] + "..."
        self.bar.console.print(escape(text), style=None if ok else "yellow", highlight=False, soft_wrap=True)
