"""Synthetic cloth meshes and their frames for the sink, recording and Rerun tests."""

from __future__ import annotations

import numpy as np

from sim.sinks import MeshTopology


def grid_topology(name: str, nx: int = 5, ny: int = 4, size: float = 0.5) -> MeshTopology:
    """nx x ny vertex grid of side `size` m, two triangles per cell."""
    u, v = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny), indexing="xy")
    uv = np.column_stack([u.ravel(), v.ravel()])
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
    a = (j * nx + i).ravel()
    faces = np.concatenate([np.column_stack([a, a + 1, a + nx + 1]), np.column_stack([a, a + nx + 1, a + nx])])
    return MeshTopology(name, faces.astype(np.int32), uv, uv * size)


MESHES = [grid_topology("front"), grid_topology("back", 4, 3)]


def positions(m: MeshTopology, k: int) -> np.ndarray:
    """Sinusoidal wave (V, 3) in m at frame k; float64 with non-representable digits."""
    x, y = m.rest.T
    z = 0.05 * np.sin(2 * np.pi * (x + 0.1 * k) + len(m.name)) + 1e-3 * k * y
    return np.column_stack([x + 0.01 * k, y, z]) / 3.0
