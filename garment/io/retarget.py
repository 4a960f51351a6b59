"""BVH motion on a rig of other proportions and another rest pose (a T-pose capture on an
A-pose mesh): world-space rotations relative to the rest pose are transferred, not local
angles or offsets.

1. Joints pair up by name (exactly, then ignoring case), or as `joints` maps them. Rig
   joints without a partner turn with their parent. Leaving one unpaired on purpose
   keeps a bone the two skeletons place differently out of it: CMU's clavicles rise 20
   degrees at rest and never move, MakeHuman's are level; paired, they would lift the
   shoulders 4 cm for the whole clip.
2. The BVH's axes are related to the scene's by the signed axis permutation closest to
   the best rotation between the two skeletons (Kabsch on the paired joints).
3. Each paired rig joint j gets an offset O_j turning its bone at bind (towards the next
   paired joint down its chain) into the BVH's at rest: its parent's offset, then the
   smallest turn that lines the bone up, so the twist a bone direction alone cannot tell
   comes down the chain. Its pose is W_j(t) = C D_j(t) C^T O_j, with D_j(t) the BVH
   joint's world rotation relative to rest and C the axis change: at the BVH's rest pose
   the mesh takes the BVH's rest pose, and from there it follows the capture's joint
   rotations.
4. The root moves as the BVH's root, scaled by the ratio of leg lengths (the chain from
   the root to the lowest joint at bind), so the feet keep their stride whatever units
   the capture used.
"""

from __future__ import annotations

import itertools

import numpy as np

from sim.errors import InputError

from .bvh import BvhClip
from .rotations import rotation_between
from .skinning import PoseTrack, Rig

MIN_PAIRED = 0.5  # share of the rig's joints the BVH must name


def joint_pairs(rig: Rig, clip: BvhClip, joints: dict[str, str] | None = None) -> np.ndarray:
    """(J,) the BVH joint of each rig joint, -1 where there is none (`joints` may pair a
    rig joint with "" to leave it unpaired)."""
    joints = joints or {}
    for r, b in joints.items():
        if r not in rig.names:
            raise InputError(f"joints: {r!r} is not a joint of the rig ({', '.join(rig.names[:8])}, ...)")
        if b and b not in clip.names:
            raise InputError(f"{clip.path}: joints: {b!r} is not a joint of the BVH ({', '.join(clip.names[:8])}, ...)")
    lower = {}
    for k, n in enumerate(clip.names):
        lower.setdefault(n.lower(), []).append(k)
    pairs = np.full(len(rig.names), -1)
    for j, n in enumerate(rig.names):
        if n in joints:
            pairs[j] = clip.names.index(joints[n]) if joints[n] else -1
        elif n in clip.names:
            pairs[j] = clip.names.index(n)
        elif len(lower.get(n.lower(), [])) == 1:
            pairs[j] = lower[n.lower()][0]
    if pairs[0] < 0:
        raise InputError(f"{clip.path}: the rig's root {rig.names[0]!r} has no joint in the BVH (its root is "
                         f"{clip.names[0]!r}); map it with joints = [[{rig.names[0]!r}, {clip.names[0]!r}]]")
    found = int((pairs >= 0).sum())
    if found < MIN_PAIRED * len(rig.names):
        missing = [n for n, p in zip(rig.names, pairs) if p < 0]
        raise InputError(f"{clip.path}: only {found} of the rig's {len(rig.names)} joints are in the BVH (missing: "
                         f"{', '.join(missing[:10])}{', ...' if len(missing) > 10 else ''}); a motion for another "
                         "skeleton? Map the names with joints = [[rig, bvh], ...]")
    return pairs


def axis_change(rig: Rig, clip: BvhClip, pairs: np.ndarray) -> np.ndarray:
    """C (3, 3): BVH axes to scene axes, the signed permutation (det +1) closest to the
    rotation that best aligns the paired joints relative to their roots."""
    rest = clip.rest_positions()
    j = np.flatnonzero(pairs >= 0)
    A = rest[pairs[j]] - rest[pairs[0]]
    B = rig.joints[j] - rig.joints[0]
    A /= max(np.linalg.norm(A, axis=1).max(), 1e-300)
    B /= max(np.linalg.norm(B, axis=1).max(), 1e-300)
    best, score = np.eye(3), -np.inf
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            C = np.zeros((3, 3))
            C[list(perm), range(3)] = signs
            if np.linalg.det(C) < 0:
                continue
            s = float(np.sum((A @ C.T) * B))
            if s > score:
                best, score = C, s
    return best


def leg_ratio(rig: Rig, clip: BvhClip, pairs: np.ndarray) -> float:
    """Scene metres per BVH unit: the length of the paired chain from the root to the
    lowest paired joint at bind (a leg), in the rig and in the BVH's rest pose; to the
    farthest one when the root is the lowest."""
    rest = clip.rest_positions()
    paired = np.flatnonzero(pairs >= 0)
    low = int(paired[np.argmin(rig.joints[paired, 2])])
    if low == 0:
        low = int(paired[np.argmax(np.linalg.norm(rig.joints[paired] - rig.joints[0], axis=1))])
    chain, j = [], low
    while j >= 0:
        if pairs[j] >= 0:
            chain.append(j)
        j = int(rig.parents[j])
    mesh = sum(np.linalg.norm(rig.joints[a] - rig.joints[b]) for a, b in zip(chain, chain[1:]))
    bvh = sum(np.linalg.norm(rest[pairs[a]] - rest[pairs[b]]) for a, b in zip(chain, chain[1:]))
    if not (mesh > 0 and bvh > 0):
        raise InputError(f"{clip.path}: cannot measure the legs (root {rig.names[0]!r} to {rig.names[low]!r} has "
                         "no length in the rig or in the BVH's rest pose)")
    return float(mesh / bvh)


def _descends(parents: np.ndarray, a: int, b: int) -> bool:
    """b is a (strict) descendant of a."""
    while b >= 0:
        b = int(parents[b])
        if b == a:
            return True
    return False


def rest_offsets(rig: Rig, clip: BvhClip, pairs: np.ndarray, C: np.ndarray) -> np.ndarray:
    """(J, 3, 3) rotation from each rig bone at bind to its BVH bone at rest (scene frame):
    the parent's, then the smallest turn that lines up the bone after it. Down a chain the
    difference of the two rest poses is carried along, twist included (a foot pointing
    forward under a leg splayed sideways turns with the leg, it does not roll); a bone with
    no usable direction keeps its parent's."""
    rest = clip.rest_positions() @ C.T
    size_rig = np.ptp(rig.joints, axis=0).max()
    size_bvh = np.ptp(rest, axis=0).max()
    tails = rig.tails if rig.tails is not None else rig.joints
    O = np.empty((len(rig.names), 3, 3))
    for j, p in enumerate(rig.parents):
        O[j] = O[p] if p >= 0 else np.eye(3)
        if pairs[j] < 0:
            continue
        c = _chain_child(rig, j, tails)
        while c is not None:
            if pairs[c] >= 0 and _descends(clip.parents, pairs[j], pairs[c]):
                d_rig, d_bvh = rig.joints[c] - rig.joints[j], rest[pairs[c]] - rest[pairs[j]]
                if np.linalg.norm(d_rig) > 1e-3 * size_rig and np.linalg.norm(d_bvh) > 1e-3 * size_bvh:
                    O[j] = rotation_between(O[j] @ d_rig, d_bvh) @ O[j]
                    break
            c = _chain_child(rig, c, tails)
    return O


def _chain_child(rig: Rig, j: int, tails: np.ndarray) -> int | None:
    """The child of j whose joint is nearest j's tail (the bone's continuation)."""
    kids = rig.children(j)
    if not kids:
        return None
    return min(kids, key=lambda c: float(np.linalg.norm(rig.joints[c] - tails[j])))


def retarget(clip: BvhClip, rig: Rig, times: np.ndarray, frame_dt: float,
             joints: dict[str, str] | None = None) -> PoseTrack:
    """The BVH's motion at `times` (s of the clip) on `rig` (scene frame)."""
    pairs = joint_pairs(rig, clip, joints)
    C = axis_change(rig, clip, pairs)
    O = rest_offsets(rig, clip, pairs, C)
    scale = leg_ratio(rig, clip, pairs)
    D, root = clip.sample(times)
    D = C @ D @ C.T
    W = np.empty((len(times), len(rig.names), 3, 3))
    for j, p in enumerate(rig.parents):
        W[:, j] = D[:, pairs[j]] @ O[j] if pairs[j] >= 0 else W[:, p]
    rig.notes += _notes(rig, clip, pairs, C, scale)
    return PoseTrack(W, scale * root @ C.T, frame_dt)


def _notes(rig: Rig, clip: BvhClip, pairs: np.ndarray, C: np.ndarray, scale: float) -> list[str]:
    axes = ["+x", "+y", "+z"]
    up = next(axes[k].replace("+", "-" if C[2, k] < 0 else "+") for k in range(3) if C[2, k] != 0)
    notes = [f"{clip.path.name}: up is {up}; 1 BVH unit = {scale * 100:.3g} cm on this body (leg lengths)"]
    unpaired = [n for n, p in zip(rig.names, pairs) if p < 0]
    if unpaired:
        notes.append(f"{clip.path.name}: no joint for {', '.join(unpaired)}: they turn with their parents")
    return notes
