"""Linear blend skinning on the bundled MakeHuman body: the bind pose reproduces the mesh,
one turned joint moves exactly the vertices weighted to it and below it, and the body
sequence blends from the bind pose into the motion."""

from __future__ import annotations

import numpy as np
import pytest

from garment.io.rig import read_makehuman, rig_to_scene
from garment.io.rotations import axis_angle_matrix, euler_matrix, matrix_quaternion, quaternion_matrix, slerp
from garment.io.skinning import PoseTrack, joint_positions, padded_weights, posed_sequence, skin

from tests.support.paths import ASSETS

MH = ASSETS / "bodies" / "makehuman_cmu"


@pytest.fixture(scope="module")
def rig():
    return rig_to_scene(read_makehuman(MH / "body.obj", "body", MH / "rig.cmu_mb.json", MH / "weights.cmu_mb.json"),
                        0.1, "y", (0.0, 0.0, 0.0))


def _bind_track(rig, frames: int = 1) -> PoseTrack:
    J = len(rig.names)
    return PoseTrack(np.broadcast_to(np.eye(3), (frames, J, 3, 3)).copy(), np.tile(rig.joints[0], (frames, 1)), 0.04)


def test_the_makehuman_body_is_read_as_documented(rig):
    assert rig.vertices.shape == (13380, 3) and rig.faces.shape == (26756, 3)  # quads fanned
    assert len(rig.names) == 31 and rig.names[0] == "Hips"
    assert np.allclose(rig.weight.sum(axis=1), 1.0) and rig.weight.shape[1] == 7  # influences per vertex
    height = np.ptp(rig.vertices[:, 2])
    assert 1.6 < height < 1.75  # decimetres, Y-up -> metres, Z-up
    head = rig.joints[rig.names.index("Head")]
    assert head[2] > rig.joints[0, 2] + 0.5  # the head is above the hips


def test_bind_pose_reproduces_the_mesh(rig):
    heads = joint_positions(rig.parents, rig.joints, *(_bind_track(rig).world, _bind_track(rig).root))
    np.testing.assert_allclose(heads[0], rig.joints, atol=1e-12)
    out = skin(rig, _bind_track(rig).world[0], heads[0])
    assert np.abs(out - rig.vertices).max() < 1e-6


@pytest.mark.parametrize("joint", ["LeftForeArm", "RightLeg", "Neck1"])
def test_one_turned_joint_moves_only_the_vertices_it_weights(rig, joint):
    j = rig.names.index(joint)
    below = {j}
    for k, p in enumerate(rig.parents):  # parents come before children
        if p in below:
            below.add(k)
    track = _bind_track(rig)
    R = axis_angle_matrix(np.array([0.3, -0.5, 0.8]))
    for k in below:
        track.world[0, k] = R
    heads = joint_positions(rig.parents, rig.joints, track.world, track.root)[0]
    out = skin(rig, track.world[0], heads)
    moved = np.linalg.norm(out - rig.vertices, axis=1)
    weighted = (np.isin(rig.weight_index, list(below)) & (rig.weight > 0)).any(axis=1)
    assert weighted.sum() > 100
    assert moved[~weighted].max() <= 1e-12
    assert moved[weighted].min() > 1e-9


def test_posed_sequence_blends_from_the_bind_pose(rig):
    # A track whose first frame turns the left forearm: the lead frames start at the bind
    # mesh, ease into the first frame and arrive there exactly.
    track = _bind_track(rig, frames=3)
    j = rig.names.index("LeftForeArm")
    track.world[:, j] = axis_angle_matrix(np.array([0.0, 0.0, 1.0]))
    seq = posed_sequence(rig, track, lead=5)
    assert seq.frames.shape == (8, 13380, 3) and seq.lead_in == pytest.approx(0.2)
    assert np.abs(seq.frames[0] - rig.vertices).max() < 1e-9
    step = np.abs(np.diff(seq.frames[:6], axis=0)).max(axis=(1, 2))
    assert step[0] < step[2] and step[-1] < step[2]  # eased: slow at both ends
    heads = joint_positions(rig.parents, rig.joints, track.world[:1], track.root[:1])[0]
    np.testing.assert_allclose(seq.frames[5], skin(rig, track.world[0], heads), atol=1e-9)


def test_posed_sequence_turns_and_moves_the_motion_onto_the_bind_pose(rig):
    # The same pose turned 90 degrees about the vertical and carried 3 m away, 1 m up: it
    # is brought back to the bind pose's place and heading, feet on its floor.
    track = _bind_track(rig, frames=2)
    turn = axis_angle_matrix(np.array([0.0, 0.0, np.pi / 2]))
    track.world[:] = turn
    track.root[:] = [3.0, 0.0, 1.0]
    track.root[1] += [0.1, 0.0, 0.0]
    seq = posed_sequence(rig, track)
    assert np.abs(seq.frames[0] - rig.vertices).max() < 1e-9
    np.testing.assert_allclose(seq.frames[1] - seq.frames[0], np.tile([0.0, -0.1, 0.0], (13380, 1)), atol=1e-9)


def test_padded_weights_normalise_and_report_unweighted_vertices():
    index, w, unweighted = padded_weights(np.array([0, 0, 2, 2, 2]), np.array([1, 0, 3, 1, 2]),
                                          np.array([1.0, 3.0, 0.5, 0.5, 0.0]), 4)
    assert index.shape == (4, 2)
    np.testing.assert_allclose(w[0], [0.75, 0.25])
    assert list(index[0]) == [0, 1] and list(index[2]) == [1, 3]
    assert list(unweighted) == [1, 3]


def test_rotation_helpers_agree():
    rng = np.random.default_rng(1)
    R = axis_angle_matrix(rng.standard_normal((50, 3)))
    np.testing.assert_allclose(quaternion_matrix(matrix_quaternion(R)), R, atol=1e-12)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    # BVH's intrinsic order: "zxy" is Rz Rx Ry.
    a = np.array([30.0, -20.0, 45.0])
    Rz, Rx, Ry = (axis_angle_matrix(np.radians(d) * np.eye(3)[k]) for d, k in zip(a, (2, 0, 1)))
    np.testing.assert_allclose(euler_matrix("zxy", a), Rz @ Rx @ Ry, atol=1e-12)
    q0, q1 = matrix_quaternion(R[:2])
    mid = quaternion_matrix(slerp(q0, q1, 0.5))
    half = R[0] @ quaternion_matrix(slerp(np.array([1.0, 0, 0, 0]), matrix_quaternion(R[0].T @ R[1]), 0.5))
    np.testing.assert_allclose(mid, half, atol=1e-12)
