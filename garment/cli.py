"""The `garment` command: a thin layer over the Python API (see garment/commands/).

Everything it does is available from Python: `garment.scene.load_scene`,
`sim.simulator.Simulator.from_scene`, `Simulator.step / run / positions`.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading

from garment.commands import COMMANDS
from sim.errors import InputError, RunStopped, printable


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="garment", description="B-spline garment simulation toolkit")
    sub = p.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f"garment.commands.{name}").register(sub)
    return p


def _terminate(signum, _frame):
    """SIGTERM (and SIGHUP) stop a command as Ctrl-C does, so every `finally` runs and no
    temporary file stays behind; `garment simulate` handles them itself while it runs."""
    raise KeyboardInterrupt(signal.Signals(signum).name)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {s: signal.signal(s, _terminate) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        return args.func(args)
    except InputError as e:
        print(f"error: {printable(e)}", file=sys.stderr)  # plain: no markup, no wrapping
        return 2
    except RunStopped as e:
        print(f"{e.prefix}: {printable(e)}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


if __name__ == "__main__":
    sys.exit(main())
