"""Garment data model, file I/O and the `garment` command."""

from . import _threads  # noqa: F401  (must run before numpy loads OpenBLAS)
