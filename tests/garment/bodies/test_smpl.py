"""SMPL-family bodies on a synthetic model in the official layout (tests/garment/bodies/
synthetic.py: a three-joint column): shape blend shapes, regressed joints, pose
correctives and skinning against values computed by hand; the .pkl reader; bad files."""

from __future__ import annotations

import os
import pickle
import sys
import types

import numpy as np
import pytest
import scipy.sparse as sp

from garment.io.rotations import axis_angle_matrix
from garment.io.skinning import joint_positions, skin
from garment.io.smpl import UP, read_model, read_motion, smpl_track, up_axis
from sim.errors import InputError

from tests.garment.bodies.synthetic import bend_motion, column_model, write_npz


@pytest.fixture
def files(tmp_path):
    return write_npz(tmp_path / "model.npz", column_model()), write_npz(tmp_path / "motion.npz", bend_motion())


def test_shape_blend_shapes_and_joints(files):
    model = read_model(files[0])
    a = column_model()
    betas = np.array([0.5, -0.5])
    shaped = model.shaped(betas)
    V = a["v_template"]
    np.testing.assert_allclose(shaped, V * [0.95, 1.05, 1.0], atol=1e-12)  # 5 % narrower, 5 % taller
    np.testing.assert_allclose(model.joints(shaped), a["J_regressor"] @ shaped, atol=1e-12)
    # The rig: the same joints, turned Z-up like any Y-up file.
    rig = model.rig(betas)
    np.testing.assert_allclose(rig.joints, (a["J_regressor"] @ shaped) @ UP["y"].T, atol=1e-12)
    np.testing.assert_allclose(rig.vertices, shaped @ UP["y"].T, atol=1e-12)
    assert rig.faces.dtype == np.int32 and rig.faces.max() < len(V)


def test_skinning_matches_the_chain_computed_by_hand(tmp_path, files):
    model = read_model(files[0])
    a = column_model()
    betas = np.array([0.5, -0.5])
    theta, phi, trans = 0.7, -0.4, np.array([0.1, 0.02, -0.03])
    poses = np.zeros((1, 9))
    poses[0, 3:6] = [0.0, 0.0, theta]  # joint 1 about z
    poses[0, 6:9] = [phi, 0.0, 0.0]  # joint 2 about x
    motion_path = write_npz(tmp_path / "pose.npz", {"poses": poses, "trans": trans[None], "mocap_framerate": 30.0})
    motion, _ = read_motion(motion_path, 3, 2)
    assert up_axis(motion, 0.0) == "y"
    # By hand, in the model's frame.
    v_s = a["v_template"] + a["shapedirs"] @ betas
    J = a["J_regressor"] @ v_s
    R1, R2 = axis_angle_matrix(np.array([0.0, 0.0, theta])), axis_angle_matrix(np.array([phi, 0.0, 0.0]))
    feature = np.concatenate([(R1 - np.eye(3)).ravel(), (R2 - np.eye(3)).ravel()])
    v_p = v_s + a["posedirs"] @ feature
    A = np.zeros((3, 3, 4))
    A[0, :, :3], A[0, :, 3] = np.eye(3), 0.0
    A[1, :, :3], A[1, :, 3] = R1, J[1] - R1 @ J[1]
    head2 = J[1] + R1 @ (J[2] - J[1])
    A[2, :, :3], A[2, :, 3] = R1 @ R2, head2 - R1 @ R2 @ J[2]
    hand = np.einsum("vj,jab,vb->va", a["weights"], A[:, :, :3], v_p) + a["weights"] @ A[:, :, 3] + trans
    # The reader's pose, without the alignment of a body sequence.
    rig = model.rig(betas)
    track = smpl_track(model, betas, motion, np.array([0.0]), 1 / 30, "y")
    heads = joint_positions(rig.parents, rig.joints, track.world, track.root)
    out = skin(rig, track.world[0], heads[0])
    np.testing.assert_allclose(out, hand @ UP["y"].T, atol=1e-12)
    assert np.abs(v_p - v_s).max() > 1e-4  # the correctives did something
    mixed = (a["weights"] > 0).sum(axis=1) > 1
    assert mixed.sum() > 20  # vertices blended between two joints are among those checked


def test_amass_motions_cut_to_the_model_with_notes(files):
    model = read_model(files[0])
    motion, notes = read_motion(files[1], model.n_joints, model.shapedirs.shape[2])
    assert motion.poses.shape == (31, 9) and motion.fps == 30.0
    assert list(motion.betas) == [0.5, -0.5]
    assert "the first 9 (3 joints) are used" in notes[0]
    assert "16 shape coefficients (betas), the model has 2" in notes[1]
    assert up_axis(motion, 0.0) == "z"  # AMASS stands the model up along Z
    # Slerp between frames: half way between two frames is half the angle.
    half = motion.local_rotations(np.array([0.5 / 30]))[0, 1]
    angle = 0.5 * (motion.poses[0, 5] + motion.poses[1, 5])
    np.testing.assert_allclose(half, axis_angle_matrix(np.array([0.0, 0.0, angle])), atol=1e-12)


def test_a_lying_body_asks_for_the_up_axis(tmp_path):
    m = bend_motion(z_up=False)
    m["poses"][:, 0:3] = [0.0, 0.0, np.pi / 2]  # the body's up along -X
    motion, _ = read_motion(write_npz(tmp_path / "lying.npz", m), 3, 2)
    with pytest.raises(InputError, match='cannot tell the motion\'s up axis.*set up = "z"'):
        up_axis(motion, 0.0)


def _pickled(arrays: dict, path, protocol: int = 2):
    """`arrays` pickled as the official SMPL files are: shapedirs a chumpy array,
    J_regressor a scipy sparse matrix (a stand-in chumpy module is installed for it)."""
    ch = types.ModuleType("chumpy.ch")

    class Ch:
        pass

    Ch.__module__, Ch.__qualname__ = "chumpy.ch", "Ch"
    ch.Ch = Ch
    doc = dict(arrays)
    shapedirs = Ch()
    shapedirs.x = arrays["shapedirs"]
    doc["shapedirs"] = shapedirs
    doc["J_regressor"] = sp.csc_matrix(arrays["J_regressor"])
    doc["bs_style"] = "lbs"
    saved = {k: sys.modules.get(k) for k in ("chumpy", "chumpy.ch")}
    sys.modules["chumpy"], sys.modules["chumpy.ch"] = types.ModuleType("chumpy"), ch
    try:
        path.write_bytes(pickle.dumps(doc, protocol=protocol))
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v
    return path


@pytest.mark.parametrize("protocol", [0, 2])
def test_official_pkl_layout_reads_like_the_npz(tmp_path, files, protocol):
    a = column_model()
    model = read_model(_pickled(a, tmp_path / "model.pkl", protocol))
    reference = read_model(files[0])
    for name in ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "parents", "faces"):
        np.testing.assert_array_equal(getattr(model, name), getattr(reference, name))


def test_pkl_files_cannot_run_code(tmp_path):
    class Evil:
        def __reduce__(self):
            return (os.system, ("true",))

    (tmp_path / "evil.pkl").write_bytes(pickle.dumps({"v_template": Evil()}))
    with pytest.raises(InputError, match=r"refers to (posix|os)\.system.*convert it to .npz"):
        read_model(tmp_path / "evil.pkl")
    (tmp_path / "list.pkl").write_bytes(pickle.dumps([1, 2]))
    with pytest.raises(InputError, match="holds a list, not an SMPL model"):
        read_model(tmp_path / "list.pkl")
    (tmp_path / "cut.pkl").write_bytes(_pickled(column_model(), tmp_path / "whole.pkl").read_bytes()[:5000])
    with pytest.raises(InputError, match="not a readable SMPL model pickle"):
        read_model(tmp_path / "cut.pkl")


def test_a_chumpy_expression_asks_for_npz(tmp_path):
    ops = types.ModuleType("chumpy.ch_ops")

    class add:
        pass

    add.__module__, add.__qualname__ = "chumpy.ch_ops", "add"
    ops.add = add
    expr = add()
    expr.a, expr.b = np.zeros(3), np.ones(3)
    sys.modules["chumpy"], sys.modules["chumpy.ch_ops"] = types.ModuleType("chumpy"), ops
    try:
        data = pickle.dumps({**column_model(), "shapedirs": expr}, protocol=2)
    finally:
        sys.modules.pop("chumpy.ch_ops")
        sys.modules.pop("chumpy")
    (tmp_path / "m.pkl").write_bytes(data)
    with pytest.raises(InputError, match="shapedirs is a chumpy expression.*convert the model to .npz"):
        read_model(tmp_path / "m.pkl")


def _broken(change):
    a = column_model()
    change(a)
    return a


BAD_MODELS = [
    ("no_posedirs", lambda a: a.pop("posedirs"), "needs posedirs"),
    ("shapedirs_2d", lambda a: a.update(shapedirs=a["shapedirs"][:, :, 0]), "shapedirs has shape"),
    ("posedirs_joints", lambda a: a.update(posedirs=a["posedirs"][:, :, :9]), r"posedirs has shape .* for 3 joints"),
    ("regressor", lambda a: a.update(J_regressor=a["J_regressor"][:2]), r"J_regressor has shape \(2, 386\)"),
    ("weights", lambda a: a.update(weights=np.c_[a["weights"], a["weights"][:, :1]]), "weights has shape"),
    ("kintree", lambda a: a.update(kintree_table=np.array([[0, 2, 0], [0, 1, 2]])), "not an earlier joint"),
    ("faces", lambda a: a.update(f=a["f"] + 1000), "f has shape .* indices below 386"),
    ("nan", lambda a: a["v_template"].__setitem__((3, 1), np.nan), "v_template has non-finite"),
    ("strings", lambda a: a.update(weights=a["weights"].astype(str)), "weights has shape .*expected 2 dimensions"),
]


@pytest.mark.parametrize("case, change, message", BAD_MODELS, ids=[c[0] for c in BAD_MODELS])
def test_bad_models_name_the_array(tmp_path, case, change, message):
    path = write_npz(tmp_path / "model.npz", _broken(change))
    with pytest.raises(InputError, match=message) as err:
        read_model(path)
    assert "model.npz" in str(err.value)


BAD_MOTIONS = [
    ("few_columns", lambda m: m.update(poses=m["poses"][:, :6]), "6 values per frame, the model's 3 joints need 9"),
    ("trans", lambda m: m.update(trans=m["trans"][:5]), r"trans has shape \(5, 3\), expected \(31, 3\)"),
    ("no_rate", lambda m: m.pop("mocap_framerate"), "no mocap_framerate; give `fps`"),
    ("rate", lambda m: m.update(mocap_framerate=np.float64(-30)), "frame rate -30 is not frames per second"),
    ("nan", lambda m: m["poses"].__setitem__((4, 4), np.nan), "poses has non-finite"),
    ("betas", lambda m: m.update(betas=np.zeros((3, 3))), "betas has shape"),
]


@pytest.mark.parametrize("case, change, message", BAD_MOTIONS, ids=[c[0] for c in BAD_MOTIONS])
def test_bad_motions_name_the_array(tmp_path, case, change, message):
    m = bend_motion()
    change(m)
    with pytest.raises(InputError, match=message):
        read_motion(write_npz(tmp_path / "motion.npz", m), 3, 2)


def test_newer_amass_frame_rate_key_and_fps_override(tmp_path):
    m = bend_motion()
    m["mocap_frame_rate"] = m.pop("mocap_framerate")
    assert read_motion(write_npz(tmp_path / "a.npz", m), 3, 2)[0].fps == 30.0
    assert read_motion(write_npz(tmp_path / "b.npz", m), 3, 2, fps=60.0)[0].fps == 60.0
