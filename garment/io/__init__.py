"""Mesh input/output: per-frame export of simulated cloth pieces."""

from .export import MeshExportSink, read_frame

__all__ = ["MeshExportSink", "read_frame"]
