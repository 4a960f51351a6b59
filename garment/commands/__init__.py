"""Subcommands of `garment`, one module each: `register(subparsers)` adds the parser and
sets `func(args) -> exit status`. To add a command, add a module and list it in COMMANDS."""

COMMANDS = ("simulate", "demo", "bench", "inspect", "conform")
