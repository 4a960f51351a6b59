"""Scene files: what to simulate, read from TOML and validated before anything runs.

A scene lists one or more rectangular B-spline cloths, the pins that hold them, the loads,
the time stepping and the outputs. Every table is optional except ``[[cloth]]``; keys left
out take the defaults of the dataclasses below. Units are SI (metres, seconds, pascals).

Full example (every key shown)::

    [scene]                     # optional
    name = "hanging"            # default: the file's stem, or "scene"
    description = "free text"

    [material]                  # optional; defaults to the cotton preset
    preset = "cotton"           # applied first, explicit keys below override it
    E_st = 2e6                  # Pa, stretch modulus, > 0
    E_sh = 1e4                  # Pa, shear modulus, >= 0
    E_bd = 8e3                  # Pa, bending modulus, >= 0
    nu = 0.243                  # Poisson ratio, in (-1, 0.5)
    h = 3.18e-4                 # m, thickness, > 0
    rho = 472.6                 # kg/m^3, density, > 0
    membrane = "fbw"            # "fbw" | "stvk" | "none" (bending only)
    quadrature = "reduced"      # "reduced" (needs >= 5 x 5 control points) | "gauss2" | "gauss3"

    [[cloth]]                   # at least one
    name = "sheet"              # unique; default "cloth0", "cloth1", ...
    size = [1.0, 1.0]           # m, width along axis_u and height along axis_v, > 0
    control_points = [25, 25]   # n x m
    origin = [-0.5, 0.0, 1.0]   # m, world position of the (u, v) = (0, 0) corner
    axis_u = [1, 0, 0]          # world direction of u; non-zero
    axis_v = [0, 0, -1]         # world direction of v; non-zero, orthogonal to axis_u

    [cloth.material]            # optional per-cloth overrides, same keys as [material];
    E_bd = 1e4                  # applied on top of [material] (or of this table's preset)

    [cloth.perturbation]        # optional: offset control points along the normal
    amplitude = 0.02            # m; by amplitude * sin(pi wu s) * sin(pi wv t)
    waves = [0, 1]              # (wu, wv) >= 0; 0 means a factor of 1 in that direction

    [[pin]]                     # any number
    cloth = "sheet"             # may be omitted when there is exactly one cloth
    corners = ["u0v0", "u1v0"]  # any of "u0v0", "u1v0", "u0v1", "u1v1"
    sides = []                  # any of "u0", "u1", "v0", "v1" (u0: the side where u = 0)
    box = [[0.0, 0.0], [1.0, 0.1]]  # [[u_min, v_min], [u_max, v_max]], normalised to [0, 1]
    depth = 1                   # rows of control points pinned; 2 also clamps the rotation
    velocity = [0.5, 0, 0]      # m/s, pinned points move with it while active
    start = 0.0                 # s, >= 0
    duration = 0.1              # s, > 0; default inf (TOML `inf` is accepted here only)

    [load]
    gravity = [0, 0, -9.81]     # m/s^2
    pressure = 0.0              # Pa, dead load per unit rest area
    pressure_direction = [0, 0, 1]  # optional, normalised; default: each cloth's normal

    [time]
    dt = 0.01                   # s, > 0
    frames = 100                # >= 1
    steps_per_frame = 1         # >= 1
    newton_tol = 1e-2           # m/s, > 0: stop when ||dC||_inf / dt < newton_tol
    max_newton_iterations = 100 # >= 1
    newton_extrapolate = 0      # >= 0: doublings tried after a full step that beats the
                                # Newton model (sliding friction; sim/newton.py)
    mode = "dynamic"            # "dynamic" | "quasistatic"

    [output]
    rrd = "out/hanging.rrd"     # paths are kept as written: relative to the current
    mesh_dir = "out/hanging_frames"  # directory, not to the scene file
    mesh_format = "npz"         # "npz" | "obj" | "ply"
    mesh_resolution = [50, 50]  # vertices per direction, each >= 2; default automatic

Any problem (unknown key, wrong type, NaN, out-of-range value, dangling reference) raises
:class:`SceneError` naming the file and the dotted key, e.g.
``scenes/a.toml: cloth[0].material.nu: must be in (-1, 0.5), got 0.7``.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from sim.errors import InputError
from sim.materials import MEMBRANE_MODELS, MIN_CONTROL_POINTS, PRESETS, QUADRATURES, Material
from sim.patches import Patch

CORNERS = ("u0v0", "u1v0", "u0v1", "u1v1")
SIDES = ("u0", "u1", "v0", "v1")
TIME_MODES = ("dynamic", "quasistatic")
MESH_FORMATS = ("npz", "obj", "ply")
# Largest |cos| of the angle between axis_u and axis_v.
ORTHOGONALITY_TOL = 1e-6



class SceneError(InputError):
    """A scene file problem, formatted as ``"{file}: {key}: {problem}"``."""

    def __init__(self, file: str | Path, key: str, problem: str):
        self.file = file
        self.key = key
        self.problem = problem
        super().__init__(f"{file}: {key}: {problem}")

    def __reduce__(self):
        return type(self), (self.file, self.key, self.problem)


# --------------------------------------------------------------------------- specs


@dataclass
class Perturbation:
    """Initial out-of-plane offset: amplitude * sin(pi waves[0] s) * sin(pi waves[1] t)."""

    amplitude: float
    waves: tuple[int, int]


@dataclass
class ClothSpec:
    """A flat rectangular cloth; see :meth:`patch`."""

    name: str
    size: tuple[float, float]
    control_points: tuple[int, int]
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis_u: tuple[float, float, float] = (1.0, 0.0, 0.0)
    axis_v: tuple[float, float, float] = (0.0, 1.0, 0.0)
    material: Material = PRESETS["cotton"]
    perturbation: Perturbation | None = None
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # initial, m/s

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

    cloth: str
    corners: tuple[str, ...] = ()
    sides: tuple[str, ...] = ()
    box: tuple[tuple[float, float], tuple[float, float]] | None = None
    depth: int = 1
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start: float = 0.0
    duration: float = math.inf


@dataclass
class LoadSpec:
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    pressure: float = 0.0
    pressure_direction: tuple[float, float, float] | None = None


@dataclass
class TimeSpec:
    dt: float = 0.01
    frames: int = 100
    steps_per_frame: int = 1
    newton_tol: float = 1e-2
    max_newton_iterations: int = 100
    newton_extrapolate: int = 0
    mode: str = "dynamic"
    preroll: float = 0.0  # s: animated bodies hold their first pose this long first
    sewing: str = "dynamic"  # "quasistatic": velocities dropped after each sewing step of the pre-roll


@dataclass
class OutputSpec:
    rrd: Path | None = None
    mesh_dir: Path | None = None
    mesh_format: str = "npz"
    mesh_resolution: tuple[int, int] | None = None


@dataclass(frozen=True)
class Spin:
    """Rigid rotation of an obstacle about `axis` through `center` at `speed` rad/s,
    starting at time `start` s (ramping up linearly over `ramp` s)."""

    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    speed: float = 0.0
    start: float = 0.0
    ramp: float = 0.0

    def angle(self, t: float) -> float:
        """Angle turned by time t: 0 before `start`, then speed ramping up over `ramp`."""
        s = max(t - self.start, 0.0)
        if self.ramp > 0.0 and s < self.ramp:
            return 0.5 * self.speed * s * s / self.ramp
        return self.speed * (s - 0.5 * self.ramp)


@dataclass
class ObstacleSpec:
    """A collision obstacle: a triangle mesh file, a meshed sphere, a plane, or an animated
    body (`animation`: an NPZ with verts (T, V, 3) and faces, or a directory of OBJ frames;
    `fps` overrides the file's frame time; positions interpolate linearly in time).

    mesh: path (relative paths resolve against the scene file's folder), scaled by
    `scale`, turned Z-up when `up` = "y", then moved by `translate`. sphere: `center`,
    `radius`, icosphere `subdivisions`. plane: `point`, `normal`, `size` (a square of side
    `size` m, meshed with two triangles).
    """

    name: str
    kind: str  # "mesh" | "sphere" | "plane" | "animation"
    mesh: Path | None = None
    animation: Path | None = None
    fps: float | None = None
    spin: Spin | None = None
    scale: float = 1.0
    up: str | None = None  # "z" or "y"; None (not given): Z-up, and an animated body is checked for it
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    subdivisions: int = 3
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    size: float = 10.0
    inset: float = 0.0  # m: start this far inside the surface; the seams close in the first half of the pre-roll, the body grows back in the second


@dataclass
class ContactSpec:
    """IPC contact: barrier activation distance dhat (m), stiffness kappa (Pa, area-weighted
    barrier; `kappa = "adaptive"` in a scene chooses it per step as IPC does,
    see sim/contact/stiffness.py), friction mu and eps_v (m/s), cloth self-contact on or off.
    seams: "merge" (closed seams share their contact vertices, sim/seams/mesh.py) or "band"
    (contact off near every seam sample: cheaper, but cloth may cross there).
    mesh_density: vertices of each cloth's contact (and output) mesh per control point;
    the paper's default is 2, its character scenes use 1 (its table: Hiphop 65K (65K))."""

    enabled: bool = False
    dhat: float = 1e-3
    kappa: float = 1e5
    adaptive_kappa: bool = False
    mu: float = 0.0
    eps_v: float = 1e-3
    self_contact: bool = True
    seams: str = "merge"
    mesh_density: float = 2.0


@dataclass
class PlacementSpec:
    """The garment's starting shape from another file: an OBJ whose first `v` lines are the
    source panel mesh's vertices in the same order (a sewn drape from an earlier run, as
    Codim-IPC starts its dress_knife scenes from drape.obj), scaled by `scale`, turned
    Z-up when `up` = "y", then moved by `translate` (the obstacle conventions)."""

    file: Path
    scale: float = 1.0
    up: str = "z"
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class GarmentSpec:
    """A garment: the patches and seams of a patch file (`garment conform` output), or a
    panel mesh / GarmentCode pattern conformed on the fly at `knot_span` (m), graded
    towards `seam_span` (m) at short seams when given (conform/grading.py), its tucks and
    knife pleats folded into the placement with `fold_pleats` (conform/pleats.py); with
    `pleat_wait`, seams sewn onto a folded pleat's face pull only once its tucks have
    nearly closed (sim.seams.sewing.SewingOptions.pleat_wait_gap). Seams are held
    by springs of `seam_stiffness` N/m per metre of seam (sim/seams/energy.py).
    `placement` replaces the panels' 3D layout before conforming (panel OBJ sources only)."""

    name: str
    source: Path
    knot_span: float = 0.03
    seam_span: float | None = None
    fold_pleats: bool = False
    pleat_wait: bool = False
    seam_stiffness: float = 1e6
    material: Material = PRESETS["cotton"]
    placement: PlacementSpec | None = None


@dataclass
class Scene:
    name: str
    path: Path | None
    cloths: list[ClothSpec]
    pins: list[PinSpec] = field(default_factory=list)
    load: LoadSpec = field(default_factory=LoadSpec)
    time: TimeSpec = field(default_factory=TimeSpec)
    output: OutputSpec = field(default_factory=OutputSpec)
    description: str = ""
    obstacles: list[ObstacleSpec] = field(default_factory=list)
    contact: ContactSpec = field(default_factory=ContactSpec)
    garments: list[GarmentSpec] = field(default_factory=list)


# --------------------------------------------------------------------------- entry points


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file."""
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise SceneError(path, "<file>", "no such file") from None
    except OSError as e:
        raise SceneError(path, "<file>", e.strerror or str(e)) from None
    except UnicodeDecodeError as e:
        problem = f"not valid UTF-8 ({e.reason} at byte {e.start})"
        raise SceneError(path, "<toml>", problem) from None
    return loads_scene(text, path)


def loads_scene(text: str, source: str | Path = "<string>") -> Scene:
    """Parse and validate a scene from TOML text; ``source`` only names it in errors."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(source, "<toml>", str(e)) from None
    return parse_scene(data, source)


def parse_scene(data: dict, source: str | Path = "<string>") -> Scene:
    """Validate an already-parsed TOML document. ``source`` names it in errors; unless it is
    a placeholder like ``"<string>"`` it also becomes :attr:`Scene.path`."""
    path = None if str(source).startswith("<") else Path(source)
    root = _Table(data, source, "", _TOP_KEYS)
    info = root.table("scene", ("name", "description"))
    material = _read_material(root.table("material", _MATERIAL_KEYS), PRESETS["cotton"])
    base = path.parent if path is not None else Path(".")
    garments = [_read_garment(t, i, base, material) for i, t in enumerate(root.tables("garment", _GARMENT_KEYS))]
    cloths = _read_cloths(root, material, required=not garments)
    obstacles = [_read_obstacle(t, i, base) for i, t in enumerate(root.tables("obstacle", _OBSTACLE_KEYS))]
    time_spec = _read_time(root.table("time", _TIME_KEYS))
    for i, o in enumerate(obstacles):
        if o.inset > 0.0 and time_spec.preroll <= 0.0:
            raise SceneError(source, f"obstacle[{i}].inset", "an inset body grows out during the pre-roll: "
                                                            "set [time] preroll > 0")
    return Scene(
        name=info.string("name") or (path.stem if path else "scene"),
        path=path,
        cloths=cloths,
        pins=[_read_pin(t, cloths) for t in root.tables("pin", _PIN_KEYS)],
        load=_read_load(root.table("load", _LOAD_KEYS)),
        time=time_spec,
        output=_read_output(root.table("output", _OUTPUT_KEYS)),
        description=info.string("description", allow_empty=True) or "",
        obstacles=obstacles,
        contact=_read_contact(root, bool(obstacles)),
        garments=garments,
    )


# --------------------------------------------------------------------------- tables

_TOP_KEYS = ("scene", "material", "cloth", "pin", "load", "time", "output", "obstacle", "contact", "garment")
_GARMENT_KEYS = ("name", "source", "knot_span_mm", "seam_span_mm", "fold_pleats", "pleat_wait", "seam_stiffness",
                 "material", "placement")
_PLACEMENT_KEYS = ("file", "scale", "up", "translate")
_MATERIAL_NUMBERS = {  # key -> bounds
    "E_st": {"gt": 0},
    "E_sh": {"ge": 0},
    "E_bd": {"ge": 0},
    "nu": {"gt": -1, "lt": 0.5},
    "h": {"gt": 0},
    "rho": {"gt": 0},
}
_MATERIAL_KEYS = ("preset", *_MATERIAL_NUMBERS, "membrane", "quadrature")
_CLOTH_KEYS = (
    "name", "size", "control_points", "origin", "axis_u", "axis_v", "material", "perturbation", "velocity"
)
_PERTURBATION_KEYS = ("amplitude", "waves")
_PIN_KEYS = ("cloth", "corners", "sides", "box", "depth", "velocity", "start", "duration")
_LOAD_KEYS = ("gravity", "pressure", "pressure_direction")
_TIME_KEYS = ("dt", "frames", "steps_per_frame", "newton_tol", "max_newton_iterations", "newton_extrapolate", "mode",
              "preroll", "sewing")
_OUTPUT_KEYS = ("rrd", "mesh_dir", "mesh_format", "mesh_resolution")
_OBSTACLE_KEYS = ("name", "mesh", "animation", "fps", "scale", "up", "translate", "sphere", "plane", "spin", "inset")
_SPIN_KEYS = ("axis", "center", "speed", "start", "ramp")
_SPHERE_KEYS = ("center", "radius", "subdivisions")
_PLANE_KEYS = ("point", "normal", "size")
_CONTACT_KEYS = ("enabled", "dhat", "kappa", "mu", "eps_v", "self_contact", "seams", "mesh_density")
UP_AXES = ("y", "z")
SEWING_MODES = ("dynamic", "quasistatic")


def _given(**values: Any) -> dict[str, Any]:
    """The values that were present in the file; absent ones keep the dataclass defaults."""
    return {k: v for k, v in values.items() if v is not None}


def _read_material(t: _Table, base: Material) -> Material:
    """``base`` (or the table's preset) with the table's explicit keys applied."""
    preset = t.choice("preset", tuple(PRESETS))
    if preset is not None:
        base = PRESETS[preset]
    numbers = {k: t.number(k, **bounds) for k, bounds in _MATERIAL_NUMBERS.items()}
    return base.with_(
        **_given(
            **numbers,
            membrane=t.choice("membrane", MEMBRANE_MODELS),
            quadrature=t.choice("quadrature", QUADRATURES),
        )
    )


def _read_garment(t: _Table, index: int, base: Path, scene_material: Material) -> GarmentSpec:
    src = Path(t.string("source", required=True))
    src = src if src.is_absolute() else base / src
    if not src.is_file():
        t.fail(t.key("source"), f"no such file: {src}")
    span = t.number("knot_span_mm", gt=0)
    seam_span = t.number("seam_span_mm", gt=0)
    placement = None
    if "placement" in t:
        pt = t.table("placement", _PLACEMENT_KEYS)
        file = Path(pt.string("file", required=True))
        file = file if file.is_absolute() else base / file
        if not file.is_file():
            pt.fail(pt.key("file"), f"no such file: {file}")
        if src.suffix.lower() != ".obj":
            pt.fail(pt.path, f"a placement needs a panel OBJ source (its vertex order), not {src.name}")
        placement = PlacementSpec(file, **_given(scale=pt.number("scale", gt=0), up=pt.choice("up", UP_AXES),
                                                 translate=pt.numbers("translate", 3)))
    return GarmentSpec(
        name=t.string("name") or f"garment{index}", source=src, placement=placement,
        material=_read_material(t.table("material", _MATERIAL_KEYS), scene_material),
        **_given(knot_span=span / 1000.0 if span else None, seam_span=seam_span / 1000.0 if seam_span else None,
                 seam_stiffness=t.number("seam_stiffness", gt=0), fold_pleats=t.read("fold_pleats", _as_bool),
                 pleat_wait=t.read("pleat_wait", _as_bool)),
    )


def _read_cloths(root: _Table, material: Material, required: bool = True) -> list[ClothSpec]:
    tables = root.tables("cloth", _CLOTH_KEYS)
    if not tables and required:
        root.fail("cloth", "the scene needs at least one [[cloth]] or [[garment]] table")
    cloths: list[ClothSpec] = []
    first_index: dict[str, int] = {}
    for i, t in enumerate(tables):
        cloth = _read_cloth(t, f"cloth{i}", material)
        if cloth.name in first_index:
            t.fail(
                t.key("name"),
                f"duplicate cloth name {cloth.name!r} (also cloth[{first_index[cloth.name]}])",
            )
        first_index[cloth.name] = i
        cloths.append(cloth)
    return cloths


def _read_cloth(t: _Table, default_name: str, scene_material: Material) -> ClothSpec:
    material = _read_material(t.table("material", _MATERIAL_KEYS), scene_material)
    control_points = t.integers("control_points", 2, required=True, ge=1)
    minimum = MIN_CONTROL_POINTS[material.quadrature]
    if min(control_points) < minimum:
        t.fail(
            t.key("control_points"),
            f"quadrature {material.quadrature!r} needs at least {minimum} x {minimum} "
            f"control points, got {control_points[0]} x {control_points[1]}",
        )
    axis_u = t.numbers("axis_u", 3)
    axis_v = t.numbers("axis_v", 3)
    _check_axes(t, axis_u or ClothSpec.axis_u, axis_v or ClothSpec.axis_v)
    perturbation = None
    if "perturbation" in t:
        p = t.table("perturbation", _PERTURBATION_KEYS)
        perturbation = Perturbation(
            amplitude=p.number("amplitude", required=True),
            waves=p.integers("waves", 2, required=True, ge=0),
        )
    return ClothSpec(
        name=t.string("name") or default_name,
        size=t.numbers("size", 2, required=True, gt=0),
        control_points=control_points,
        material=material,
        perturbation=perturbation,
        **_given(origin=t.numbers("origin", 3), axis_u=axis_u, axis_v=axis_v, velocity=t.numbers("velocity", 3)),
    )


def _check_axes(t: _Table, axis_u: tuple, axis_v: tuple) -> None:
    norms = {}
    for name, axis in (("axis_u", axis_u), ("axis_v", axis_v)):
        norms[name] = math.hypot(*axis)
        if norms[name] == 0.0:
            t.fail(t.key(name), "must be non-zero")
    cos = abs(float(np.dot(axis_u, axis_v))) / (norms["axis_u"] * norms["axis_v"])
    if cos > ORTHOGONALITY_TOL:
        t.fail(
            t.key("axis_v"),
            f"must be orthogonal to axis_u (|cos| = {cos:.3g} > {ORTHOGONALITY_TOL:g})",
        )


def _read_pin(t: _Table, cloths: list[ClothSpec]) -> PinSpec:
    names = [c.name for c in cloths]
    cloth = t.string("cloth")
    if cloth is None:
        if len(names) > 1:
            t.fail(t.key("cloth"), f"required when there are several cloths ({', '.join(names)})")
        cloth = names[0]
    elif cloth not in names:
        t.fail(t.key("cloth"), f"unknown cloth {cloth!r} (cloths: {', '.join(names)})")
    corners = t.choices("corners", CORNERS)
    sides = t.choices("sides", SIDES)
    box = t.read("box", _as_box)
    if not (corners or sides or box):
        t.fail(t.path, "needs at least one of corners, sides, box")
    return PinSpec(
        cloth=cloth,
        **_given(
            corners=corners,
            sides=sides,
            box=box,
            depth=t.integer("depth", ge=1),
            velocity=t.numbers("velocity", 3),
            start=t.number("start", ge=0),
            duration=t.number("duration", gt=0, allow_inf=True),
        ),
    )


def _as_box(t: _Table, value: Any, key: str) -> tuple[tuple[float, float], tuple[float, float]]:
    lo, hi = (
        tuple(
            t.as_number(x, f"{key}[{i}][{j}]", ge=0, le=1)
            for j, x in enumerate(t.as_array(row, f"{key}[{i}]", 2))
        )
        for i, row in enumerate(t.as_array(value, key, 2))
    )
    for axis, label in enumerate("uv"):
        if lo[axis] > hi[axis]:
            t.fail(key, f"{label}_min = {lo[axis]:g} > {label}_max = {hi[axis]:g}")
    return lo, hi


def _read_load(t: _Table) -> LoadSpec:
    direction = t.unit_vector("pressure_direction")
    return LoadSpec(
        **_given(
            gravity=t.numbers("gravity", 3),
            pressure=t.number("pressure"),
            pressure_direction=direction,
        )
    )


def _read_time(t: _Table) -> TimeSpec:
    return TimeSpec(
        **_given(
            dt=t.number("dt", gt=0),
            frames=t.integer("frames", ge=1),
            steps_per_frame=t.integer("steps_per_frame", ge=1),
            newton_tol=t.number("newton_tol", gt=0),
            max_newton_iterations=t.integer("max_newton_iterations", ge=1),
            newton_extrapolate=t.integer("newton_extrapolate", ge=0),
            mode=t.choice("mode", TIME_MODES),
            preroll=t.number("preroll", ge=0),
            sewing=t.choice("sewing", SEWING_MODES),
        )
    )


def _read_output(t: _Table) -> OutputSpec:
    rrd = t.string("rrd")
    mesh_dir = t.string("mesh_dir")
    return OutputSpec(
        **_given(
            rrd=Path(rrd) if rrd else None,
            mesh_dir=Path(mesh_dir) if mesh_dir else None,
            mesh_format=t.choice("mesh_format", MESH_FORMATS),
            mesh_resolution=t.integers("mesh_resolution", 2, ge=2),
        )
    )


def _read_obstacle(t: _Table, index: int, base: Path) -> ObstacleSpec:
    kinds = [k for k in ("mesh", "animation", "sphere", "plane") if k in t]
    if len(kinds) != 1:
        t.fail(t.path, f"needs exactly one of 'mesh', 'animation', 'sphere', 'plane', got {kinds or 'none'}")
    kind = kinds[0]
    values: dict[str, Any] = {"name": t.string("name") or f"obstacle{index}", "kind": kind,
                              **_given(inset=t.number("inset", ge=0))}
    if kind == "mesh":
        mesh = Path(t.string("mesh", required=True))
        mesh = mesh if mesh.is_absolute() else base / mesh
        if not mesh.is_file():
            t.fail(t.key("mesh"), f"no such file: {mesh}")
        values.update(_given(mesh=mesh, scale=t.number("scale", gt=0), up=t.choice("up", UP_AXES),
                             translate=t.numbers("translate", 3)))
    elif kind == "animation":
        anim = Path(t.string("animation", required=True))
        anim = anim if anim.is_absolute() else base / anim
        if not anim.exists():
            t.fail(t.key("animation"), f"no such file or directory: {anim}")
        values.update(_given(animation=anim, fps=t.number("fps", gt=0), scale=t.number("scale", gt=0),
                             up=t.choice("up", UP_AXES), translate=t.numbers("translate", 3)))
    elif kind == "sphere":
        sp = t.table("sphere", _SPHERE_KEYS)
        values.update(_given(center=sp.numbers("center", 3), radius=sp.number("radius", required=True, gt=0),
                             subdivisions=sp.integer("subdivisions", ge=0, le=6)))
    else:
        pl = t.table("plane", _PLANE_KEYS)
        values.update(_given(point=pl.numbers("point", 3), normal=pl.unit_vector("normal"),
                             size=pl.number("size", gt=0)))
    if "spin" in t:
        if kind == "animation":
            t.fail(t.key("spin"), "an animated body already moves; spin applies to static obstacles")
        st = t.table("spin", _SPIN_KEYS)
        values["spin"] = Spin(**_given(axis=st.unit_vector("axis"), center=st.numbers("center", 3),
                                       speed=st.number("speed", required=True), start=st.number("start", ge=0),
                                       ramp=st.number("ramp", ge=0)))
    return ObstacleSpec(**values)


def _read_contact(root: _Table, has_obstacles: bool) -> ContactSpec:
    present = "contact" in root
    t = root.table("contact", _CONTACT_KEYS)
    enabled = t.read("enabled", _as_bool)
    adaptive = t.data.get("kappa") == "adaptive"
    return ContactSpec(
        **_given(
            enabled=enabled if enabled is not None else (present or has_obstacles),
            dhat=t.number("dhat", gt=0),
            kappa=None if adaptive else t.number("kappa", gt=0),
            adaptive_kappa=adaptive or None,
            mu=t.number("mu", ge=0),
            eps_v=t.number("eps_v", gt=0),
            self_contact=t.read("self_contact", _as_bool),
            seams=t.choice("seams", ("merge", "band")),
            mesh_density=t.number("mesh_density", gt=0),
        )
    )


def _as_bool(t: "_Table", value: Any, key: str) -> bool:
    if not isinstance(value, bool):
        t.fail(key, f"must be true or false, got {_kind(value)}")
    return value


# --------------------------------------------------------------------------- typed reading


class _Table:
    """One TOML table being read. It knows its file and dotted key path, so every error
    names both, and it rejects unknown keys up front.

    Field readers (``number``, ``integers``, ``choice``, ...) return the converted value of a
    key, or None when the key is absent (an error instead when ``required``). Value
    converters (``as_number``, ...) check one value found at a given key path.
    """

    def __init__(self, data: Any, file: str | Path, path: str, keys: Iterable[str]):
        self.file = file
        self.path = path
        if not isinstance(data, dict):
            self.fail(path, f"must be a table, got {_kind(data)}")
        self.data = data
        keys = tuple(keys)
        for name in data:
            if name not in keys:
                self.fail(self.key(name), _unknown_key(name, keys))

    def __contains__(self, name: str) -> bool:
        return name in self.data

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def fail(self, key: str, problem: str) -> NoReturn:
        raise SceneError(self.file, key, problem)

    # --- field readers

    def read(self, name: str, convert: Callable, required: bool = False, **options) -> Any:
        """``convert(self, value, key, **options)`` applied to the key's value, if present."""
        if name not in self.data:
            if required:
                self.fail(self.key(name), "missing required key")
            return None
        return convert(self, self.data[name], self.key(name), **options)

    def number(self, name: str, required: bool = False, **bounds) -> float | None:
        return self.read(name, _Table.as_number, required, **bounds)

    def integer(self, name: str, required: bool = False, **bounds) -> int | None:
        return self.read(name, _Table.as_integer, required, **bounds)

    def string(self, name: str, required: bool = False, allow_empty: bool = False) -> str | None:
        return self.read(name, _Table.as_string, required, allow_empty=allow_empty)

    def choice(self, name: str, choices: tuple[str, ...], required: bool = False) -> str | None:
        return self.read(name, _Table.as_choice, required, choices=choices)

    def numbers(self, name: str, length: int, required: bool = False, **bounds):
        return self.read(
            name, _Table.as_tuple, required, item=_Table.as_number, length=length, **bounds
        )

    def unit_vector(self, name: str) -> tuple[float, float, float] | None:
        """A non-zero 3-vector, normalised."""
        v = self.numbers(name, 3)
        if v is None:
            return None
        norm = math.hypot(*v)
        if norm == 0.0:
            self.fail(self.key(name), "must be non-zero")
        return tuple(x / norm for x in v)

    def integers(self, name: str, length: int, required: bool = False, **bounds):
        return self.read(
            name, _Table.as_tuple, required, item=_Table.as_integer, length=length, **bounds
        )

    def choices(self, name: str, choices: tuple[str, ...]) -> tuple[str, ...] | None:
        """An array of distinct names from ``choices``, any length."""
        values = self.read(name, _Table.as_tuple, item=_Table.as_choice, choices=choices)
        for i, value in enumerate(values or ()):
            if value in values[:i]:
                self.fail(f"{self.key(name)}[{i}]", f"duplicate {value!r}")
        return values

    def table(self, name: str, keys: Iterable[str]) -> _Table:
        """The sub-table ``name``; an empty one when absent."""
        return _Table(self.data.get(name, {}), self.file, self.key(name), keys)

    def tables(self, name: str, keys: Iterable[str]) -> list[_Table]:
        """The array of tables ``[[name]]``; empty when absent."""
        value = self.data.get(name, [])
        key = self.key(name)
        if not isinstance(value, list):
            self.fail(key, f"must be an array of tables ([[{name}]]), got {_kind(value)}")
        return [_Table(item, self.file, f"{key}[{i}]", keys) for i, item in enumerate(value)]

    # --- value converters

    def as_number(self, value: Any, key: str, allow_inf: bool = False, **bounds) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f"must be a number, got {_kind(value)}")
        value = float(value)
        if math.isnan(value) or (math.isinf(value) and not allow_inf):
            self.fail(key, f"must be finite, got {value}")
        self._check_bounds(value, key, **bounds)
        return value

    def as_integer(self, value: Any, key: str, **bounds) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"must be an integer, got {_kind(value)}")
        self._check_bounds(value, key, **bounds)
        return value

    def as_string(self, value: Any, key: str, allow_empty: bool = False) -> str:
        if not isinstance(value, str):
            self.fail(key, f"must be a string, got {_kind(value)}")
        if not value and not allow_empty:
            self.fail(key, "must not be empty")
        return value

    def as_choice(self, value: Any, key: str, choices: tuple[str, ...]) -> str:
        value = self.as_string(value, key)
        if value not in choices:
            valid = ", ".join(repr(c) for c in choices)
            self.fail(key, f"unknown name {value!r} (valid: {valid})")
        return value

    def as_array(self, value: Any, key: str, length: int | None = None) -> list:
        if not isinstance(value, list):
            self.fail(key, f"must be an array, got {_kind(value)}")
        if length is not None and len(value) != length:
            self.fail(key, f"must have {length} entries, got {len(value)}")
        return value

    def as_tuple(self, value: Any, key: str, item: Callable, length: int | None = None, **options):
        """An array whose entries are each converted by ``item(self, entry, key[i], **options)``."""
        return tuple(
            item(self, x, f"{key}[{i}]", **options)
            for i, x in enumerate(self.as_array(value, key, length))
        )

    def _check_bounds(self, value: float, key: str, gt=None, ge=None, lt=None, le=None) -> None:
        lower = gt if gt is not None else ge
        upper = lt if lt is not None else le
        if (
            (gt is not None and not value > gt)
            or (ge is not None and not value >= ge)
            or (lt is not None and not value < lt)
            or (le is not None and not value <= le)
        ):
            if lower is not None and upper is not None:
                left, right = ("(" if gt is not None else "["), (")" if lt is not None else "]")
                rule = f"in {left}{lower:g}, {upper:g}{right}"
            elif lower is not None:
                rule = f"{'>' if gt is not None else '>='} {lower:g}"
            else:
                rule = f"{'<' if lt is not None else '<='} {upper:g}"
            self.fail(key, f"must be {rule}, got {value:g}")


def _unknown_key(name: str, valid: tuple[str, ...]) -> str:
    close = difflib.get_close_matches(name, valid, n=1)
    hint = f"did you mean {close[0]!r}?" if close else f"valid keys: {', '.join(valid)}"
    return f"unknown key {name!r} ({hint})"


def _kind(value: Any) -> str:
    """A TOML-flavoured description of a value's type for error messages."""
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    for kind, name in ((int, "integer"), (float, "float"), (str, "string")):
        if isinstance(value, kind):
            return f"{name} {value!r}"
    if isinstance(value, list):
        return "array"
    if isinstance(value, dict):
        return "table"
    return type(value).__name__  # datetime, date, time
