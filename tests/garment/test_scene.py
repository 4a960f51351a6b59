"""Scene files: parsing, defaults, material merging, patches and validation errors."""

from __future__ import annotations

import math
import pickle
import tomllib
from pathlib import Path

import numpy as np
import pytest

import garment.scene as scene_module
from garment.build import build_simulator
from sim.materials import PRESETS, Material
from sim.newton import EXTRAPOLATE
from garment.scene import (
    ClothSpec,
    ContactSpec,
    LoadSpec,
    OutputSpec,
    Perturbation,
    PinSpec,
    Scene,
    SceneError,
    SewingSpec,
    TimeSpec,
    load_scene,
    loads_scene,
    parse_scene,
)
from garment.scene.schema import schema

from tests.support.paths import ROOT

FULL = """\
[scene]
name = "hanging"
description = "free text"

[material]
preset = "cotton"
E_st = 2e6
E_sh = 1e4
E_bd = 8e3
nu = 0.243
h = 3.18e-4
rho = 472.6
membrane = "fbw"
quadrature = "reduced"

[[cloth]]
name = "sheet"
size = [1.0, 1.0]
control_points = [25, 25]
origin = [-0.5, 0.0, 1.0]
axis_u = [1, 0, 0]
axis_v = [0, 0, -1]
[cloth.material]
[cloth.perturbation]
amplitude = 0.02
waves = [0, 1]

[[pin]]
cloth = "sheet"
corners = ["u0v0", "u1v0"]
velocity = [0.5, 0, 0]
duration = 0.1

[load]
gravity = [0, 0, -9.81]
pressure = 0.0
start = 0.0
ramp = 0.0

[time]
dt = 0.01
frames = 100
steps_per_frame = 1
newton_tol = 1e-2
max_newton_iterations = 100
mode = "dynamic"

[output]
rrd = "out/hanging.rrd"
mesh_dir = "out/hanging_frames"
mesh_format = "npz"
mesh_resolution = [50, 50]
"""

CLOTH = """\
[[cloth]]
size = [1.0, 1.0]
control_points = [5, 5]
"""


def write(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --------------------------------------------------------------------------- valid scenes


def test_full_scene(tmp_path):
    path = write(tmp_path, FULL)
    scene = load_scene(path)

    assert scene.name == "hanging"
    assert scene.description == "free text"
    assert scene.path == path
    assert len(scene.cloths) == 1
    cloth = scene.cloths[0]
    assert cloth == ClothSpec(
        name="sheet",
        size=(1.0, 1.0),
        control_points=(25, 25),
        origin=(-0.5, 0.0, 1.0),
        axis_u=(1.0, 0.0, 0.0),
        axis_v=(0.0, 0.0, -1.0),
        material=PRESETS["cotton"],
        perturbation=Perturbation(amplitude=0.02, waves=(0, 1)),
    )
    assert scene.pins == [
        PinSpec(cloth="sheet", corners=("u0v0", "u1v0"), velocity=(0.5, 0.0, 0.0), duration=0.1)
    ]
    assert scene.load == LoadSpec(gravity=(0.0, 0.0, -9.81), pressure=0.0)
    assert scene.time == TimeSpec(newton_extrapolate=EXTRAPOLATE)  # no friction: the doublings default
    assert scene.output == OutputSpec(
        rrd=Path("out/hanging.rrd"),
        mesh_dir=Path("out/hanging_frames"),
        mesh_format="npz",
        mesh_resolution=(50, 50),
    )
    # Output paths stay relative to the current directory, not the scene file.
    assert not scene.output.rrd.is_absolute()


ASSETS = ROOT / "assets"


def _with(text: str, after: dict[str, str]) -> str:
    """``text`` with each line ``after[line]`` inserted after ``line``."""
    for line, added in after.items():
        assert line + "\n" in text
        text = text.replace(line + "\n", f"{line}\n{added}\n", 1)
    return text


# FULL plus every other key of every table (test_every_key_example_covers_the_schema).
EVERY_KEY = _with(FULL, {
    "axis_v = [0, 0, -1]": "velocity = [0, 0, 0.1]",
    "[cloth.material]": "E_bd = 1e4",
    'corners = ["u0v0", "u1v0"]': "sides = []\nbox = [[0.0, 0.0], [1.0, 0.1]]\ndepth = 1\nstart = 0.0",
    "pressure = 0.0": "pressure_direction = [0, 0, 1]",
    'mode = "dynamic"': 'newton_extrapolate = 0\nnewton_relative_tol = 0.0\npreroll = 0.1\nsewing = "quasistatic"\nsettle_drag = 0.0',
}) + f"""
[[obstacle]]
name = "ball"
inset = 0.001
[obstacle.sphere]
center = [0, 0, 0.5]
radius = 0.2
subdivisions = 2
[obstacle.spin]
axis = [0, 0, 2]
center = [0, 0, 0]
speed = 1.0
start = 0.0
ramp = 0.1

[[obstacle]]
[obstacle.plane]
point = [0, 0, -1]
normal = [0, 0, 1]
size = 4.0

[[obstacle]]
mesh = "{ASSETS / 'bodies' / 'mean_all.obj'}"
scale = 1.0
up = "y"
translate = [0, 0, 0.75]
raise_arms = 20.0

[[obstacle]]
animation = "{ASSETS / 'bodies' / 'rumba_dancing_121f.npz'}"
fps = 25.0

[[obstacle]]
scale = 0.1
up = "y"
fps = 120.0
blend = 0.05
[obstacle.skin]
mesh = "{ASSETS / 'bodies' / 'makehuman_cmu' / 'body.obj'}"
group = "body"
rig = "{ASSETS / 'bodies' / 'makehuman_cmu' / 'rig.cmu_mb.json'}"
weights = "{ASSETS / 'bodies' / 'makehuman_cmu' / 'weights.cmu_mb.json'}"
motion = "{ASSETS / 'bodies' / 'makehuman_cmu' / '01_01.bvh'}"
joints = [["LeftHandFinger1", "LFingers"], ["LeftShoulder", ""]]
start = 3.5
end = 6.5

[[obstacle]]
[obstacle.smpl]  # no SMPL model ships: any existing files do for reading the keys
model = "{ASSETS / 'bodies' / 'rumba_dancing_121f.npz'}"
motion = "{ASSETS / 'bodies' / 'rumba_dancing_121f.npz'}"
start = 0.5
end = 1.5

[contact]
enabled = true
dhat = 1e-3
kappa = "adaptive"
mu = 0.1
eps_v = 1e-3
self_contact = true
seams = "merge"
mesh_density = 2.0

[[garment]]
name = "dress"
source = "{ASSETS / 'garments' / 'dress_knife.obj'}"
knot_span_mm = 40
seam_span_mm = 8
fold_pleats = true
pleat_wait = true
seam_stiffness = 1e5
[garment.material]
nu = 0.3
[garment.placement]
file = "{ASSETS / 'garments' / 'dress_knife.obj'}"
scale = 1.0
up = "z"
translate = [0, 0, 0]

[sewing]
ramp_start = 20.0
multiplier_step = 1.5
block_reach = 8.0
held_fraction = 0.05
pleat_wait_gap_mm = 2.5
pleat_wait_end = 0.4
"""


def test_every_key_example_is_valid():
    scene = loads_scene(EVERY_KEY)
    assert scene.cloths[0].material.E_bd == 1e4
    assert scene.pins[0].box == ((0.0, 0.0), (1.0, 0.1))
    assert scene.load.pressure_direction == (0.0, 0.0, 1.0)
    assert [o.kind for o in scene.obstacles] == ["sphere", "plane", "mesh", "animation", "skin", "smpl"]
    assert scene.obstacles[4].skin.joints == (("LeftHandFinger1", "LFingers"), ("LeftShoulder", ""))
    assert scene.obstacles[5].smpl.end == 1.5
    assert scene.obstacles[0].spin.axis == (0.0, 0.0, 1.0)
    assert scene.contact.adaptive_kappa and scene.contact.kappa == ContactSpec().kappa
    assert scene.sewing == SewingSpec(20.0, 1.5, 8.0, 0.05, 2.5e-3, 0.4)
    assert (scene.garments[0].knot_span, scene.garments[0].seam_span) == (0.04, 0.008)


def test_every_key_example_covers_the_schema():
    def written(data, dotted=""):
        for name, value in data.items():
            yield dotted + name
            for table in value if isinstance(value, list) else [value]:
                if isinstance(table, dict):
                    yield from written(table, f"{dotted}{name}.")

    seen = set()  # [cloth.material] has the keys of [material]: written once is enough

    def declared(keys, dotted=""):
        for k in keys:
            yield dotted + k.name
            if k.sub is not None and id(k.sub) not in seen:
                seen.add(id(k.sub))
                yield from declared(k.sub.keys, f"{dotted}{k.name}.")

    assert set(declared(schema(Scene).keys)) - set(written(tomllib.loads(EVERY_KEY))) == set()


def test_module_docstring_points_at_the_reference():
    assert "docs/scene-reference.md" in scene_module.__doc__


def test_sewing_defaults_and_millimetres():
    assert loads_scene(CLOTH).sewing == SewingSpec()
    assert SewingSpec() == SewingSpec(ramp_start=10.0, multiplier_step=2.0, block_reach=10.0, held_fraction=0.01,
                                      pleat_wait_gap=3e-3, pleat_wait_end=None)
    sewing = loads_scene(CLOTH + "[sewing]\npleat_wait_gap_mm = 5\nheld_fraction = 0\n").sewing
    assert sewing == SewingSpec(pleat_wait_gap=5e-3, held_fraction=0.0)
    assert isinstance(sewing.held_fraction, float)


def test_defaults(tmp_path):
    scene = load_scene(write(tmp_path, CLOTH, "drape.toml"))
    assert scene.name == "drape"
    assert scene.description == ""
    assert scene.cloths == [ClothSpec(name="cloth0", size=(1.0, 1.0), control_points=(5, 5))]
    assert scene.cloths[0].material == PRESETS["cotton"]
    assert scene.pins == []
    assert scene.load == LoadSpec()
    assert scene.time == TimeSpec(newton_extrapolate=EXTRAPOLATE)
    assert scene.output == OutputSpec()


def test_loads_and_parse_without_file():
    scene = loads_scene(CLOTH)
    assert scene.path is None and scene.name == "scene"
    assert parse_scene({"cloth": [{"size": [2, 1], "control_points": [5, 6]}]}).cloths[0].size == (
        2.0,
        1.0,
    )


def test_material_preset_then_overrides_then_per_cloth():
    scene = loads_scene(
        """
        [material]
        preset = "cotton"
        E_sh = 2e6
        membrane = "stvk"

        [[cloth]]
        name = "a"
        size = [1, 1]
        control_points = [5, 5]

        [[cloth]]
        name = "b"
        size = [1, 1]
        control_points = [3, 3]
        [cloth.material]
        h = 1e-3
        quadrature = "gauss2"
        """
    )
    cotton = PRESETS["cotton"]
    a, b = scene.cloths
    assert a.material == cotton.with_(E_sh=2e6, membrane="stvk")
    assert b.material == cotton.with_(E_sh=2e6, membrane="stvk", h=1e-3, quadrature="gauss2")
    assert isinstance(a.material.E_sh, float)


def test_several_cloths_default_names_and_pin_defaults():
    scene = loads_scene(
        CLOTH
        + CLOTH
        + """
        [[pin]]
        cloth = "cloth1"
        sides = ["v1", "u0"]
        box = [[0, 0.5], [0.25, 0.5]]
        depth = 2
        start = 0.5
        duration = inf
        """
    )
    assert [c.name for c in scene.cloths] == ["cloth0", "cloth1"]
    pin = scene.pins[0]
    assert pin == PinSpec(
        cloth="cloth1", sides=("v1", "u0"), box=((0.0, 0.5), (0.25, 0.5)), depth=2, start=0.5
    )
    assert math.isinf(pin.duration)


def test_pin_cloth_may_be_omitted_with_one_cloth():
    scene = loads_scene(CLOTH + '[[pin]]\ncorners = ["u1v1"]\n')
    assert scene.pins[0].cloth == "cloth0"
    assert scene.pins[0].duration == math.inf


def test_pressure_direction_is_normalised():
    scene = loads_scene(CLOTH + "[load]\npressure = 5\npressure_direction = [0, 3, 4]\n")
    assert scene.load.pressure == 5.0
    assert scene.load.pressure_direction == pytest.approx((0.0, 0.6, 0.8))


# --------------------------------------------------------------------------- patches


def test_patch_flat_sheet_lies_in_its_plane():
    origin = np.array([-0.5, 0.2, 1.0])
    au, av = np.array([1.0, 1.0, 0.0]), np.array([0.0, 0.0, -2.0])
    cloth = ClothSpec("s", (2.0, 1.0), (7, 5), tuple(origin), tuple(au), tuple(av))
    patch = cloth.patch()
    assert patch.shape == (7, 5)
    assert patch.rest.shape == (7, 5, 2) and patch.world.shape == (7, 5, 3)
    normal = np.cross(au, av)
    normal /= np.linalg.norm(normal)
    np.testing.assert_allclose(cloth.normal, normal)
    np.testing.assert_allclose((patch.world - origin) @ normal, 0.0, atol=1e-12)
    # The corners span the rectangle of the given size along the unit axes.
    np.testing.assert_allclose(patch.world[0, 0], origin)
    np.testing.assert_allclose(patch.world[-1, 0], origin + 2.0 * au / np.linalg.norm(au))
    np.testing.assert_allclose(patch.world[0, -1], origin + 1.0 * av / np.linalg.norm(av))


@pytest.mark.parametrize("waves", [(1, 1), (2, 3), (0, 1), (0, 0)])
def test_patch_perturbation_moves_along_the_normal(waves):
    amplitude = 0.02
    flat = ClothSpec("s", (1.0, 2.0), (25, 25), (0, 0, 1), (1, 0, 0), (0, 0, -1))
    bumpy = ClothSpec(**{**vars(flat), "perturbation": Perturbation(amplitude, waves)})
    offset = bumpy.patch().world - flat.patch().world
    normal = np.array([0.0, 1.0, 0.0])  # cross((1,0,0), (0,0,-1))
    np.testing.assert_allclose(offset - (offset @ normal)[..., None] * normal, 0.0, atol=1e-15)
    along = offset @ normal
    rest = flat.patch().rest
    s, t = rest[..., 0] / 1.0, rest[..., 1] / 2.0
    expected = amplitude * np.ones_like(s)
    for w, x in zip(waves, (s, t)):
        if w:
            expected = expected * np.sin(np.pi * w * x)
    np.testing.assert_allclose(along, expected, atol=1e-15)
    # Odd nets put control points at s = t = 0.5, so a single bump reaches the amplitude.
    if waves in ((1, 1), (0, 1), (0, 0)):
        assert np.abs(along).max() == pytest.approx(amplitude)
    assert np.abs(along).max() <= amplitude + 1e-15


# --------------------------------------------------------------------------- errors

PIN = '[[pin]]\ncorners = ["u0v0"]\n'

ERRORS = {
    # id: (scene text, dotted key, text the problem must contain)
    "unknown key with suggestion": (
        CLOTH + "[time]\ndtt = 0.01\n",
        "time.dtt",
        "unknown key 'dtt' (did you mean 'dt'?)",
    ),
    "unknown top-level table": (CLOTH + "[simulation]\n", "simulation", "unknown key"),
    "unknown cloth key": (CLOTH + "colour = 'red'\n", "cloth[0].colour", "unknown key"),
    "unknown perturbation key": (
        CLOTH + "[cloth.perturbation]\namplitude = 1\nwaves = [1, 1]\nphase = 0\n",
        "cloth[0].perturbation.phase",
        "unknown key",
    ),
    "bool for number": (CLOTH + "[time]\ndt = true\n", "time.dt", "must be a number"),
    "string for number": (CLOTH + "[load]\npressure = '1'\n", "load.pressure", "must be a number"),
    "nan": (CLOTH + "[load]\npressure = nan\n", "load.pressure", "finite"),
    "nan in vector": (CLOTH + "[load]\ngravity = [0, nan, 0]\n", "load.gravity[1]", "finite"),
    "inf outside duration": (CLOTH + "[time]\ndt = inf\n", "time.dt", "finite"),
    "nan duration": (CLOTH + PIN + "duration = nan\n", "pin[0].duration", "finite"),
    "float for int": (
        "[[cloth]]\nsize = [1, 1]\ncontrol_points = [5.0, 5]\n",
        "cloth[0].control_points[0]",
        "must be an integer",
    ),
    "bool for int": (CLOTH + "[time]\nframes = false\n", "time.frames", "must be an integer"),
    "wrong array length": (
        "[[cloth]]\nsize = [1, 1, 1]\ncontrol_points = [5, 5]\n",
        "cloth[0].size",
        "2 entries",
    ),
    "scalar for array": (CLOTH + "origin = 0\n", "cloth[0].origin", "must be an array"),
    "missing size": ("[[cloth]]\ncontrol_points = [5, 5]\n", "cloth[0].size", "missing"),
    "negative size": (
        "[[cloth]]\nsize = [-1, 1]\ncontrol_points = [5, 5]\n",
        "cloth[0].size[0]",
        "must be > 0",
    ),
    "zero E_st": (CLOTH + "[material]\nE_st = 0\n", "material.E_st", "must be > 0"),
    "negative E_sh": (CLOTH + "[material]\nE_sh = -1\n", "material.E_sh", "must be >= 0"),
    "zero rho": (CLOTH + "[material]\nrho = 0\n", "material.rho", "must be > 0"),
    "zero per-cloth thickness": (
        CLOTH + "[cloth.material]\nh = 0\n",
        "cloth[0].material.h",
        "must be > 0",
    ),
    "zero dt": (CLOTH + "[time]\ndt = 0\n", "time.dt", "must be > 0"),
    "zero newton_tol": (CLOTH + "[time]\nnewton_tol = 0.0\n", "time.newton_tol", "> 0"),
    "zero frames": (CLOTH + "[time]\nframes = 0\n", "time.frames", "must be >= 1"),
    "negative extrapolation": (CLOTH + "[time]\nnewton_extrapolate = -1\n", "time.newton_extrapolate", "must be >= 0"),
    "nu = 0.5": (CLOTH + "[material]\nnu = 0.5\n", "material.nu", "must be in (-1, 0.5)"),
    "nu = -1": (CLOTH + "[material]\nnu = -1\n", "material.nu", "must be in (-1, 0.5)"),
    "reduced quadrature net too small": (
        "[[cloth]]\nsize = [1, 1]\ncontrol_points = [4, 10]\n",
        "cloth[0].control_points",
        "'reduced' needs at least 5 x 5",
    ),
    "gauss2 net too small": (
        "[material]\nquadrature = 'gauss2'\n[[cloth]]\nsize = [1, 1]\ncontrol_points = [3, 2]\n",
        "cloth[0].control_points",
        "'gauss2' needs at least 3 x 3",
    ),
    "unknown preset": (CLOTH + "[material]\npreset = 'silk'\n", "material.preset", "'cotton'"),
    "unknown membrane": (
        CLOTH + "[material]\nmembrane = 'neohookean'\n",
        "material.membrane",
        "'fbw', 'stvk'",
    ),
    "unknown quadrature": (
        CLOTH + "[cloth.material]\nquadrature = 'gauss4'\n",
        "cloth[0].material.quadrature",
        "'reduced', 'gauss2', 'gauss3'",
    ),
    "unknown mode": (CLOTH + "[time]\nmode = 'static'\n", "time.mode", "'quasistatic'"),
    "unknown seam contact": (CLOTH + "[contact]\nseams = 'weld'\n", "contact.seams", "'merge', 'band'"),
    "zero contact mesh density": (CLOTH + "[contact]\nmesh_density = 0\n", "contact.mesh_density", "> 0"),
    "unknown mesh format": (
        CLOTH + "[output]\nmesh_format = 'stl'\n",
        "output.mesh_format",
        "'npz', 'obj', 'ply'",
    ),
    "mesh resolution too small": (
        CLOTH + "[output]\nmesh_resolution = [1, 10]\n",
        "output.mesh_resolution[0]",
        "must be >= 2",
    ),
    "zero axis": (CLOTH + "axis_u = [0, 0, 0]\n", "cloth[0].axis_u", "non-zero"),
    "axes not orthogonal": (CLOTH + "axis_v = [1, 1, 0]\n", "cloth[0].axis_v", "orthogonal"),
    "negative waves": (
        CLOTH + "[cloth.perturbation]\namplitude = 0.01\nwaves = [-1, 1]\n",
        "cloth[0].perturbation.waves[0]",
        ">= 0",
    ),
    "unknown corner": ('[[pin]]\ncorners = ["u0v2"]\n', "pin[0].corners[0]", "'u1v1'"),
    "unknown side": ('[[pin]]\nsides = ["u2"]\n', "pin[0].sides[0]", "'v1'"),
    "duplicate corner": ('[[pin]]\ncorners = ["u0v0", "u0v0"]\n', "pin[0].corners[1]", "duplicate"),
    "pin to unknown cloth": (PIN + 'cloth = "shirt"\n', "pin[0].cloth", "unknown cloth 'shirt'"),
    "pin without cloth among several": (
        CLOTH + CLOTH + PIN,
        "pin[0].cloth",
        "several cloths",
    ),
    "pin selects nothing": ("[[pin]]\ndepth = 2\n", "pin[0]", "corners, sides, box"),
    "pin box outside [0, 1]": (
        "[[pin]]\nbox = [[0, 0], [1.5, 1]]\n",
        "pin[0].box[1][0]",
        "must be in [0, 1]",
    ),
    "pin box min > max": ("[[pin]]\nbox = [[0, 0.6], [1, 0.5]]\n", "pin[0].box", "v_min"),
    "pin depth 0": (PIN + "depth = 0\n", "pin[0].depth", ">= 1"),
    "pin negative start": (PIN + "start = -1\n", "pin[0].start", ">= 0"),
    "pin zero duration": (PIN + "duration = 0\n", "pin[0].duration", "> 0"),
    "duplicate cloth names": (
        CLOTH + "name = 'cloth1'\n" + CLOTH,
        "cloth[1].name",
        "duplicate cloth name 'cloth1'",
    ),
    "no cloth": ("[time]\ndt = 0.01\n", "cloth", "at least one [[cloth]]"),
    "cloth as plain table": ("[cloth]\nsize = [1, 1]\n", "cloth", "array of tables"),
    "empty output path": (CLOTH + "[output]\nrrd = ''\n", "output.rrd", "empty"),
    "unknown sewing key": (
        CLOTH + "[sewing]\npleat_wait_gap = 3\n",
        "sewing.pleat_wait_gap",
        "unknown key 'pleat_wait_gap' (did you mean 'pleat_wait_gap_mm'?)",
    ),
    "zero ramp start": (CLOTH + "[sewing]\nramp_start = 0\n", "sewing.ramp_start", "must be > 0, got 0"),
    "held fraction above 1": (CLOTH + "[sewing]\nheld_fraction = 1.5\n", "sewing.held_fraction", "must be in [0, 1]"),
    "negative pleat wait end": (CLOTH + "[sewing]\npleat_wait_end = -0.1\n", "sewing.pleat_wait_end", ">= 0"),
    "zero pleat wait gap": (CLOTH + "[sewing]\npleat_wait_gap_mm = 0\n", "sewing.pleat_wait_gap_mm", "> 0"),
    "nan multiplier step": (CLOTH + "[sewing]\nmultiplier_step = nan\n", "sewing.multiplier_step", "finite"),
    "string block reach": (CLOTH + "[sewing]\nblock_reach = '10'\n", "sewing.block_reach", "must be a number"),
    "sewing as array": ("sewing = [1]\n" + CLOTH, "sewing", "must be a table"),
}


@pytest.mark.parametrize(("text", "key", "problem"), ERRORS.values(), ids=ERRORS.keys())
def test_invalid_scene(tmp_path, text, key, problem):
    # Scenes whose pins come first still need a cloth, after the pins.
    if "[[cloth]]" not in text and key != "cloth":
        text = text + CLOTH
    path = write(tmp_path, text, "broken.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    error = info.value
    message = str(error)
    assert error.key == key
    assert error.file == path
    assert message.startswith(f"{path}: {key}: ")
    assert str(path) in message and key in message
    assert problem in error.problem


def test_missing_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == "<file>"
    assert str(path) in str(info.value) and "no such file" in str(info.value)


def test_toml_syntax_error(tmp_path):
    path = write(tmp_path, CLOTH + "[time]\ndt = = 1\n", "syntax.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == "<toml>"
    assert str(path) in str(info.value) and "line 5" in str(info.value)


def test_error_from_string_names_the_source():
    expected = r"^<string>: material\.nu: must be in \(-1, 0\.5\), got 0\.7$"
    with pytest.raises(SceneError, match=expected):
        loads_scene(CLOTH + "[material]\nnu = 0.7\n")


def test_scene_error_is_a_value_error_and_pickles():
    error = SceneError("a.toml", "time.dt", "must be > 0, got 0")
    assert isinstance(error, ValueError)
    copy = pickle.loads(pickle.dumps(error))
    assert (copy.file, copy.key, copy.problem, str(copy)) == (
        "a.toml",
        "time.dt",
        "must be > 0, got 0",
        str(error),
    )


def test_newton_extrapolate_reaches_the_solver(tmp_path):
    scene = load_scene(write(tmp_path, CLOTH + "[time]\nnewton_extrapolate = 3\nnewton_tol = 0.02\n"
                                                 "newton_relative_tol = 0.1\n"))
    opts = build_simulator(scene).model.newton
    assert (opts.extrapolate, opts.tol, opts.relative_tol) == (3, 0.02, 0.1)
    plain = build_simulator(load_scene(write(tmp_path, CLOTH, "plain.toml"))).model.newton
    assert (plain.extrapolate, plain.relative_tol) == (EXTRAPOLATE, 0.0)


def test_doublings_default_off_inside_a_narrow_friction_band(tmp_path):
    # Doublings pay on buckling and with a 1 cm/s band; with a 1 mm/s band they cost more.
    def doublings(contact):
        return load_scene(write(tmp_path, CLOTH + contact, "c.toml")).time.newton_extrapolate

    assert doublings("") == EXTRAPOLATE
    assert doublings("[contact]\nmu = 0.2\neps_v = 1e-3\n") == 0
    assert doublings("[contact]\nmu = 0.2\neps_v = 1e-2\n") == EXTRAPOLATE
    assert doublings("[contact]\nmu = 0.0\neps_v = 1e-3\n") == EXTRAPOLATE
    assert doublings("[contact]\nmu = 0.2\neps_v = 1e-3\n[time]\nnewton_extrapolate = 2\n") == 2


def test_material_default_is_cotton():
    assert ClothSpec("x", (1, 1), (5, 5)).material == Material()


def test_loads_start_late_and_ramp_in():
    """[load] start and ramp: no gravity before `start` (the cloth stays where it is), then
    a linear ramp; the free cloth's drop follows implicit Euler under the ramped g."""
    from garment.build import build_simulator

    sim = build_simulator(loads_scene(CLOTH + "[load]\nstart = 0.05\nramp = 0.02\n[time]\ndt = 0.01\n"))
    C0 = sim.state.C.copy()
    for _ in range(5):
        sim.step()
    assert np.abs(sim.state.C - C0).max() == 0.0
    for _ in range(13):  # to t = 0.18 s
        sim.step()
    # Implicit Euler of a free fall, loads evaluated at the end of each step.
    v = x = 0.0
    for k in range(1, 19):
        v += 0.01 * 9.81 * min(max((0.01 * k - 0.05) / 0.02, 0.0), 1.0)
        x += 0.01 * v
    drop = C0[:, 2].mean() - sim.state.C[:, 2].mean()
    assert drop == pytest.approx(x, rel=1e-6)
