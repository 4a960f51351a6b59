"""Visualization: Rerun recordings (`rerun_sink`, read back by `recording`) and PyVista
off-screen renders (`render`). Nothing heavy is imported here: the command line reads
`DEFAULT_VIEWER_URL` while building its parser."""

import sim.threads  # noqa: F401  (thread defaults, before numpy loads OpenBLAS)

# Where a Rerun viewer started with plain `rerun` listens for gRPC streams.
DEFAULT_VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"
