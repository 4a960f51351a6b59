"""Errors worded for the user. The command line prints them without a traceback:
InputError (a bad input file or value) exits with 2, SimulationError (a run that could
not go on) with 3, Interrupted (SIGINT/SIGTERM, state saved) with 130."""


class InputError(ValueError):
    """A problem with an input file or value, worded for the user (name the file and key)."""


class RunStopped(Exception):
    """A run that ended early on purpose; `exit_code` is the process status to use."""

    exit_code = 1
    prefix = "error"


class SimulationError(RunStopped):
    """A step failed even after splitting it down to the floor; the message names the
    frame, the likely cause and where the checkpoint is."""

    exit_code = 3


class Interrupted(RunStopped):
    """SIGINT/SIGTERM: the run stopped after its last completed frame, outputs are valid
    and a checkpoint was written (the message says how to resume)."""

    exit_code = 130
    prefix = "interrupted"


def printable(text: object, limit: int = 2000) -> str:
    """`text` safe for a terminal: control characters (escape sequences, NUL, bell) and
    other unprintable ones written as Python escapes (\\x1b), at most `limit` characters."""
    s = str(text)
    s = "".join(c if c.isprintable() or c in "\n\t" else repr(c)[1:-1] for c in s)
    if len(s) > limit:
        s = f"{s[:limit]}... ({len(s) - limit} more characters)"
    return s
