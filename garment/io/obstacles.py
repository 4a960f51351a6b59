"""Obstacle geometry from scene specs: triangle meshes, meshed spheres, planes, animated
bodies (garment/io/bodies.py) and bodies posed by a skeleton (garment/io/rigged.py)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arms import find_arms, raised, turn
from .bodies import BodySequence, check_extent, check_up_axis, load_sequence, to_scene_frame
from .meshfile import read_mesh


@dataclass
class ObstacleGeometry:
    """A triangle mesh: vertices (V, 3) in m (at time 0), faces (F, 3) int32, and for an
    animated body its per-frame sequence."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    sequence: BodySequence | None = None
    spin: object | None = None  # garment.scene.Spin
    delay: float = 0.0  # s: the motion starts this late (pre-roll), holding the first pose
    # Dressing: the body starts `inset` m inside its surface (along vertex normals) and
    # grows to full size between times grow[0] and grow[1], pushing the cloth out through
    # contact. Seams then close around a slimmer body (their straight pulls clear it), and
    # a garment fitted to a drape may dip a millimetre into the body it was draped on.
    inset: float = 0.0
    # And its arms start raised by this angle (degrees, garment/io/arms.py), lowered
    # over the same time: a skirt laid round the hips is sewn clear of the hands.
    raise_arms: float = 0.0
    grow: tuple[float, float] = (0.0, 0.0)
    _offsets: np.ndarray | None = None
    arms: list | None = None  # garment/io/arms.find_arms of the vertices; found when first needed if None

    @property
    def animated(self) -> bool:
        return self.sequence is not None or self.spin is not None or self.inset > 0.0 or self.raise_arms > 0.0

    def at(self, t: float) -> np.ndarray:
        """(V, 3) vertex positions at time t."""
        t0, t1 = self.grow
        V = self._pose(t - self.delay)
        if t >= t1 or (self.inset <= 0.0 and self.raise_arms <= 0.0):
            return V
        ahead = min((t1 - t) / (t1 - t0), 1.0)  # of the way still to grow
        if self.inset > 0.0:
            V = V - ahead * self._inset_offsets()
        if self.raise_arms > 0.0:
            if self.arms is None:
                self.arms = find_arms(self.vertices, self.faces)
            V = raised(V, self.arms, ahead * np.radians(self.raise_arms))
        return V

    def _pose(self, t: float) -> np.ndarray:
        if self.sequence is not None:
            return self.sequence.at(t)
        if self.spin is not None:
            return _rotate(self.vertices, self.spin.axis, self.spin.center, self.spin.angle(t))
        return self.vertices

    def _inset_offsets(self) -> np.ndarray:
        """(V, 3) inward offsets of the first pose: `inset` along the vertex normals, at most
        0.4 x the local thickness (fingers and wrists would turn inside out)."""
        if self._offsets is None:
            import trimesh
            from scipy.spatial import cKDTree

            V = self.vertices
            n = np.asarray(trimesh.Trimesh(V, self.faces, process=False).vertex_normals)
            # Thickness: distance to the nearest vertex facing the other way (the far side).
            k = min(64, len(V))
            dist, idx = cKDTree(V).query(V, k=k, distance_upper_bound=2.5 * self.inset)
            hit = np.isfinite(dist)
            opposite = hit & (np.einsum("vd,vkd->vk", n, n[np.where(hit, idx, 0)]) < -0.5)
            thickness = np.where(opposite, dist, np.inf).min(axis=1)
            self._offsets = np.minimum(self.inset, 0.4 * thickness)[:, None] * n
        return self._offsets


def _rotate(V: np.ndarray, axis, center, angle: float) -> np.ndarray:
    """V rotated by `angle` about the unit `axis` through `center` (Rodrigues)."""
    c = np.asarray(center, float)
    return c + turn(V - c, np.asarray(axis, float), angle)


def load_obstacle(spec, time=None) -> ObstacleGeometry:
    """Geometry of a garment.scene.ObstacleSpec; `time` (the scene's TimeSpec) tells a
    rigged body how to sample its motion (garment/io/rigged.py)."""
    geometry = _geometry(spec, time)
    geometry.spin = getattr(spec, "spin", None)
    return geometry


def _geometry(spec, time=None) -> ObstacleGeometry:
    import trimesh

    if spec.kind == "plane":
        return ObstacleGeometry(spec.name, *plane_quad(spec.point, spec.normal, spec.size))
    if spec.kind == "sphere":
        m = trimesh.creation.icosphere(subdivisions=spec.subdivisions, radius=spec.radius)
        V = np.asarray(m.vertices) + np.asarray(spec.center, float)
        return ObstacleGeometry(spec.name, V, np.asarray(m.faces, np.int32))
    if spec.kind in ("skin", "smpl"):
        from .rigged import rigged_sequence

        seq = rigged_sequence(spec, time)
        return ObstacleGeometry(spec.name, seq.frames[0].copy(), seq.faces, seq)
    if spec.kind == "animation":
        seq = load_sequence(spec.animation, spec.scale, spec.up or "z", spec.translate, spec.fps)
        if spec.up is None:
            check_up_axis(spec.animation, seq.frames[0])
        return ObstacleGeometry(spec.name, seq.frames[0].copy(), seq.faces, seq)
    V, F = read_mesh(spec.mesh, "obstacle mesh")
    V = to_scene_frame(V, spec.scale, spec.up or "z", spec.translate)
    check_extent(spec.mesh, V, spec.scale, "the obstacle")
    return ObstacleGeometry(spec.name, V, F.astype(np.int32))


def plane_quad(point, normal, size: float) -> tuple[np.ndarray, np.ndarray]:
    """A size x size square of two triangles centred at `point`, facing `normal`.

    A mesh rather than an analytic half-space, so that ipctk's static-obstacle filter also
    keeps other obstacles (a sphere resting on the ground) from colliding with it.
    """
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    h = 0.5 * size
    V = np.asarray(point, float) + h * np.array([-a - b, a - b, a + b, -a + b])
    return V, np.array([[0, 1, 2], [0, 2, 3]], np.int32)
