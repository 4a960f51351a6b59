"""Rotations for skeletons, vectorised over leading axes: matrices (..., 3, 3) acting on
column vectors, unit quaternions (..., 4) as (w, x, y, z), axis-angle vectors (..., 3) in
radians, Euler angles as BVH writes them (degrees, intrinsic, in channel order)."""

from __future__ import annotations

import numpy as np

_AXES = {"x": 0, "y": 1, "z": 2}


def axis_matrix(axis: str, angle: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations by `angle` (rad) about the coordinate axis "x", "y" or "z"."""
    angle = np.asarray(angle, float)
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(angle.shape + (3, 3))
    i = _AXES[axis]
    j, k = (i + 1) % 3, (i + 2) % 3
    R[..., i, i] = 1.0
    R[..., j, j] = c
    R[..., k, k] = c
    R[..., j, k] = -s
    R[..., k, j] = s
    return R


def euler_matrix(axes: str, degrees: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation R = R_a0 R_a1 ... of Euler angles (..., len(axes)) in degrees
    about the axes named in order (BVH's "Zrotation Xrotation Yrotation" is "zxy")."""
    degrees = np.asarray(degrees, float)
    R = np.broadcast_to(np.eye(3), degrees.shape[:-1] + (3, 3)).copy()
    for n, a in enumerate(axes):
        R = R @ axis_matrix(a, np.radians(degrees[..., n]))
    return R


def axis_angle_matrix(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations of axis-angle vectors (..., 3) (Rodrigues; exact at 0)."""
    v = np.asarray(v, float)
    theta = np.linalg.norm(v, axis=-1)
    small = theta < 1e-12
    safe = np.where(small, 1.0, theta)
    k = v / safe[..., None]
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -k[..., 2], k[..., 1]
    K[..., 1, 0], K[..., 1, 2] = k[..., 2], -k[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -k[..., 1], k[..., 0]
    s = np.where(small, 0.0, np.sin(theta))[..., None, None]
    c = np.where(small, 0.0, 1.0 - np.cos(theta))[..., None, None]
    return np.eye(3) + s * K + c * (K @ K)


def matrix_quaternion(R: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w >= 0) of rotation matrices (..., 3, 3); the largest
    of |w|, |x|, |y|, |z| is solved for first, so no branch divides by a small number."""
    R = np.asarray(R, float)
    m = R.reshape(-1, 3, 3)
    tr = np.trace(m, axis1=1, axis2=2)
    diag = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    pick = np.argmax(diag, axis=1)
    q = np.empty((len(m), 4))
    for case in range(4):
        s = pick == case
        if not s.any():
            continue
        a = m[s]
        if case == 0:
            r = np.sqrt(np.maximum(1.0 + tr[s], 1e-300)) * 2.0
            q[s] = np.stack([0.25 * r, (a[:, 2, 1] - a[:, 1, 2]) / r, (a[:, 0, 2] - a[:, 2, 0]) / r,
                             (a[:, 1, 0] - a[:, 0, 1]) / r], axis=1)
            continue
        i = case - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        r = np.sqrt(np.maximum(1.0 + a[:, i, i] - a[:, j, j] - a[:, k, k], 1e-300)) * 2.0
        out = np.empty((len(a), 4))
        out[:, 0] = (a[:, k, j] - a[:, j, k]) / r
        out[:, 1 + i] = 0.25 * r
        out[:, 1 + j] = (a[:, j, i] + a[:, i, j]) / r
        out[:, 1 + k] = (a[:, k, i] + a[:, i, k]) / r
        q[s] = out
    q *= np.where(q[:, :1] < 0.0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(R.shape[:-2] + (4,))


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of quaternions (..., 4) (normalised first)."""
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spherical interpolation of quaternions (..., 4) at fractions s (...), the short way."""
    q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
    s = np.asarray(s, float)[..., None]
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0.0, -q1, q1)  # q and -q are one rotation: take the shorter arc
    d = np.abs(d)
    theta = np.arccos(np.clip(d, -1.0, 1.0))
    near = theta < 1e-6
    sin = np.where(near, 1.0, np.sin(theta))
    a = np.where(near, 1.0 - s, np.sin((1.0 - s) * theta) / sin)
    b = np.where(near, s, np.sin(s * theta) / sin)
    q = a * q0 + b * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def slerp_matrices(R0: np.ndarray, R1: np.ndarray, s) -> np.ndarray:
    """Rotation matrices between R0 and R1 (..., 3, 3) at fraction s."""
    return quaternion_matrix(slerp(matrix_quaternion(R0), matrix_quaternion(R1), s))


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) smallest rotation turning direction a into direction b (half a turn about an
    axis normal to a when they are opposite)."""
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        if c > 0.0:
            return np.eye(3)
        normal = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        return axis_angle_matrix(np.pi * normal / np.linalg.norm(normal))
    return axis_angle_matrix(axis / s * np.arctan2(s, c))


def twist_angle(R: np.ndarray, axis: int = 2) -> float:
    """Angle (rad) of the twist of rotation R (3, 3) about coordinate `axis` in its
    swing-twist split: the turn about the vertical of a body's root, its heading."""
    q = matrix_quaternion(R)
    return float(2.0 * np.arctan2(q[1 + axis], q[0]))
