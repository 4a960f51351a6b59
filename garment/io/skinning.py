"""Linear blend skinning: a rigged mesh (Rig, built once) posed by a track of joint
rotations (PoseTrack, one entry per frame) into a BodySequence.

Conventions (every array in the scene frame: metres, Z-up). A pose gives each joint j a
world rotation W_j relative to the bind pose and the root's position; joint positions
follow by forward kinematics, h_j = h_parent + W_parent (b_j - b_parent), with b the bind
joints. A vertex v moves to sum_k w_k (W_jk (v - b_jk) + h_jk) over its weighted joints.
The bind pose (every W = I, root at b_0) reproduces the mesh.

`posed_sequence` turns a track into the frames of an obstacle: the motion is turned about
the vertical and moved so its first frame stands where the bind pose stands, facing the
same way, with the lowest point of the clip on the bind pose's floor; then `lead` frames
blend from the bind pose into the first frame (slerp per joint, eased in and out), for the
end of the pre-roll (docs/bodies.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from sim.budget import format_bytes, require_memory

from .bodies import BodySequence
from .rotations import axis_matrix, slerp_matrices, twist_angle


@dataclass
class Rig:
    """A mesh bound to a skeleton. names, parents (J,) (-1 for the root; parents before
    children), joints (J, 3) bind positions in m; vertices (V, 3) the bind mesh in m,
    faces (F, 3) int32; weight_index / weight (V, K): each vertex's joints and weights
    (rows sum to 1, unused slots weight 0). tails (J, 3): where each bone points at bind
    (for retargeting; None when the rig has none). correctives: W (J, 3, 3) -> (V, 3)
    offsets added to the bind vertices before skinning (SMPL's pose blend shapes)."""

    names: list[str]
    parents: np.ndarray
    joints: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    weight_index: np.ndarray
    weight: np.ndarray
    tails: np.ndarray | None = None
    correctives: Callable[[np.ndarray], np.ndarray] | None = None
    notes: list[str] = field(default_factory=list)

    def children(self, j: int) -> list[int]:
        return [int(c) for c in np.flatnonzero(self.parents == j)]


@dataclass
class PoseTrack:
    """world (T, J, 3, 3) joint rotations relative to the bind pose, root (T, 3) the root
    joint's position in m, frame_dt in s: T frames of a motion in the scene frame."""

    world: np.ndarray
    root: np.ndarray
    frame_dt: float


def padded_weights(vertex: np.ndarray, joint: np.ndarray, weight: np.ndarray,
                   n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(index (V, K) int32, weight (V, K), unweighted vertex ids) from (vertex, joint,
    weight) triples; zero weights dropped, each row normalised to sum 1."""
    keep = weight > 0.0
    vertex, joint, weight = vertex[keep], joint[keep], weight[keep]
    order = np.lexsort((joint, vertex))
    vertex, joint, weight = vertex[order], joint[order], weight[order]
    counts = np.bincount(vertex, minlength=n_vertices)
    K = max(int(counts.max(initial=0)), 1)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.arange(len(vertex)) - start[vertex]
    index = np.zeros((n_vertices, K), np.int32)
    w = np.zeros((n_vertices, K))
    index[vertex, slot] = joint
    w[vertex, slot] = weight
    total = w.sum(axis=1)
    unweighted = np.flatnonzero(total <= 0.0)
    w /= np.where(total > 0.0, total, 1.0)[:, None]
    return index, w, unweighted


def joint_positions(parents: np.ndarray, bind: np.ndarray, world: np.ndarray, root: np.ndarray) -> np.ndarray:
    """(T, J, 3) joint positions by forward kinematics from world rotations (T, J, 3, 3)
    and root positions (T, 3)."""
    h = np.empty(world.shape[:2] + (3,))
    for j, p in enumerate(parents):
        if p < 0:
            h[:, j] = root
        else:
            h[:, j] = h[:, p] + np.einsum("tab,b->ta", world[:, p], bind[j] - bind[p])
    return h


@njit(cache=True)
def _skin(rest, index, weight, A, out):
    """out[v] = sum_k weight[v, k] * A[index[v, k]] @ (rest[v], 1); A (J, 3, 4). Serial:
    a 13k-vertex body takes about a millisecond a frame, and no thread pool is started
    (readers run in forked children under the fuzz tests)."""
    for v in range(rest.shape[0]):
        x, y, z = rest[v, 0], rest[v, 1], rest[v, 2]
        ox = oy = oz = 0.0
        for k in range(index.shape[1]):
            wk = weight[v, k]
            if wk == 0.0:
                continue
            a = A[index[v, k]]
            ox += wk * (a[0, 0] * x + a[0, 1] * y + a[0, 2] * z + a[0, 3])
            oy += wk * (a[1, 0] * x + a[1, 1] * y + a[1, 2] * z + a[1, 3])
            oz += wk * (a[2, 0] * x + a[2, 1] * y + a[2, 2] * z + a[2, 3])
        out[v, 0], out[v, 1], out[v, 2] = ox, oy, oz


def skin(rig: Rig, world: np.ndarray, heads: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(V, 3) vertices of one pose: world (J, 3, 3) rotations, heads (J, 3) joint positions."""
    rest = rig.vertices if rig.correctives is None else rig.vertices + rig.correctives(world)
    A = np.empty((len(world), 3, 4))
    A[:, :, :3] = world
    A[:, :, 3] = heads - np.einsum("jab,jb->ja", world, rig.joints)
    out = np.empty_like(rest) if out is None else out
    _skin(np.ascontiguousarray(rest, dtype=np.float64), rig.weight_index, rig.weight, A, out)
    return out


def posed_sequence(rig: Rig, track: PoseTrack, lead: int = 0, source: str = "the body") -> BodySequence:
    """The body's frames: `lead` frames blending from the bind pose into the track's first
    frame, then the track, aligned to the bind pose (module docstring)."""
    T, V = len(track.world), len(rig.vertices)
    need = 8.0 * 3 * V * (T + lead)
    require_memory(2 * need, f"{source}: {T + lead} frames of {V} vertices ({format_bytes(need)})",
                   "shorten the clip (end) or the run (frames), or raise the time step (dt)")
    turn = axis_matrix("z", -twist_angle(track.world[0, 0]))
    world = turn @ track.world
    root = (track.root - track.root[0]) @ turn.T + rig.joints[0]
    heads = joint_positions(rig.parents, rig.joints, world, root)
    frames = np.empty((lead + T, V, 3))
    for t in range(T):
        skin(rig, world[t], heads[t], frames[lead + t])
    lift = rig.vertices[:, 2].min() - frames[lead:, :, 2].min()
    frames[lead:, :, 2] += lift
    if lead:
        s = np.arange(lead) / lead
        s = s * s * (3.0 - 2.0 * s)  # eased: the body starts and arrives at rest
        first = np.broadcast_to(world[0], (lead,) + world.shape[1:])
        blend = slerp_matrices(np.broadcast_to(np.eye(3), first.shape), first,
                               np.broadcast_to(s[:, None], first.shape[:2]))
        path = (1.0 - s)[:, None] * rig.joints[0] + s[:, None] * (root[0] + [0.0, 0.0, lift])
        bheads = joint_positions(rig.parents, rig.joints, blend, path)
        for k in range(lead):
            skin(rig, blend[k], bheads[k], frames[k])
    return BodySequence(frames, np.ascontiguousarray(rig.faces, np.int32), float(track.frame_dt),
                        lead_in=lead * float(track.frame_dt), notes=list(rig.notes))
