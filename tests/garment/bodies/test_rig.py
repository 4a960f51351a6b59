"""MakeHuman-style rigs: the reader on a synthetic column (cubes, MEAN and VERTEX joints),
bad files refused with the file and the fix, and the unit and up-axis checks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from garment.io.rig import read_makehuman, rig_to_scene
from garment.io.rigged import check_person
from sim.errors import InputError

from tests.garment.bodies.synthetic import JOINT_Y, column_mesh, write_column_rig
from tests.support.paths import ASSETS

MH = ASSETS / "bodies" / "makehuman_cmu"


def test_the_column_rig(tmp_path):
    p = write_column_rig(tmp_path, unit=0.01)
    rig = read_makehuman(p["mesh"], "body", p["rig"], p["weights"])
    V, F = column_mesh()
    assert rig.names == ["Root", "Mid", "Top"] and list(rig.parents) == [-1, 0, 1]
    np.testing.assert_allclose(rig.vertices, V / 0.01, atol=1e-4)  # only the body group's vertices
    assert rig.faces.shape == F.shape
    np.testing.assert_allclose(rig.joints[:2, 1], np.array(JOINT_Y[:2]) / 0.01, atol=1e-6)  # cube centroids
    placed = rig_to_scene(rig, 0.01, "y", (1.0, 0.0, 0.0))
    np.testing.assert_allclose(placed.joints[1], [1.0, 0.0, 0.4], atol=1e-8)
    np.testing.assert_allclose(placed.tails[0], placed.joints[1], atol=1e-8)


def _edit_json(path, change):
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))


BAD = [
    ("weights_vertex", "weights", lambda d: d["weights"]["Mid"].append([5000, 0.5]),
     r"weights.json: bone 'Mid' weights vertex 5000, but the mesh has 418 vertices"),
    ("weights_bone", "weights", lambda d: d["weights"].update(Spine=[[0, 1.0]]),
     "weights for bone 'Spine', which the rig does not have"),
    ("weights_negative", "weights", lambda d: d["weights"]["Mid"].append([3, -1.0]), "negative weight -1"),
    ("weights_nan", "weights", lambda d: d["weights"]["Mid"].append([3, float("nan")]),
     "expected a list of \\[vertex, weight\\] number pairs"),
    ("unweighted", "weights", lambda d: d["weights"].update(Root=[]),
     r"weights.json: \d+ vertices of the body have no weight"),
    ("weights_format", "weights", lambda d: d.pop("weights"), "not MakeHuman weights"),
    ("cube", "rig", lambda d: d["Mid"]["head"].update(cube_name="joint-elbow"),
     "joint cube 'joint-elbow' is not a group of the mesh OBJ"),
    ("mean", "rig", lambda d: d["Top"]["head"].update(vertex_indices=[1, 99999]),
     "vertex 99999 is out of range"),
    ("strategy", "rig", lambda d: d["Top"]["tail"].update(strategy="GUESS"), "unknown strategy 'GUESS'"),
    ("parent", "rig", lambda d: d["Top"].update(parent="Neck"), "unknown parent 'Neck'"),
    ("cycle", "rig", lambda d: (d["Mid"].update(parent="Top")), "is not connected to the root"),
    ("two_roots", "rig", lambda d: d["Top"].update(parent=""), "exactly one root bone"),
    ("not_rig", "rig", lambda d: d.clear(), "not a MakeHuman rig"),
]


@pytest.mark.parametrize("case, which, change, message", BAD, ids=[c[0] for c in BAD])
def test_bad_rig_files_name_the_problem(tmp_path, case, which, change, message):
    p = write_column_rig(tmp_path)
    _edit_json(p[which], change)
    with pytest.raises(InputError, match=message) as err:
        read_makehuman(p["mesh"], "body", p["rig"], p["weights"])
    assert p[which].name in str(err.value)


def test_bad_meshes_and_groups(tmp_path):
    p = write_column_rig(tmp_path)
    with pytest.raises(InputError, match=r"no group 'torso' with faces \(groups: 'body', 'joint-root'"):
        read_makehuman(p["mesh"], "torso", p["rig"], p["weights"])
    with pytest.raises(InputError, match='helper groups .* give group = "body"'):
        read_makehuman(p["mesh"], None, p["rig"], p["weights"])
    text = p["mesh"].read_text()
    p["mesh"].write_text(text.replace("v ", "v nan ", 1))
    with pytest.raises(InputError, match=r"body.obj:1: non-finite vertex coordinate"):
        read_makehuman(p["mesh"], "body", p["rig"], p["weights"])
    p["mesh"].write_text(text + "f 1 2 99999\n")
    with pytest.raises(InputError, match=r"body.obj:\d+: face index 99999 is out of range"):
        read_makehuman(p["mesh"], "body", p["rig"], p["weights"])
    p["mesh"].write_text(text)
    p["rig"].write_bytes(b"\x00\xff not json")
    with pytest.raises(InputError, match="rig.json: not a rig JSON"):
        read_makehuman(p["mesh"], "body", p["rig"], p["weights"])


def test_units_and_up_axis_are_checked_with_the_fix():
    rig = read_makehuman(MH / "body.obj", "body", MH / "rig.cmu_mb.json", MH / "weights.cmu_mb.json")
    with pytest.raises(InputError, match=r"body.obj: the body is 16.7 m across after scale = 1, not a person's .*"
                                         r"looks like decimetres \(MakeHuman's unit\): set scale = 0.1"):
        check_person(MH / "body.obj", rig_to_scene(rig, 1.0, "z", (0, 0, 0)).vertices, 1.0, None)
    with pytest.raises(InputError, match="167 m across after scale = 10.*looks like centimetres: set scale = 0.1$"):
        check_person(MH / "body.obj", rig_to_scene(rig, 10.0, "z", (0, 0, 0)).vertices, 10.0, None)
    with pytest.raises(InputError, match='it looks Y-up; set `up = "y"`'):
        check_person(MH / "body.obj", rig_to_scene(rig, 0.1, "z", (0, 0, 0)).vertices, 0.1, None)
    check_person(MH / "body.obj", rig_to_scene(rig, 0.1, "y", (0, 0, 0)).vertices, 0.1, None)
