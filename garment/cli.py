"""The `garment` command: a thin layer over the Python API (see garment/commands/).

Everything it does is available from Python: `garment.scene.load_scene`,
`sim.simulator.Simulator.from_scene`, `Simulator.step / run / positions`.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from garment.commands import COMMANDS
from sim.errors import InputError, RunStopped


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="garment", description="B-spline garment simulation toolkit")
    sub = p.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f"garment.commands.{name}").register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)  # plain: no markup, no wrapping
        return 2
    except RunStopped as e:
        print(f"{e.prefix}: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
