"""Retargeting BVH motion onto the MakeHuman rig: a capture of the rig itself reproduces
the bind mesh; a T-pose capture whose first frame is the mesh's A-pose puts the joints back
on the mesh's joints (1 cm); the real CMU capture drives every bone along the capture's
own bone directions; units and axes of the file do not matter."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from garment.io.bvh import read_bvh
from garment.io.retarget import axis_change, joint_pairs, retarget
from garment.io.rig import read_makehuman, rig_to_scene
from garment.io.rigged import LIVELY, MAKEHUMAN_JOINTS
from garment.io.rotations import axis_angle_matrix
from garment.io.skinning import joint_positions, posed_sequence
from garment.io.smpl import UP
from sim.errors import InputError

from tests.garment.bodies.synthetic import write_bvh, write_column_bvh, write_column_rig
from tests.support.paths import ASSETS

MH = ASSETS / "bodies" / "makehuman_cmu"
ZXY = ("Zrotation", "Xrotation", "Yrotation")


@pytest.fixture(scope="module")
def rig():
    return rig_to_scene(read_makehuman(MH / "body.obj", "body", MH / "rig.cmu_mb.json", MH / "weights.cmu_mb.json"),
                        0.1, "y", (0.0, 0.0, 0.0))


def _below(rig, name: str) -> list[int]:
    out = {rig.names.index(name)}
    for k, p in enumerate(rig.parents):
        if p in out:
            out.add(k)
    return sorted(out)


def _capture_of_the_rig(rig, path, rest_turns: dict, unit: float, frames_world: list) -> object:
    """A BVH of the rig's own skeleton, Y-up in file units of `unit` m, whose rest pose is
    the bind pose with world rotations `rest_turns` (joint -> R, scene frame) applied down
    each chain, and whose frames have the world rotations `frames_world` (list of (J, 3, 3),
    scene frame). Returns the path."""
    J = len(rig.names)
    Q = np.broadcast_to(np.eye(3), (J, 3, 3)).copy()
    for name, R in rest_turns.items():
        for k in _below(rig, name):
            Q[k] = R
    P = rig.joints.copy()
    for j, p in enumerate(rig.parents):
        if p >= 0:
            P[j] = P[p] + Q[p] @ (rig.joints[j] - rig.joints[p])
    C = UP["y"]  # scene axes of the file's (Y-up) axes
    P_file = P @ C / unit
    offsets = np.array([P_file[j] - (P_file[p] if p >= 0 else P_file[j]) for j, p in enumerate(rig.parents)])
    rows = []
    for G in frames_world:  # G: the world rotation relative to the BVH rest, scene frame
        row = list(P_file[0] + [3.0, 0.0, 2.0])
        for j, p in enumerate(rig.parents):
            L = G[j] if p < 0 else G[p].T @ G[j]
            rows_zxy = Rotation.from_matrix(C.T @ L @ C).as_euler("ZXY", degrees=True)
            row += list(rows_zxy)
        rows.append(row)
    channels = [("Xposition", "Yposition", "Zposition") + ZXY] + [ZXY] * (J - 1)
    return write_bvh(path, rig.names, list(rig.parents), offsets, channels, np.array(rows), 1 / 30)


def test_a_capture_of_the_rig_itself_reproduces_the_bind_mesh(rig, tmp_path):
    I = np.broadcast_to(np.eye(3), (len(rig.names), 3, 3))
    path = _capture_of_the_rig(rig, tmp_path / "self.bvh", {}, 0.01, [I, I])
    clip = read_bvh(path)
    track = retarget(clip, rig, np.array([0.0, 1 / 30]), 1 / 30)
    heads = joint_positions(rig.parents, rig.joints, track.world, track.root)
    np.testing.assert_allclose(heads[0] - heads[0, 0], rig.joints - rig.joints[0], atol=1e-9)
    seq = posed_sequence(rig, track)
    assert np.abs(seq.frames - rig.vertices).max() < 1e-6


def test_a_t_pose_capture_whose_first_frame_is_the_a_pose_lands_on_the_mesh_joints(rig, tmp_path):
    # Rest pose: arms raised to horizontal (the A-pose arms swung about the forward axis),
    # legs splayed 15 degrees, as the CMU conversions' rest poses are; in inches. Frame 0
    # undoes it (the mesh's A-pose), frame 1 is the rest pose itself.
    def level(name):
        j = rig.names.index(name)
        d = rig.joints[rig.children(j)[0]] - rig.joints[j]
        return axis_angle_matrix(np.array([0.0, -np.arctan2(-d[2], abs(d[0])) * np.sign(d[0]), 0.0]))

    turns = {"LeftArm": level("LeftArm"), "RightArm": level("RightArm"),
             "LeftUpLeg": axis_angle_matrix(np.radians([0.0, -15.0, 0.0])),
             "RightUpLeg": axis_angle_matrix(np.radians([0.0, 15.0, 0.0]))}
    J = len(rig.names)
    Q = np.broadcast_to(np.eye(3), (J, 3, 3)).copy()
    for name, R in turns.items():
        Q[_below(rig, name)] = R
    path = _capture_of_the_rig(rig, tmp_path / "tpose.bvh", turns, 0.0254,
                               [np.swapaxes(Q, 1, 2), np.broadcast_to(np.eye(3), (J, 3, 3))])
    clip = read_bvh(path)
    track = retarget(clip, rig, np.array([0.0, 1 / 30]), 1 / 30)
    heads = joint_positions(rig.parents, rig.joints, track.world, track.root)
    err = np.linalg.norm((heads[0] - heads[0, 0]) - (rig.joints - rig.joints[0]), axis=1)
    assert err.max() < 0.01, f"{rig.names[int(np.argmax(err))]}: {err.max() * 100:.2f} cm"
    # Frame 1, the capture's T-pose: the upper arms are level.
    for side in ("Left", "Right"):
        shoulder, elbow = heads[1, rig.names.index(f"{side}Arm")], heads[1, rig.names.index(f"{side}ForeArm")]
        assert abs(elbow[2] - shoulder[2]) < 1e-3 and abs(elbow[0] - shoulder[0]) > 0.2
    seq = posed_sequence(rig, track)
    assert np.abs(seq.frames[0] - rig.vertices).max() < 0.01


@pytest.fixture(scope="module")
def cmu(rig):
    clip = read_bvh(MH / "01_01.bvh")
    times = np.arange(LIVELY[0], LIVELY[1], 12) * clip.frame_time
    return clip, times, retarget(clip, rig, times, 0.1, MAKEHUMAN_JOINTS)


def test_the_cmu_capture_drives_every_bone_along_the_captures_bone(rig, cmu):
    clip, times, track = cmu
    pairs = joint_pairs(rig, clip, MAKEHUMAN_JOINTS)
    C = axis_change(rig, clip, pairs)
    np.testing.assert_allclose(C, UP["y"])  # CMU is Y-up
    # The capture's joint positions at those times (forward kinematics of its own offsets).
    world, root = clip.sample(times)
    p = np.empty(world.shape[:2] + (3,))
    for j, parent in enumerate(clip.parents):
        p[:, j] = root if parent < 0 else p[:, parent] + world[:, parent] @ clip.offsets[j]
    heads = joint_positions(rig.parents, rig.joints, track.world, track.root)
    checked = 0
    for j, parent in enumerate(rig.parents):
        if parent < 0 or pairs[j] < 0 or pairs[parent] < 0 or clip.parents[pairs[j]] != pairs[parent]:
            continue
        if np.linalg.norm(clip.offsets[pairs[j]]) < 1e-6:
            continue
        mesh = heads[:, j] - heads[:, parent]
        capture = (p[:, pairs[j]] - p[:, pairs[parent]]) @ C.T
        cos = np.sum(mesh * capture, axis=1) / np.linalg.norm(mesh, axis=1) / np.linalg.norm(capture, axis=1)
        assert cos.min() > 1.0 - 1e-9, rig.names[j]
        checked += 1
    assert checked >= 15
    # Bone lengths stay the mesh's.
    bone = np.linalg.norm(heads[:, 5] - heads[:, rig.parents[5]], axis=1)
    np.testing.assert_allclose(bone, np.linalg.norm(rig.joints[5] - rig.joints[rig.parents[5]]), rtol=1e-9)


def test_the_cmu_root_moves_at_the_mesh_scale(rig, cmu):
    clip, times, track = cmu
    assert track.root.shape == (len(times), 3)
    stride = np.ptp(track.root[:, :2], axis=0).max()
    assert 0.5 < stride < 3.0  # two forward jumps of a 1.7 m person, in metres
    assert any("1 BVH unit = 5.48 cm" in n for n in rig.notes)


def test_file_units_and_axes_do_not_matter(tmp_path):
    paths = write_column_rig(tmp_path / "rig")
    rig = rig_to_scene(read_makehuman(paths["mesh"], "body", paths["rig"], paths["weights"]), 1.0, "y", (0, 0, 0))
    frames = []
    for unit in (0.01, 0.0254):
        clip = read_bvh(write_column_bvh(tmp_path / f"m{unit}.bvh", unit=unit))
        frames.append(posed_sequence(rig, retarget(clip, rig, np.arange(13) / 60, 1 / 60)).frames)
    # The same capture written Z-up: positions (x, y, z) -> (x, -z, y), rotations alike.
    clip = read_bvh(tmp_path / "m0.01.bvh")
    C = UP["y"]
    offsets = clip.offsets @ C.T
    values = clip.values.copy()
    values[:, :3] = values[:, :3] @ C.T
    col = 3
    for chans in clip.channels:
        rot = [k for k, c in enumerate(chans) if c.endswith("rotation")]
        L = clip.local_rotations(np.arange(clip.n_frames))
        values[:, col + rot[0]: col + rot[0] + 3] = 0.0
        col += len(chans)
    L = C @ clip.local_rotations(np.arange(clip.n_frames)) @ C.T
    rows = [np.r_[values[t, :3], np.concatenate([Rotation.from_matrix(L[t, j]).as_euler("ZXY", degrees=True)
                                                  for j in range(3)])] for t in range(clip.n_frames)]
    zup = write_bvh(tmp_path / "zup.bvh", clip.names, list(clip.parents), offsets,
                    [("Xposition", "Yposition", "Zposition") + ZXY, ZXY, ZXY], np.array(rows), clip.frame_time)
    clip = read_bvh(zup)
    frames.append(posed_sequence(rig, retarget(clip, rig, np.arange(13) / 60, 1 / 60)).frames)
    assert np.abs(frames[1] - frames[0]).max() < 1e-6
    assert np.abs(frames[2] - frames[0]).max() < 1e-6
    assert np.abs(frames[0][6] - frames[0][0]).max() > 0.1  # it does bend


def test_joint_names_are_matched_or_refused(rig, tmp_path):
    paths = write_column_rig(tmp_path / "rig")
    column = rig_to_scene(read_makehuman(paths["mesh"], "body", paths["rig"], paths["weights"]), 1.0, "y", (0, 0, 0))
    clip = read_bvh(write_column_bvh(tmp_path / "m.bvh"))
    clip.names = ["root", "MID", "Tip"]  # case differs; Tip is another joint
    assert list(joint_pairs(column, clip)) == [0, 1, -1]
    assert list(joint_pairs(column, clip, {"Top": "Tip"})) == [0, 1, 2]
    with pytest.raises(InputError, match="'Head' is not a joint of the rig"):
        joint_pairs(column, clip, {"Head": "Tip"})
    with pytest.raises(InputError, match="'Neck' is not a joint of the BVH"):
        joint_pairs(column, clip, {"Top": "Neck"})
    clip.names = ["Pelvis", "MID", "Tip"]
    with pytest.raises(InputError, match="root 'Root' has no joint in the BVH.*joints = \\[\\['Root', 'Pelvis'\\]\\]"):
        joint_pairs(column, clip)
    # The CMU capture on the column: hardly any joint pairs up.
    with pytest.raises(InputError, match="only 1 of the rig's 3 joints"):
        cmu_clip = read_bvh(MH / "01_01.bvh")
        cmu_clip.names[0] = "Root"
        joint_pairs(column, cmu_clip)
