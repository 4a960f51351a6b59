"""SIGTERM handled like Ctrl-C for commands that have nothing to save: the stack unwinds
(temporary files are removed, child processes stopped) and `garment.cli.main` exits 130."""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager


@contextmanager
def terminate_raises_interrupt():
    """While active, SIGTERM raises KeyboardInterrupt in the main thread, as SIGINT does."""
    if threading.current_thread() is not threading.main_thread():  # signal() works only there
        yield
        return

    def interrupt(_signum, _frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
