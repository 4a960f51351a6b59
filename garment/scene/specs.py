"""What a scene file says, as dataclasses; each field that is a TOML key declares it here
(schema.key: meaning, unit, bounds, choices), once. docs/scene-reference.md is generated
from these declarations (python -m garment.scene.reference --write)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.materials import MEMBRANE_MODELS, MIN_CONTROL_POINTS, PRESETS, QUADRATURES, Material
from sim.newton import EXTRAPOLATE, EXTRAPOLATE_MIN_EPS_V
from sim.patches import Patch
from garment.scene.schema import Key, declare, key

CORNERS = ("u0v0", "u1v0", "u0v1", "u1v1")
SIDES = ("u0", "u1", "v0", "v1")
TIME_MODES = ("dynamic", "quasistatic")
SEWING_MODES = ("dynamic", "quasistatic")
MESH_FORMATS = ("npz", "obj", "ply")
UP_AXES = ("y", "z")
SEAM_CONTACT = ("merge", "band")
OBSTACLE_KINDS = ("mesh", "animation", "sphere", "plane", "skin", "smpl")
RIGGED_KINDS = ("skin", "smpl")  # bodies posed from a skeleton's motion (garment/io/rigged.py)
MOVING_KINDS = ("animation",) + RIGGED_KINDS
FILE_KINDS = ("mesh",) + MOVING_KINDS  # obstacles read from a file: scaled, turned and moved


# The keys of sim.materials.Material, which knows nothing of scene files.
declare(
    preset=Key(
        "a preset applied first; the other keys override it", hint=str, choices=tuple(PRESETS),
        default_text='none: [material] starts from "cotton", a cloth\'s or garment\'s from [material]',
    ),
    E_st=Key("stretch modulus", unit="Pa", gt=0),
    E_sh=Key("shear modulus", unit="Pa", ge=0),
    E_bd=Key("bending modulus", unit="Pa", ge=0),
    nu=Key("Poisson ratio", gt=-1, lt=0.5),
    h=Key("thickness", unit="m", gt=0, plausible=(None, 0.1)),
    rho=Key("density", unit="kg/m^3", gt=0),
    membrane=Key('membrane energy; "none": bending only', choices=MEMBRANE_MODELS),
    quadrature=Key(
        "quadrature rule; a cloth's control net needs at least "
        + ", ".join(f"{n} x {n} points ({q})" for q, n in MIN_CONTROL_POINTS.items()),
        choices=QUADRATURES,
    ),
)(Material)

_MATERIAL_OVERRIDES = "overrides applied on top of [material] (or of this table's own preset)"


@dataclass
class Perturbation:
    """Initial out-of-plane offset: amplitude * sin(pi waves[0] s) * sin(pi waves[1] t)."""

    amplitude: float = key(doc="offset along the normal: amplitude * sin(pi wu s) * sin(pi wv t)", unit="m",
                           required=True)
    waves: tuple[int, int] = key(doc="(wu, wv); 0 means a factor of 1 in that direction", ge=0, required=True)


@dataclass
class ClothSpec:
    """A flat rectangular cloth; see :meth:`patch`."""

    name: str = key(doc="unique name", default_text='"cloth0", "cloth1", ... by position')
    size: tuple[float, float] = key(doc="width along axis_u and height along axis_v", unit="m", gt=0, required=True,
                                    plausible=(None, 20.0))
    control_points: tuple[int, int] = key(doc="control net n x m", ge=1, required=True)
    origin: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="world position of the (u, v) = (0, 0) corner",
                                             unit="m")
    axis_u: tuple[float, float, float] = key((1.0, 0.0, 0.0), doc="world direction of u; non-zero")
    axis_v: tuple[float, float, float] = key((0.0, 1.0, 0.0),
                                             doc="world direction of v; non-zero, orthogonal to axis_u")
    material: Material = key(PRESETS["cotton"], doc=_MATERIAL_OVERRIDES)
    perturbation: Perturbation | None = key(None, doc="optional: offset the control points along the normal")
    velocity: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="initial velocity", unit="m/s")

    @property
    def normal(self) -> np.ndarray:
        """Unit normal cross(axis_u, axis_v) of the flat sheet."""
        au = np.asarray(self.axis_u, float) / np.linalg.norm(self.axis_u)
        av = np.asarray(self.axis_v, float) / np.linalg.norm(self.axis_v)
        n = np.cross(au, av)
        return n / np.linalg.norm(n)

    def patch(self) -> Patch:
        """The cloth's patch, with the perturbation (if any) applied to the world points."""
        patch = Patch.rectangle(
            self.name, self.size, self.control_points, self.origin, self.axis_u, self.axis_v
        )
        if self.perturbation is not None:
            s = patch.rest[..., 0] / self.size[0]
            t = patch.rest[..., 1] / self.size[1]
            wu, wv = self.perturbation.waves
            offset = self.perturbation.amplitude * _wave(wu, s) * _wave(wv, t)
            patch.world += offset[..., None] * self.normal
        return patch


def _wave(waves: int, x: np.ndarray) -> np.ndarray:
    """sin(pi waves x), or 1 when waves == 0."""
    return np.sin(np.pi * waves * x) if waves else np.ones_like(x)


@dataclass
class PinSpec:
    """Control points of one cloth held in place (or moved at constant velocity)."""

    cloth: str = key(doc="the cloth pinned", default_text="the only cloth; required when there are several")
    corners: tuple[str, ...] = key((), doc="corners pinned", choices=CORNERS)
    sides: tuple[str, ...] = key((), doc="sides pinned; u0 is the side where u = 0", choices=SIDES)
    box: tuple[tuple[float, float], tuple[float, float]] | None = key(
        None, doc="control points in [[u_min, v_min], [u_max, v_max]] of the normalised (u, v) square", ge=0, le=1
    )
    depth: int = key(1, doc="rows of control points pinned from a side or corner; 2 also clamps the rotation", ge=1)
    velocity: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="pinned points move with it while active",
                                               unit="m/s")
    start: float = key(0.0, doc="time the pin starts", unit="s", ge=0)
    duration: float = key(math.inf, doc="time the pin holds (TOML `inf` is accepted here only)", unit="s", gt=0,
                          allow_inf=True)


@dataclass
class LoadSpec:
    gravity: tuple[float, float, float] = key((0.0, 0.0, -9.81), doc="gravitational acceleration", unit="m/s^2")
    pressure: float = key(0.0, doc="dead load per unit rest area", unit="Pa")
    pressure_direction: tuple[float, float, float] | None = key(
        None, doc="direction of the pressure (normalised)", normalise=True, default_text="each cloth's normal"
    )
    start: float = key(0.0, doc="gravity and pressure are off before this time (a garment sewn weightless)",
                       unit="s", ge=0)
    ramp: float = key(0.0, doc="then they ramp in linearly over this time", unit="s", ge=0)


@dataclass
class TimeSpec:
    dt: float = key(0.01, doc="time step", unit="s", gt=0)
    frames: int = key(100, doc="frames simulated", ge=1)
    steps_per_frame: int = key(1, doc="time steps per frame", ge=1)
    newton_tol: float = key(1e-2, doc="Newton stops when ||dC||_inf / dt < newton_tol", unit="m/s", gt=0)
    newton_relative_tol: float = key(
        0.0, ge=0, doc="Newton may stop at this fraction of the step's RMS control-point speed instead "
        "(0: newton_tol only; garment dress: 0.1)")
    max_newton_iterations: int = key(100, doc="Newton iterations per step at most", ge=1)
    newton_extrapolate: int | None = key(
        None, ge=0, doc="doublings tried after a full step that beats the Newton model (buckling, sliding "
        "friction; sim/newton.py)", default_text=f"{EXTRAPOLATE}; 0 with friction whose eps_v < {EXTRAPOLATE_MIN_EPS_V:g}")
    mode: str = key("dynamic", doc="time integration", choices=TIME_MODES)
    preroll: float = key(0.0, doc="animated bodies hold their first pose this long first", unit="s", ge=0)
    sewing: str = key("dynamic", doc='"quasistatic": velocities dropped after each sewing step of the pre-roll',
                      choices=SEWING_MODES)
    settle_drag: float = key(0.0, doc="velocities decay by exp(-settle_drag dt) each step after the pre-roll: a "
                             "drag that settles a garment on still bodies without swinging (garment dress: 10)",
                             unit="1/s", ge=0)


@dataclass
class OutputSpec:
    rrd: Path | None = key(None, doc="Rerun recording written", default_text="none")
    mesh_dir: Path | None = key(None, doc="folder the per-frame meshes are written to", default_text="none")
    mesh_format: str = key("npz", doc="per-frame mesh format", choices=MESH_FORMATS)
    mesh_resolution: tuple[int, int] | None = key(None, doc="output mesh vertices per direction", ge=2,
                                                  default_text="automatic")


@dataclass(frozen=True)
class Spin:
    """Rigid rotation of an obstacle about `axis` through `center` at `speed` rad/s,
    starting at time `start` s (ramping up linearly over `ramp` s)."""

    axis: tuple[float, float, float] = key((0.0, 0.0, 1.0), doc="rotation axis (normalised)", normalise=True)
    center: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="a point on the axis", unit="m")
    speed: float = key(0.0, doc="angular speed", unit="rad/s", required=True)
    start: float = key(0.0, doc="time the rotation starts", unit="s", ge=0)
    ramp: float = key(0.0, doc="the speed ramps up linearly over this time", unit="s", ge=0)

    def angle(self, t: float) -> float:
        """Angle turned by time t: 0 before `start`, then speed ramping up over `ramp`."""
        s = max(t - self.start, 0.0)
        if self.ramp > 0.0 and s < self.ramp:
            return 0.5 * self.speed * s * s / self.ramp
        return self.speed * (s - 0.5 * self.ramp)


def _start(note: str = "") -> float:
    return key(0.0, unit="s", ge=0, doc=f"time in the motion of the first frame used{note}")


def _end() -> float | None:
    return key(None, unit="s", gt=0, doc="time in the motion where it stops; the body then holds its last pose",
               default_text="the motion's end")


@dataclass(frozen=True)
class SkinSpec:
    """A mesh skinned to a rig (MakeHuman/MPFB JSON) and moved by BVH motion capture,
    retargeted from the capture's rest pose to the mesh's bind pose (garment/io/rig.py,
    garment/io/retarget.py, docs/bodies.md)."""

    mesh: Path = key(doc="the body mesh OBJ; its vertex order is what the rig and weights index", exists="file",
                     required=True)
    rig: Path = key(doc="the rig JSON: bones with parent, head and tail (MakeHuman, MPFB)", exists="file",
                    required=True)
    weights: Path = key(doc='the skin weights JSON: {"weights": {bone: [[vertex, weight], ...]}}', exists="file",
                        required=True)
    motion: Path = key(doc="the BVH motion capture", exists="file", required=True)
    group: str | None = key(None, doc="the OBJ group that is the body (the other groups are left out)",
                            default_text='every face; MakeHuman\'s base mesh needs "body"')
    joints: tuple[tuple[str, str], ...] = key((), allow_empty=True,
                                              doc='[rig joint, BVH joint] pairs for names that differ (the others '
                                                  'pair by name); a BVH joint "" leaves the rig joint to turn with '
                                                  "its parent")
    start: float = _start(" (a CMU conversion's frame 0 is a calibration T-pose: start one frame in)")
    end: float | None = _end()


@dataclass(frozen=True)
class SmplSpec:
    """An SMPL, SMPL-H or SMPL-X body (the user's model file) moved by an AMASS-style motion
    (garment/io/smpl.py, docs/bodies.md)."""

    model: Path = key(doc="the model: .npz, or the official .pkl (v_template, shapedirs, posedirs, J_regressor, "
                          "weights, kintree_table, f)", exists="file", required=True)
    motion: Path = key(doc="the motion .npz: poses (T, 3 J), trans (T, 3), betas, mocap_framerate (AMASS)",
                       exists="file", required=True)
    start: float = _start()
    end: float | None = _end()


@declare(sphere=Key("a meshed sphere (an icosphere)"), plane=Key("a square plane meshed with two triangles"))
@dataclass
class ObstacleSpec:
    """A collision obstacle: a triangle mesh file, a meshed sphere, a plane, or an animated
    body (`animation`: an NPZ with verts (T, V, 3) and faces, or a directory of OBJ frames;
    `fps` overrides the file's frame time; positions interpolate linearly in time), or a
    body posed by a skeleton's motion (`skin`: a rigged mesh and BVH motion capture;
    `smpl`: an SMPL-family model and an AMASS motion), blending from its bind pose into
    the motion's first frame over the last `blend` s of the pre-roll.

    mesh: path (relative paths resolve against the scene file's folder), scaled by
    `scale`, turned Z-up when `up` = "y", then moved by `translate`. sphere: `center`,
    `radius`, icosphere `subdivisions`. plane: `point`, `normal`, `size` (a square of side
    `size` m, meshed with two triangles).
    """

    name: str = key(doc="obstacle name", default_text='"obstacle0", "obstacle1", ... by position')
    kind: str  # "mesh" | "sphere" | "plane" | "animation": which of those keys is given
    mesh: Path | None = key(None, doc="a triangle mesh file", exists="file")
    animation: Path | None = key(
        None, exists="file or directory",
        doc="an animated body: an NPZ with verts (T, V, 3) and faces, or a directory of OBJ frames; "
            "positions interpolate linearly in time",
    )
    skin: SkinSpec | None = key(None, doc="a mesh skinned to a rig, moved by BVH motion capture (docs/bodies.md)")
    smpl: SmplSpec | None = key(None, doc="an SMPL, SMPL-H or SMPL-X body moved by an AMASS-style motion "
                                          "(docs/bodies.md)")
    fps: float | None = key(None, doc="frame rate, overriding the file's frame time", unit="1/s", gt=0,
                            kinds=MOVING_KINDS, default_text="the file's")
    blend: float | None = key(None, unit="s", ge=0, kinds=RIGGED_KINDS,
                              doc="the body moves from its bind pose into the motion's first frame over the last "
                                  "`blend` s of the pre-roll (at most [time] preroll)",
                              default_text="half of [time] preroll")
    spin: Spin | None = key(None, doc="optional: a rigid rotation (not for an animated body)", after="plane")
    scale: float = key(1.0, doc="scale applied to the file's coordinates (MakeHuman: decimetres, scale = 0.1)",
                       gt=0, kinds=FILE_KINDS)
    up: str | None = key(None, doc='the file\'s up axis; "y" is turned Z-up (smpl: the motion\'s; the model is Y-up)',
                         choices=UP_AXES, kinds=FILE_KINDS,
                         default_text="Z-up, and an animated or skinned body is checked for it; smpl: detected")
    translate: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="offset applied after scaling and turning",
                                                unit="m", kinds=FILE_KINDS)
    center: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="centre", unit="m", table="sphere")
    radius: float = key(0.0, doc="radius", unit="m", gt=0, required=True, table="sphere", plausible=(None, 20.0))
    subdivisions: int = key(3, doc="icosphere subdivisions", ge=0, le=6, table="sphere")
    point: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="a point on the plane", unit="m", table="plane")
    normal: tuple[float, float, float] = key((0.0, 0.0, 1.0), doc="normal (normalised)", normalise=True,
                                             table="plane")
    size: float = key(10.0, doc="side of the square", unit="m", gt=0, table="plane")
    inset: float = key(
        0.0, unit="m", ge=0,
        doc="start this far inside the surface: the seams close in the first half of the pre-roll, the body "
            "grows back in the second; needs [time] preroll > 0",
    )
    raise_arms: float = key(
        0.0, unit="deg", ge=0, le=90, kinds=FILE_KINDS,
        doc="start with the arms (found from the mesh: what hangs free beside the torso) turned up and out by "
            "this angle, lowered while the body grows back: a skirt sewn round an A-pose body's hips clear of "
            "its hands; needs [time] preroll > 0",
    )


@dataclass
class ContactSpec:
    """IPC contact: barrier activation distance dhat (m), stiffness kappa (Pa, area-weighted
    barrier; `kappa = "adaptive"` in a scene chooses it per step as IPC does,
    see sim/contact/stiffness.py), friction mu and eps_v (m/s), cloth self-contact on or off.
    seams: "merge" (closed seams share their contact vertices, sim/seams/mesh.py) or "band"
    (contact off near every seam sample: cheaper, but cloth may cross there).
    mesh_density: vertices of each cloth's contact (and output) mesh per control point;
    the paper's default is 2, its character scenes use 1 (its table: Hiphop 65K (65K))."""

    enabled: bool = key(False, doc="contact on or off",
                        default_text="true when the scene has a [contact] table or an [[obstacle]]")
    dhat: float = key(1e-3, doc="barrier activation distance", unit="m", gt=0, plausible=(None, 0.1))
    kappa: float = key(1e5, doc='barrier stiffness (area-weighted); "adaptive" chooses it per step as IPC does '
                                "(sim/contact/stiffness.py)", unit="Pa", gt=0, also=("adaptive",))
    adaptive_kappa: bool = False  # kappa = "adaptive"
    mu: float = key(0.0, doc="friction coefficient", ge=0)
    eps_v: float = key(1e-3, doc="friction smoothing velocity", unit="m/s", gt=0)
    self_contact: bool = key(True, doc="cloth self-contact")
    seams: str = key("merge", choices=SEAM_CONTACT,
                     doc='"merge": closed seams share their contact vertices (sim/seams/mesh.py); "band": contact '
                         "off near every seam sample (cheaper, but cloth may cross there)")
    mesh_density: float = key(2.0, gt=0, doc="vertices of each cloth's contact (and output) mesh per control point; "
                                             "the paper's default is 2, its character scenes use 1")


@dataclass
class PlacementSpec:
    """The garment's starting shape from another file: an OBJ whose first `v` lines are the
    source panel mesh's vertices in the same order (a sewn drape from an earlier run, as
    Codim-IPC starts its dress_knife scenes from drape.obj), scaled by `scale`, turned
    Z-up when `up` = "y", then moved by `translate` (the obstacle conventions)."""

    file: Path = key(doc="an OBJ whose first `v` lines are the source panel mesh's vertices in the same order "
                         "(a sewn drape from an earlier run)", exists="file", required=True)
    scale: float = key(1.0, doc="scale applied to the file's coordinates", gt=0)
    up: str = key("z", doc='the file\'s up axis; "y" is turned Z-up', choices=UP_AXES)
    translate: tuple[float, float, float] = key((0.0, 0.0, 0.0), doc="offset applied after scaling and turning",
                                                unit="m")


@dataclass
class GarmentSpec:
    """A garment: the patches and seams of a patch file (`garment conform` output), or a
    panel mesh / GarmentCode pattern conformed on the fly at `knot_span` (m; the scene
    key is knot_span_mm), graded towards `seam_span` (m) at short seams
    (conform/grading.py; by default 8 mm on a garment with tucks, else uniform), its
    tucks and knife pleats folded into the placement with `fold_pleats`
    (conform/pleats.py; on by default, a no-op without tucks); with `pleat_wait` (also
    on), seams sewn onto a folded pleat's face or across its layers pull only once its
    tucks have nearly closed (SewingSpec.pleat_wait_gap). Seams are held by springs of
    `seam_stiffness` N/m per metre of seam (sim/seams/energy.py). `placement` replaces
    the panels' 3D layout before conforming (panel OBJ sources only)."""

    name: str = key(doc="garment name", default_text='"garment0", "garment1", ... by position')
    source: Path = key(doc="a patch file (`garment conform` output), or a panel mesh or GarmentCode pattern "
                           "conformed on the fly", exists="file", required=True)
    knot_span: float = key(0.03, doc="knot span a panel source is conformed at", unit="mm", gt=0,
                          plausible=(0.5, 1000.0))
    seam_span: float | None = key(None, doc="knot span graded towards at short seams (conform/grading.py)",
                                  unit="mm", gt=0, plausible=(0.1, 1000.0),
                                  default_text="8 mm on a garment with tucks (conform/pleats.py, TUCK_SEAM_SPAN), "
                                               "else knot_span_mm throughout; knot_span_mm or more: uniform")
    fold_pleats: bool = key(True, doc="tucks and knife pleats start folded (conform/pleats.py); false leaves "
                                      "them flat")
    pleat_wait: bool = key(True, doc="seams sewn onto a folded pleat's face, or across its layers (a dart), pull "
                                     "only once its tucks have nearly closed ([sewing] pleat_wait_gap_mm, "
                                     "pleat_wait_end)")
    seam_stiffness: float = key(1e6, doc="seam springs, N/m per metre of seam (sim/seams/energy.py)",
                                unit="N/m^2", gt=0)
    material: Material = key(PRESETS["cotton"], doc=_MATERIAL_OVERRIDES)
    placement: PlacementSpec | None = key(
        None, doc="optional: the panels' starting 3D layout from another file (panel OBJ sources only)"
    )


@dataclass
class SewingSpec:
    """How seams are sewn (sim/simulator.py): the pre-roll's stiffness ramp, the seam
    multiplier updates, blocked seam pairs and pleat waits."""

    ramp_start: float = key(10.0, unit="N/m^2", gt=0,
                            doc="seam stiffness at the start of the pre-roll ramp; it grows geometrically to the "
                                "seam stiffness")
    multiplier_step: float = key(2.0, unit="E h", gt=0,
                                 doc="cap of one seam-multiplier update, in units of the cloth's force per unit "
                                     "length at 100 % strain (E h)")
    block_reach: float = key(10.0, unit="d_hat", gt=0,
                             doc="open seam pairs closer than this many d_hat are tested for being sewable without "
                                 "a crossing")
    held_fraction: float = key(0.01, ge=0, le=1,
                               doc="share of the seam stiffness kept by samples whose nearest matched pair is "
                                   "blocked with cloth between its sides, or within 0.5 mm")
    pleat_wait_gap: float = key(3e-3, unit="mm", gt=0,
                                doc="a seam sewn onto a folded pleat's face ([[garment]] pleat_wait) pulls once the "
                                    "pleat's tucks are within this gap, or from pleat_wait_end on")
    pleat_wait_end: float | None = key(None, unit="s", ge=0, default_text="the end of [time] preroll",
                                       doc="a seam waiting for a pleat's tucks (pleat_wait_gap_mm) pulls from this "
                                           "time on")


@declare(
    scene=Key("the scene's name and description"),
    material=Key('the material of every cloth and garment; the "cotton" preset when absent', hint=Material,
                 after="scene"),
)
@dataclass
class Scene:
    name: str = key(doc="the scene's name", table="scene", default_text='the file\'s stem, or "scene"')
    path: Path | None  # the scene file; None for a scene parsed from text
    cloths: list[ClothSpec] = key(toml="cloth", doc="a flat rectangular B-spline cloth; a scene needs at least one "
                                                    "[[cloth]] or [[garment]]")
    pins: list[PinSpec] = key(
        default_factory=list, toml="pin",
        doc="control points of one cloth held in place or moved at constant velocity; needs at least one of "
            "corners, sides, box",
    )
    load: LoadSpec = key(default_factory=LoadSpec, doc="loads on every cloth")
    time: TimeSpec = key(default_factory=TimeSpec, doc="time stepping and the Newton solver")
    output: OutputSpec = key(default_factory=OutputSpec,
                             doc="what a run writes; paths are kept as written: relative to the current directory, "
                                 "not to the scene file")
    description: str = key("", doc="free text", table="scene", allow_empty=True)
    obstacles: list[ObstacleSpec] = key(
        default_factory=list, toml="obstacle",
        doc="a collision obstacle: exactly one of mesh, animation, [obstacle.sphere], [obstacle.plane], "
            "[obstacle.skin], [obstacle.smpl]; relative paths resolve against the scene file's folder",
    )
    contact: ContactSpec = key(default_factory=ContactSpec,
                               doc="IPC contact between cloths, garments and obstacles, with friction")
    garments: list[GarmentSpec] = key(
        default_factory=list, toml="garment",
        doc="a garment: the patches and seams of a patch file, or panels conformed on the fly; relative paths "
            "resolve against the scene file's folder",
    )
    sewing: SewingSpec = key(default_factory=SewingSpec, doc="how seams are sewn (sim/simulator.py)")
