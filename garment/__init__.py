"""Garment data model, file I/O and the `garment` command."""

import sim.threads  # noqa: F401  (must run before numpy loads OpenBLAS)
