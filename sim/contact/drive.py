"""Prescribed motion of animated bodies within a time step.

Body vertices are Dirichlet data: by the end of step n+1 they must sit at their frame
positions. Placing them there at once could push a body through cloth, so the body moves
along the Newton iterations instead (IPC's treatment of moving boundary conditions): each
iteration's step carries the body's remaining motion dB, the cloth direction includes the
first-order push of that motion (-H_cc^-1 H_cb dB), and CCD bounds the joint motion. While
the body is still on its way a step is taken as far as CCD allows, without the energy
test (prescribed motion need not lower the cloth's energy); once the body has arrived the
ordinary projected Newton iterations finish the step. Once a drive iteration's CCD fraction
falls below newton.BLOCKED (one pinched contact holds the whole body's motion to a sliver),
every body vertex moves on its own as far as the cloth around it allows (advance_each, half
of its clearance) and ordinary iterations let the cloth give way; the parts held back stay
behind their targets and catch up in later steps. A body is never driven through the cloth.
"""

from __future__ import annotations

import numpy as np

from .mesh import ContactMesh


class BodyDrive:
    """Moves the obstacles of `mesh` (in the order of `obstacles`) toward their targets."""

    def __init__(self, mesh: ContactMesh, obstacles):
        self.mesh = mesh
        self.obstacles = list(obstacles)
        sizes = [o.vertices.shape[0] for o in self.obstacles]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        self.target = mesh.obstacle_vertices.copy()

    @property
    def animated(self) -> bool:
        return any(o.animated for o in self.obstacles)

    def set_time(self, t: float) -> None:
        """Targets: every body's positions at time t."""
        self.target = np.concatenate([o.at(t) for o in self.obstacles]) if self.obstacles else self.target

    def remaining(self) -> np.ndarray:
        """(Vo, 3) motion still to make."""
        return self.target - self.mesh.obstacle_vertices

    @property
    def pending(self) -> bool:
        return bool(np.any(self.target != self.mesh.obstacle_vertices))

    def lag(self) -> float:
        """Largest distance (m) of a body vertex from its target."""
        r = self.remaining()
        return float(np.sqrt((r * r).sum(axis=1).max(initial=0.0)))

    def advance(self, alpha: float) -> None:
        """Move the fraction alpha of the remaining way (exactly onto the target at 1)."""
        if alpha >= 1.0:
            self.mesh.move_obstacles(self.target)
        elif alpha > 0.0:
            self.mesh.move_obstacles(self.mesh.obstacle_vertices + alpha * self.remaining())

    def advance_each(self, limit: np.ndarray) -> None:
        """Move every obstacle vertex along its remaining way by at most limit (Vo,) m."""
        r = self.remaining()
        length = np.sqrt((r * r).sum(axis=1))
        f = np.minimum(1.0, limit / np.maximum(length, 1e-300))
        B = self.mesh.obstacle_vertices + f[:, None] * r
        self.mesh.move_obstacles(np.where((f >= 1.0)[:, None], self.target, B))

    def positions(self) -> dict[str, np.ndarray]:
        """Current vertices of each obstacle, by name."""
        B = self.mesh.obstacle_vertices
        return {o.name: B[a:b] for o, a, b in zip(self.obstacles, self.offsets[:-1], self.offsets[1:])}
