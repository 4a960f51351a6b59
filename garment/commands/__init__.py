"""Subcommands of `garment`, one module each: `register(subparsers)` adds the parser and
sets `func(args) -> exit status`. To add a command, add a module and list it in COMMANDS.

Every command module is imported to build the parser, so each imports the simulator,
Rerun and PyVista inside the function that runs it: `garment --help` stays instant."""

COMMANDS = ("simulate", "dress", "demo", "bench", "inspect", "view", "conform", "batch")
