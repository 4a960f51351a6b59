"""Visualization: Rerun recordings (`rerun_sink`, read back by `recording`) and PyVista
off-screen renders (`render`). Nothing heavy is imported here: the command line reads
`DEFAULT_VIEWER_URL` while building its parser."""

import os

import sim.threads  # noqa: F401  (thread defaults, before numpy loads OpenBLAS)

# Rerun's Rust side logs to stderr with colour codes, e.g. an ERROR line for every file its
# loader cannot decode, before our own one-line error. Off unless the user asks for it;
# read once, when rerun is first imported (every import of rerun goes through viz).
os.environ.setdefault("RUST_LOG", "off")

# Where a Rerun viewer started with plain `rerun` listens for gRPC streams.
DEFAULT_VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"
