"""Console output shared by the commands: progress bars and tables on stderr/stdout."""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table
from rich.text import Text

from sim.errors import printable

err = Console(stderr=True)


def progress(quiet: bool) -> Progress:
    """A progress bar with ETA and a free-text `status` field for per-step statistics."""
    return Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(), TimeRemainingColumn(), TextColumn("{task.fields[status]}"),
        console=err, disable=quiet, transient=False,
    )


def print_table(title: str, columns, rows: list[dict]) -> None:
    """Rows of dicts as a table on stdout; floats to 4 digits, `*_fraction` as percent.
    Cells and title are plain text: names from input files (a panel named `[/x]` or
    holding NUL bytes) are shown escaped, never read as markup or sent to the terminal."""
    table = Table(title=Text(printable(title)))
    cols = [c for c in columns if any(c in r for r in rows)]
    for c in cols:
        table.add_column(c, justify="right")
    for r in rows:
        table.add_row(*[Text(printable(_fmt(c, r.get(c, "")))) for c in cols])
    out = Console()
    if not out.is_terminal:
        out = Console(width=240)  # keep full column names when piped
    out.print(table)


def _fmt(column: str, v) -> str:
    if isinstance(v, float):
        return f"{v:.0%}" if column.endswith("fraction") else f"{v:.4g}"
    return str(v)
