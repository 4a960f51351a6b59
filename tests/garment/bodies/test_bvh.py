"""The BVH reader: hierarchy, channel orders, sampling between frames, the CMU file, and
damaged files refused with the line and the fix."""

from __future__ import annotations

import numpy as np
import pytest

from garment.io.bvh import read_bvh
from garment.io.rotations import axis_angle_matrix, euler_matrix
from sim.errors import InputError

from tests.garment.bodies.synthetic import write_bvh, write_column_bvh
from tests.support.paths import ASSETS


def test_the_column_capture(tmp_path):
    clip = read_bvh(write_column_bvh(tmp_path / "m.bvh", frames=13, frame_time=1 / 60))
    assert clip.names == ["Root", "Mid", "Top"] and list(clip.parents) == [-1, 0, 1]
    assert clip.n_frames == 13 and clip.frame_time == pytest.approx(1 / 60) and clip.duration == pytest.approx(0.2)
    np.testing.assert_allclose(clip.rest_positions(), [[0, 0, 0], [0, 40, 0], [0, 80, 0]])
    np.testing.assert_allclose(clip.end_sites[2], [0, 10, 0])
    world, root = clip.sample(np.array([0.0, 0.5 / 60, 6 / 60]))
    np.testing.assert_allclose(root[1], 0.5 * (clip.values[0, :3] + clip.values[1, :3]))
    # Mid bends about Z: half way between frames 0 and 1 is half the angle (slerp).
    half = 0.5 * (clip.values[0, 6] + clip.values[1, 6])
    np.testing.assert_allclose(world[1, 1], axis_angle_matrix(np.radians([0.0, 0.0, half])), atol=1e-12)
    np.testing.assert_allclose(world[2, 2], world[2, 1], atol=1e-12)  # Top does not turn by itself


def test_channel_order_is_the_rotation_order(tmp_path):
    angles = np.array([[10.0, -25.0, 40.0]])
    for order in ("Xrotation Yrotation Zrotation", "Zrotation Xrotation Yrotation", "Yrotation Zrotation Xrotation"):
        chans = tuple(order.split())
        path = write_bvh(tmp_path / "o.bvh", ["A"], [-1], np.zeros((1, 3)), [chans], angles, 0.1)
        clip = read_bvh(path)
        expected = euler_matrix("".join(c[0].lower() for c in chans), angles[0])
        R = np.eye(3)
        for c, a in zip(chans, angles[0]):
            R = R @ axis_angle_matrix(np.radians(a) * np.eye(3)["XYZ".index(c[0])])
        np.testing.assert_allclose(clip.local_rotations(np.array([0]))[0, 0], R, atol=1e-12)
        np.testing.assert_allclose(expected, R, atol=1e-12)


def test_the_cmu_file():
    clip = read_bvh(ASSETS / "bodies" / "makehuman_cmu" / "01_01.bvh")
    assert len(clip.names) == 31 and clip.n_frames == 2752 and clip.values.shape == (2752, 96)
    assert clip.frame_time == pytest.approx(1 / 120, rel=1e-4)
    assert clip.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
    assert np.isfinite(clip.values).all()


CUT_HIERARCHY = "HIERARCHY\nROOT Hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition"


def _column(tmp_path):
    return write_column_bvh(tmp_path / "m.bvh").read_text()


BAD = [
    ("truncated_motion", lambda t: t[: len(t) * 2 // 3], "declares 13 frames but holds"),
    ("truncated_hierarchy", lambda t: CUT_HIERARCHY, "no MOTION section"),
    ("cut_in_hierarchy", lambda t: t.split("JOINT Top")[0] + "MOTION\nFrames: 1\nFrame Time: 0.1\n0\n",
     "the hierarchy ends early"),
    ("nan", lambda t: _sub_value(t, 3, 5, "nan"),
     r"m.bvh:\d+: frame 3 has a non-finite value"),
    ("word", lambda t: _sub_value(t, 2, 1, "abc"), r"m.bvh:\d+: frame 2: 'abc' is not a number"),
    ("short_line", lambda t: _drop_value(t, 4), r"m.bvh:\d+: frame 4 has 11 values, the hierarchy declares 12"),
    ("channel", lambda t: t.replace("Zrotation", "Wrotation", 1), "unknown channel 'Wrotation'"),
    ("duplicate", lambda t: t.replace("JOINT Top", "JOINT Mid"), "joint 'Mid' appears twice"),
    ("offset", lambda t: t.replace("OFFSET 0.000000000 40.000000000", "OFFSET 0.000000000 inf", 1),
     r"m.bvh:\d+: Mid OFFSET: non-finite number .inf."),
    ("frame_time", lambda t: t.replace("Frame Time: 0.016666667", "Frame Time: 30"), "frame time 30 s"),
    ("no_frames", lambda t: t.replace("Frames: 13", "Frames: 0"), "the clip has no frames"),
    ("extra_lines", lambda t: t + "1 " * 12 + "\n", "more lines than the 13 frames declared"),
    ("two_roots", lambda t: t.replace("MOTION", "ROOT B\n{\nOFFSET 0 0 0\nCHANNELS 0\n}\nMOTION"),
     "one skeleton per file"),
    ("brace", lambda t: t.replace("{", "(", 1), "expected '{'"),
]


def _sub_value(text: str, frame: int, column: int, value: str) -> str:
    head, motion = text.split("Frame Time:")
    lines = motion.split("\n")
    row = lines[1 + frame].split()
    row[column] = value
    lines[1 + frame] = " ".join(row)
    return head + "Frame Time:" + "\n".join(lines)


def _drop_value(text: str, frame: int) -> str:
    head, motion = text.split("Frame Time:")
    lines = motion.split("\n")
    lines[1 + frame] = " ".join(lines[1 + frame].split()[:-1])
    return head + "Frame Time:" + "\n".join(lines)


@pytest.mark.parametrize("case, change, message", BAD, ids=[c[0] for c in BAD])
def test_damaged_files_name_the_problem(tmp_path, case, change, message):
    path = tmp_path / "m.bvh"
    path.write_text(change(_column(tmp_path)))
    with pytest.raises(InputError, match=message) as err:
        read_bvh(path)
    assert "m.bvh" in str(err.value)


def test_binary_and_missing_files(tmp_path):
    (tmp_path / "b.bvh").write_bytes(b"HIERARCHY\n\xff\xfe")
    with pytest.raises(InputError, match="not a BVH text file"):
        read_bvh(tmp_path / "b.bvh")
    with pytest.raises(InputError, match="no such file"):
        read_bvh(tmp_path / "gone.bvh")
