"""One garment on one body with defaults: conform, place, sew, settle, check, write.

    from garment.dress.job import dress
    report = dress("pattern.json", "body.obj", "out/")

writes out/patches.json (the conformed garment as placed), out/run.rrd, out/garment.obj
(the settled garment, in the body file's units and axes, so it overlays the body) and
out/report.json, and returns the report: status ("ok", or the failure category conform,
placement, sewing, intersection, timeout, nan), seam_gap_max_mm, crossings (the
independent check, garment/verify.py, summed over every exported frame), dofs, seconds,
settle_time_s, and where the time went: placing_s, then steps, seconds, Newton
iterations and splits (failed steps retried as two halves; `splits` says why) of each
phase (sewing, gravity_ramp, settling). Bad input (a file that cannot
be read) raises sim.errors.InputError.

The defaults are one mechanism for every garment (docs/dressing.md):
- sewing: the body starts shrunk (`inset`, at most 0.4 x its local thickness) so seams
  pulled straight across an armpit or shoulder clear it; seams stiffen over the first half
  of `sew_time`, the body grows back over the second, pushing the cloth out by contact;
  velocities are dropped after each sewing step, and gravity is off until the body is
  whole, then ramps in over `gravity_ramp`;
- settling under a drag (`settle_drag`): the cloth's velocity decays by exp(-10 dt) a
  step, so the garment comes to rest on the still body instead of swinging about it
  (dress_02's skirt swung at 4-15 cm/s for over a second) and still falls freely (dropped
  velocities, quasi-static, held skirt_04's hem 10 cm up after 2.5 s);
- layout: panels that cross each other or the shrunk body move apart first (layout.py);
- at rest: the run ends when the garment is at rest (RMS control-point speed of a step below
  `rest_speed` over `rest_frames` frames, seams closed), or at `max_time`;
- drawn in: once sewn, a top opening at the trunk's heights wider than the trunk everywhere
  below it (nothing could hold it up) gets an elastic band, tightened to 0.9 x the body's girth where it sits while
  gravity comes on (drawstring.py; the report's `drawstring`);
- slid off: a garment whose mean height drops FALLEN below where it was placed stops as a
  `placement` failure (nothing on the body holds it up).
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import numpy as np

from sim.errors import InputError, SimulationError
from sim.files import atomic_write, output_folder
from sim.newton import EXTRAPOLATE
from sim.recovery import SplitWarning

from ..io.bodies import from_scene_frame, to_scene_frame
from ..scene.schema import key, rule, within
from ..verify import frame_crossings, shared_vertices, stack_meshes
from .drawstring import body_mesh, draw_in
from .frame import BodyFrame, pattern_up, read_body
from .girth import loose_opening, trunk_centre
from .halves import into_own_half
from .layout import PlacementError, arms_out_of_the_way, lift_over_body, separate
from .paths import out_of_seam_paths

STATUSES = ("ok", "conform", "placement", "sewing", "intersection", "timeout", "nan")


@dataclass
class DressOptions:
    """The defaults of `garment dress`; every garment gets the same ones. Each carries its
    bounds as a scene key does (garment/scene/schema.py), checked on `--set`."""

    knot_span_mm: float = key(40.0, doc="B-spline knot span in mm", gt=0)
    seam_span_mm: float = key(0.0, doc="knot span at short seams (tucks, dart legs) in mm; 0: 8 mm on a garment "
                                       "with tucks, else uniform nets (conform/pleats.py, TUCK_SEAM_SPAN); the knot "
                                       "span or more: uniform", ge=0)
    material: str = key("cotton", doc="material preset")
    seam_stiffness: float = key(1e7, doc="seam stiffness per metre of seam", unit="N/m^2", gt=0)
    inset: float = key(0.05, doc="how far the body starts inside its surface (capped at 0.4 x thickness)",
                       unit="m", gt=0)
    sew_time: float = key(0.6, doc="seams close in the first half, the body grows back in the second", unit="s",
                          gt=0)
    gravity_ramp: float = key(0.2, doc="gravity, off while sewing, ramps in over this time", unit="s", gt=0)
    dt: float = key(0.01, doc="time step while sewing", unit="s", gt=0)
    steps_per_frame: int = key(4, doc="sewing steps per exported frame (25 frames a second)", ge=1)
    # Once sewn, what is wanted is where the garment comes to rest, not how it swings
    # there: implicit Euler at 4x the sewing step reaches the same rest shape in about
    # half the Newton iterations (skirt_04 settling 643 -> 320 at rest at 3.04 s against
    # 2.96 s, 0.8 mm apart; jumpsuit_04 from its sewn state 687 -> 313 to rest at 1.28 s
    # against 1.36 s), and at 8x (0.08 s) dress_06's full-circle skirt, falling into its
    # drape for 3 s, rests at 3.8 s in 669 ramp and settling iterations instead of 1,347
    # (stop 58). At 16x (0.16 s) a step takes about as many Newton iterations as at 0.08 s
    # (dress_04's three-tier skirt: 23-46), so the fall costs half: dress_04 at rest in 465
    # settling iterations from t = 0.84 s where 0.08 s steps took 492 to reach only 1.96 s,
    # dress_06's ramp and settling 360 against 525-547, at rest at 3.0 s as before (stop 74).
    # A frame is dt x steps_per_frame long, or one step when that is longer.
    # Sewing steps of 0.02 s throughout left shirt_mean's and dress_06's seams 3.2-3.4 mm
    # open (docs/dressing.md, stop 57); once the seams are stiff and the body grows back
    # they do no harm: shirt_mean sewn in 377 Newton iterations instead of 486, dress_06
    # in 387 instead of 508, seams closed as before (stop 58).
    settle_dt: float = key(0.16, doc="time step once sewn (gravity ramp and settling)", unit="s", gt=0)
    grow_dt: float = key(0.02, doc="time step while the body grows back (sewing's second half)", unit="s", gt=0)
    # Simulated time at most; the wall-clock timeout is what bounds the work. At 2.5 s
    # skirt_04's side seams were still sliding off the hands at 0.1-0.2 m/s.
    max_time: float = key(5.0, doc="simulated time at most", unit="s", gt=0)
    rest_speed: float = key(0.01, doc="RMS control-point speed counted as at rest", unit="m/s", gt=0)
    rest_frames: int = key(3, doc="frames at rest that end the run", ge=1)
    timeout: float = key(600.0, doc="wall-clock time at most", unit="s", gt=0)
    settle_drag: float = key(10.0, doc="after sewing the cloth's velocity decays by exp(-settle_drag dt) a step",
                             unit="1/s", gt=0)
    mu: float = key(0.2, doc="friction coefficient", gt=0)
    dhat: float = key(1e-3, doc="contact distance", unit="m", gt=0)
    # Friction's static band and Newton's step doublings, as dress_rumba.toml (docs/findings.md,
    # "Sliding friction and extrapolation"). At eps_v 1e-3 m/s a point held by static
    # friction makes Newton jump across it every iteration (jumpsuit_04's first gravity
    # step: 0.78 mm either way for 40 iterations); at 1e-2 the buckling cloth's full steps
    # fall short of the energy's fall instead, which doublings take up. Gravity ramp:
    # 21.1 -> 14.8 Newton iterations a step (docs/dressing.md, "Static friction band").
    eps_v: float = key(1e-2, doc="friction's static band", unit="m/s", gt=0)
    newton_extrapolate: int = key(EXTRAPOLATE, doc="Newton step doublings (0: none)", ge=0)
    # Newton stops at 10 % of the step's RMS control-point speed (or at newton_tol, if
    # larger): the rest shape is wanted, not the fall's path (sim/newton.tolerance).
    newton_relative_tol: float = key(0.1, doc="Newton's tolerance as a fraction of the step's speed", ge=0)

    @classmethod
    def with_overrides(cls, overrides: dict | None) -> "DressOptions":
        options = cls()
        known = {f.name: f for f in fields(cls)}
        for k, v in (overrides or {}).items():
            if k not in known:
                raise InputError(f"unknown dress setting {k!r}; known: {', '.join(known)}")
            default = getattr(options, k)
            try:
                value = type(default)(v)
            except (TypeError, ValueError):
                raise InputError(f"dress setting {k} = {v!r}: expected a {type(default).__name__}") from None
            bounds = known[k].metadata["key"].bounds
            if isinstance(value, (int, float)) and not (np.isfinite(value) and within(value, **bounds)):
                raise InputError(f"dress setting {k} = {v!r}: must be {rule(**bounds)}")
            options = replace(options, **{k: value})
        return options


class DressFailure(Exception):
    """A garment that could not be dressed, with its status category."""

    def __init__(self, category: str, message: str):
        super().__init__(message)
        self.category = category


def dress(pattern, body, outdir, overrides: dict | None = None, on_frame=None) -> dict:
    """Dress `body` (a static mesh file) in `pattern` (GarmentCode JSON or a panel mesh);
    see the module docstring. on_frame(frame, frames_max, stats_line): progress."""
    start = time.perf_counter()
    options = DressOptions.with_overrides(overrides)
    pattern, body = Path(pattern), Path(body)
    outdir = output_folder(outdir, "the dress output folder (-o)")
    outdir.mkdir(parents=True, exist_ok=True)
    report = {"pattern": str(pattern), "body": str(body), "status": None, "error": None,
              "seam_gap_max_mm": None, "crossings": None, "dofs": None, "seconds": None, "settle_time_s": None,
              "options": asdict(options)}
    try:
        frame, body_V, body_F = _body(body)
        report["body_frame"] = frame.describe()
        placed = place_garment(pattern, frame, body_V, body_F, options, outdir)
        report["moved_panels_mm"] = {k: round(v * 1e3, 1) for k, v in placed.moved.items()}
        report["lifted_panels_mm"] = {k: round(v * 1e3, 1) for k, v in placed.lifted.items()}
        report["out_of_seam_paths_mm"] = {k: round(v * 1e3, 1) for k, v in placed.out_of_paths.items()}
        report["bent_into_own_half_mm"] = {k: round(v * 1e3, 1) for k, v in placed.bent.items()}
        report["raised_arms_deg"] = placed.raise_arms
        report["seams_below_resolution"] = placed.below_resolution
        obstacle = {"name": "body", "mesh": str(body.resolve()), "scale": frame.scale, "up": frame.up,
                    "raise_arms": placed.raise_arms}
        _simulate(dress_scene(outdir / "patches.json", obstacle, options), options, outdir, frame, report,
                  start, on_frame)
    except DressFailure as e:
        report["status"], report["error"] = e.category, str(e)
    except PlacementError as e:
        report["status"], report["error"] = "placement", str(e)
    finally:
        report["seconds"] = round(time.perf_counter() - start, 2)
        for phase in report.get("phases", {}).values():  # rounded per step, they drifted (up to 0.005 s a step)
            phase["seconds"] = round(phase["seconds"], 2)
        if report["status"] is not None:
            with atomic_write(outdir / "report.json") as tmp:
                tmp.write_text(json.dumps(report, indent=1, allow_nan=False) + "\n")
    return report


def _body(path: Path):
    """The body's frame, and its vertices in the simulator's (Z-up metres) and faces."""
    V, F, frame = read_body(path)
    return frame, to_scene_frame(V.astype(float), frame.scale, frame.up), F.astype(np.int32)


def place_garment(pattern: Path, frame: BodyFrame, body_V, body_F, options: DressOptions, outdir: Path):
    """Conform the pattern, bring it into the body's frame, lift the panels of seams that
    would close through the body over it, move crossing panels apart (against the body as
    shrunk at the start) and write outdir/patches.json. Returns the layout.Layout."""
    from conform.pipeline import ConformOptions, conform_all

    from ..io.garments import read_pattern
    from ..io.obstacles import ObstacleGeometry
    from ..io.patchfile import save_patchset

    conform_options = ConformOptions(knot_span=options.knot_span_mm * 1e-3,
                                     seam_span=options.seam_span_mm * 1e-3 or "auto")
    panels, seams = read_pattern(pattern, conform_options.finest_span)
    ps = conform_all(panels, seams, conform_options)
    # conform_all cuts a panel whose net folds over into pieces; one that still folds (no
    # cut helped) is no valid cloth.
    bad = dict(ps.failures)
    bad.update({p.name: _fold_reason(ps.panel_of(p.name), panels, conform_options)
                for p in ps.patches if ps.quality[p.name]["folds"]})
    if bad:
        raise DressFailure("conform", "panels that did not conform: " + "; ".join(f"{k}: {v}" for k, v in bad.items()))
    up = pattern_up(pattern)
    for p in ps.patches:  # the pattern's frame to the simulator's (Z-up, metres)
        p.world = np.ascontiguousarray(to_scene_frame(p.world, 1.0, up))
    if up == "y":
        fit_to_body(ps.patches, body_V)
    # Seams pulled shut through the body (a strap laid in front of a shoulder, its partner
    # behind) press the cloth into it while the body grows back: over it, they close.
    panels = [ps.panel_of(p.name) for p in ps.patches]
    # A panel laid inside another seam's closing paths would be sewn into that seam.
    out = out_of_seam_paths(ps.patches, ps.seams, body_V, body_F, panels)
    # Two trouser cuffs overlapping between the legs, which no rigid move parts, would be
    # sewn through each other.
    bent = into_own_half(ps.patches, ps.seams, body_V, body_F, panels)
    # A skirt laid over the hands is sewn with the arms raised (lowered as the body grows).
    angle, arms = arms_out_of_the_way(ps.patches, ps.seams, body_V, body_F)
    grow = (0.5 * options.sew_time, options.sew_time)
    start = ObstacleGeometry("body", body_V, body_F, raise_arms=angle, grow=grow, arms=arms).at(0.0)
    lifted = lift_over_body(ps.patches, ps.seams, start, body_F, panels)
    shrunk = ObstacleGeometry("body", body_V, body_F, inset=options.inset, raise_arms=angle, grow=grow, arms=arms)
    layout = separate(ps.patches, shrunk.at(0.0), body_F, panels=panels)
    layout.lifted, layout.raise_arms, layout.out_of_paths, layout.bent = lifted, angle, out, bent
    layout.below_resolution = sorted({n for q in ps.quality.values() for n in q.get("seams_below_resolution", [])})
    save_patchset(outdir / "patches.json", ps)
    return layout


def _how_far(report: dict, sim, check) -> dict[str, float]:
    """Record where the run got to, finished or stopped: the widest seam gap and the five
    widest seams (mm), the crossings of the frames written and the simulated time.
    Returns every seam's gap, m."""
    gaps = sim.seam_gaps()
    report["seam_gap_max_mm"] = round(max(gaps.values(), default=0.0) * 1e3, 3)
    report["worst_seams_mm"] = {k: round(v * 1e3, 2) for k, v in sorted(gaps.items(), key=lambda kv: -kv[1])[:5]}
    report["crossings"] = int(check.crossings)
    report["simulated_s"] = round(sim.state.t, 3)
    # How far the body is from its pose, held back by cloth it could not push aside (arms
    # lowered onto sleeves sewn round them raised: dress_777_04 ended 210 mm short).
    drive = sim.model.drive
    report["body_lag_mm"] = round(drive.lag() * 1e3, 1) if drive is not None else 0.0
    return gaps


def _fold_reason(root: str, panels, options) -> str:
    """Why a patch of pattern panel `root` still folds after every cut: the panel's outline
    pinched to (almost) nothing (a strap whose two sides meet), or in general a net no cut
    could untangle."""
    from conform.boundary import extract_outline
    from conform.pipeline import NECK_LOBE
    from conform.split import PINCH, necks_of

    by_name = {p.name: p for p in panels}
    necks = necks_of(extract_outline(by_name[root]), NECK_LOBE * options.knot_span) if root in by_name else []
    if necks and min(n.depth for n in necks) < PINCH:
        n = min(necks, key=lambda n: n.depth)
        where = 100.0 * (n.tip + 0.5 * n.depth * n.axis)
        return (f"panel {root}'s outline narrows to {n.depth * 1e3:.2g} mm or less at ({where[0]:.1f}, {where[1]:.1f}) cm "
                f"of the panel, too thin to be cloth: widen it to {PINCH * 1e3:g} mm or more in the pattern")
    return "its net folds over between quadrature points (no cut of the panel helped)"


# GarmentCode lays its patterns out around its mean bodies: 1.72 m tall, feet on the
# ground plane, centred on the vertical axis.
GARMENTCODE_HEIGHT = 1.72


def fit_to_body(patches, body_V: np.ndarray) -> None:
    """Move each GarmentCode panel (rigidly, Z-up metres) to the same place relative to
    this body as to GarmentCode's: its height above the feet scaled by the bodies' height
    ratio, its horizontal offset kept about the body's centre. On GarmentCode's own bodies
    this moves nothing by more than a few millimetres."""
    lo, hi = body_V.min(0), body_V.max(0)
    centre = trunk_centre(body_V)
    ratio = (hi[2] - lo[2]) / GARMENTCODE_HEIGHT
    for p in patches:
        c = p.world.reshape(-1, 3).mean(0)
        target = np.array([centre[0] + c[0], centre[1] + c[1], lo[2] + ratio * c[2]])
        p.world = p.world + (target - c)


def dress_scene(patches: Path, obstacle: dict, o: DressOptions, preroll: float | None = None,
                frames: int | None = None, name: str | None = None, drag: bool = True, base: Path | None = None):
    """The scene that sews and settles the placed garment `patches` on the body
    `obstacle` (a scene [[obstacle]] table, which gets the inset) with the defaults `o`;
    preroll: the bodies' pre-roll (default: the sewing time; a moving body starts after
    it, and gravity starts with it: the body is whole only then); frames: default
    max_time's worth; drag: o.settle_drag after the pre-roll (a still body: to rest
    without swinging), else none (a moving body's motion is followed); base: the scene
    file the obstacle's relative paths are relative to (default: beside `patches`)."""
    from ..scene.read import parse_scene

    data = {
        "scene": {"name": name or patches.parent.name or "dress"},
        "material": {"preset": o.material},
        "garment": [{"name": "garment", "source": str(patches.resolve()), "seam_stiffness": o.seam_stiffness}],
        "obstacle": [{**obstacle, "inset": o.inset}],
        # Weightless while sewing: the garment cannot drop off the shrunk body before its
        # seams hold and the body has grown back; then gravity ramps in.
        "load": {"gravity": [0.0, 0.0, -9.81], "start": preroll or o.sew_time, "ramp": o.gravity_ramp},
        "contact": {"dhat": o.dhat, "kappa": "adaptive", "mu": o.mu, "eps_v": o.eps_v},
        "time": {"dt": o.dt, "steps_per_frame": o.steps_per_frame, "preroll": preroll or o.sew_time,
                 "newton_extrapolate": o.newton_extrapolate,
                 "newton_relative_tol": o.newton_relative_tol if drag else 0.0,
                 "sewing": "quasistatic",
                 "settle_drag": o.settle_drag if drag else 0.0,
                 "frames": frames or int(np.ceil(o.max_time / (o.dt * o.steps_per_frame)))},
    }
    return parse_scene(data, base or patches.parent / "scene.toml")


# m: a garment whose mean height has dropped this far below where it was placed has slid
# off the body; with no floor, nothing stops it (skirt_06: a 157 cm waistband on a ~75 cm
# waist fell at 0.8 m/s until the 10-minute limit). Its mean, not its lowest point: that
# floor-length skirt's hem starts 15 cm below the feet, and a hood falls down the back.
FALLEN = 0.25


class _Check:
    """Sink: the independent crossing check on every exported frame, and how far the
    garment's mean height has dropped since the first (`drop`, m)."""

    def __init__(self):
        self.crossings = 0
        self.worst = (0, 0)
        self.non_finite = False
        self.start = None
        self.drop = 0.0

    def open(self, meshes) -> None:
        self.meshes = meshes

    def write(self, frame) -> None:
        cloth = [(frame.positions[m.name], m.faces) for m in self.meshes if m.kind == "cloth"]
        bodies = [(frame.positions[m.name], m.faces) for m in self.meshes if m.kind != "cloth"]
        body, cloth_pairs = frame_crossings(cloth, bodies)
        if body < 0:
            self.non_finite = True
            return
        if cloth:
            z = mean_height(cloth)
            self.start = z if self.start is None else self.start
            self.drop = self.start - z
        self.crossings += body + cloth_pairs
        if body + cloth_pairs > sum(self.worst):
            self.worst = (body, cloth_pairs)

    def close(self) -> None:
        pass


class _Frames:
    """Sink: calls back with every frame written after the first (its steps taken)."""

    def __init__(self, callback):
        self.callback = callback

    def open(self, meshes) -> None:
        pass

    def write(self, frame) -> None:
        if frame.steps:
            self.callback(frame)

    def close(self) -> None:
        pass


# The phases of a dress run, for the report's time split.
PHASES = ("sewing", "gravity_ramp", "settling")
SPLITS_KEPT = 10  # the report keeps the first few split messages (why each step failed)


def phase_at(t: float, o: DressOptions) -> str:
    """The phase of the step ending at t: sewing (seams close, the body grows back),
    gravity_ramp, settling."""
    if t <= o.sew_time + 1e-9:
        return "sewing"
    return "gravity_ramp" if t <= o.sew_time + o.gravity_ramp + 1e-9 else "settling"


def mean_height(cloth: list) -> float:
    """Mean z (m) of the vertices of all cloth meshes [(V, F)]."""
    return float(np.concatenate([V[:, 2] for V, _ in cloth]).mean())


def _simulate(scene, o: DressOptions, outdir: Path, frame: BodyFrame, report: dict, start: float, on_frame) -> None:
    from sim.driver import drive
    from viz.rerun_sink import RerunSink

    from ..build import build_simulator

    try:
        sim = build_simulator(scene)
    except InputError as e:
        raise DressFailure("placement", str(e)) from None
    report["dofs"] = int(sim.n_dofs)
    frames = scene.time.frames
    check = _Check()
    calm = {"frames": 0, "still": 0, "settled": None, "timeout": False, "fell": None}
    phases = report["phases"] = {name: {"steps": 0, "seconds": 0.0, "newton_iterations": 0, "splits": 0}
                                 for name in PHASES}
    clock = [time.perf_counter()]
    # The time step changes between frames only: the first frame end once the body grows.
    frame_time = o.dt * o.steps_per_frame
    grow_from = np.ceil(0.5 * o.sew_time / frame_time - 1e-9) * frame_time
    report["placing_s"] = round(clock[0] - start, 2)  # reading, conforming, placing, building

    def at_rest() -> bool:
        if time.perf_counter() - start > o.timeout:
            calm["timeout"] = True
            return True
        if check.drop > FALLEN:
            calm["fell"] = (sim.state.t, check.drop)
            return True
        if calm["settled"] is not None:
            return True
        # The frame count is max_time in sewing frames; settling frames can be longer.
        return sim.state.t >= o.max_time - 1e-9

    def on_step(st) -> None:
        t = sim.state.t
        # Wall-clock time since the last step (its frame's output and checks included);
        # the iterations of a step split in two are those of its last half.
        phase = phases[phase_at(t, o)]
        now = time.perf_counter()
        phase["steps"] += 1
        phase["seconds"] += now - clock[0]  # rounded once, when the report is written
        phase["newton_iterations"] += st.newton_iterations
        clock[0] = now
        if t >= o.sew_time - 1e-9:
            if "drawstring" not in report:  # sewn: an opening too wide to rest on is drawn in
                report["drawstring"] = draw_in(sim, (t, t + o.gravity_ramp))
            if sim.dt != o.settle_dt:
                sim.set_dt(o.settle_dt)  # sewn: longer steps to the rest shape (DressOptions.settle_dt)
        elif t >= grow_from - 1e-9 and sim.dt != o.grow_dt:
            sim.set_dt(o.grow_dt)  # seams stiff, the body growing back (DressOptions.grow_dt)

    def on_split(message: str) -> None:
        # A failed step retried as two halves: the failed attempt's time is in its phase's
        # seconds but not its iterations (dress_06, stop 77: 564 s of sewing, 394 iterations).
        phases[phase_at(sim.state.t + sim.dt, o)]["splits"] += 1
        report.setdefault("splits", [])
        if len(report["splits"]) < SPLITS_KEPT:
            report["splits"].append(message)
        warnings.warn(message, SplitWarning, stacklevel=2)

    def on_frame_written(frame) -> None:
        t, st = frame.time, frame.steps[-1]
        if on_frame is not None:
            on_frame(frame.index, frames, st)
        if t < o.sew_time + o.gravity_ramp - 1e-9:
            return
        rms = st.extra["speed_rms"]  # of the frame's last step, before the drag
        gaps = sim.seam_gaps()
        closed = max(gaps.values(), default=0.0) < 1e-3
        calm.setdefault("trace", []).append(round(rms * 1e3, 1))
        calm["frames"] = calm["frames"] + 1 if rms < o.rest_speed and closed else 0
        calm["still"] = calm["still"] + 1 if rms < o.rest_speed else 0  # seams or not
        if calm["frames"] >= o.rest_frames and calm["settled"] is None:
            calm["settled"] = t

    sinks = [RerunSink(outdir / "run.rrd", recording_name=scene.name), check, _Frames(on_frame_written)]
    try:
        drive(sim, frames, o.steps_per_frame, sinks, should_stop=at_rest, floor=o.dt / 16, on_step=on_step,
              on_warning=on_split,
              frame_time=frame_time)
    except SimulationError as e:
        # What the run got to: the open seams name the panels, the crossings count the
        # frames written (upper_garment_06 stopped at 0.84 s with its cuffs 18-27 mm open).
        _how_far(report, sim, check)
        bad = not np.all(np.isfinite(sim.state.C))
        raise DressFailure("nan" if bad else "sewing" if sim.state.t < o.sew_time else "intersection", str(e)) from None
    gaps = _how_far(report, sim, check)
    gap = max(gaps.values(), default=0.0)
    report["worst_frame_crossings"] = {"garment_body": check.worst[0], "garment_garment": check.worst[1]}
    report["settle_time_s"] = None if calm["settled"] is None else round(calm["settled"], 3)
    trace = calm.get("trace", [])
    report["speed_rms_mm_s"] = trace  # per exported frame after sewing
    _write_garment(sim, outdir / "garment.obj", frame)
    moving = None if calm["settled"] is not None or calm["timeout"] else (sim.state.t, trace[-1] if trace else None)
    fell = None if calm["fell"] is None else (*calm["fell"], _loose_opening(sim))
    report["status"], report["error"] = verdict(
        check.non_finite or not np.all(np.isfinite(sim.state.C)), check.crossings,
        o.timeout if calm["timeout"] else None, gap, report["worst_seams_mm"], fell, moving,
        still=calm["still"] >= o.rest_frames)


def _loose_opening(sim) -> str | None:
    """Why a garment that slid off could not stay on, when its top opening is wider than
    the body's trunk anywhere (garment/dress/girth.py): a sentence naming the opening's
    panels and both lengths, or None."""
    body = body_mesh(sim)
    cloth, X, T = _garment_mesh(sim)
    if not cloth or body is None:
        return None
    found = loose_opening(X, T, *body)
    if found is None:
        return None
    loop, length, girth, height = found
    on_loop = {tuple(p) for p in X[loop]}
    panels = [name for name, V, _ in cloth if any(tuple(p) in on_loop for p in V)]
    return (f"its top opening ({', '.join(panels)}) is {100 * length:.0f} cm round, and the body's trunk is at "
            f"most {100 * girth:.0f} cm round (at {height:.2f} m): narrow that waist or neckline in the pattern")


def verdict(non_finite: bool, crossings: int, timed_out: float | None, gap: float,
            worst_seams_mm: dict, fell: tuple[float, float] | None = None,
            moving: tuple[float, float | None] | None = None, still: bool = False) -> tuple[str, str | None]:
    """(status, error) of a finished run, the gravest failure first: cloth through cloth or
    body is reported even when the run also ran out of time (it was reported as "timeout"
    at 6ff4f59, hiding jumpsuit_02's 16 crossings). fell: (t, m dropped[, why]) when the garment
    slid off the body (a `placement` failure: this body cannot wear it). moving: (t, RMS
    speed in mm/s of the last frame, None before gravity) when the run reached max_time
    without coming to rest: not settled, so a `timeout` (skirt_04 was "ok" at 2.5 s while
    its side seams slid off the hands at 0.1-0.2 m/s). still: the cloth was at rest over the
    last rest_frames frames, seams or not: with seams open that is a `sewing` failure, not a
    timeout (jumpsuit_00 lay still from 1.1 s to the 10-minute limit, two seams 6 mm open)."""
    if non_finite:
        return "nan", None
    if crossings:
        return "intersection", f"{crossings} intersecting triangle pairs over the exported frames"
    if fell is not None:
        why = fell[2] if len(fell) > 2 and fell[2] else ("nothing on the body holds it up (a waist or neckline "
                                                         "wider than the body where it should rest?)")
        return "placement", (f"the garment slid off the body: by t = {fell[0]:.2f} s it had dropped "
                             f"{fell[1]:.2f} m (mean height) from where it was placed; {why}")
    seams = ", ".join(f"{k} {v} mm" for k, v in worst_seams_mm.items())
    if still and gap >= 1e-3:
        return "sewing", "at rest with seams still open: " + seams
    if timed_out is not None:
        return "timeout", f"not at rest after {timed_out:.0f} s of wall-clock time"
    if moving is not None:
        speed = "" if moving[1] is None else f" (RMS control-point speed {moving[1]:g} mm/s)"
        return "timeout", f"not at rest after {moving[0]:.2f} s of simulated time (max_time){speed}"
    if gap >= 1e-3:
        return "sewing", "seams still open: " + seams
    return "ok", None


def _write_garment(sim, path: Path, frame: BodyFrame) -> None:
    """The settled garment as one mesh (sewn panels joined at their shared seam vertices),
    in the body file's units and axes."""
    from viz.recording import export_mesh

    _, X, T = _garment_mesh(sim)
    export_mesh(path, from_scene_frame(X, frame.scale, frame.up), T)


def _garment_mesh(sim):
    """The cloth pieces [(name, V, F)] as they stand, and the garment as one mesh (X, T),
    sewn panels joined at their shared seam vertices."""
    pos = sim.positions()
    cloth = [(m.name, pos[m.name], m.faces) for m in sim.topologies() if m.kind == "cloth"]
    if not cloth:
        return cloth, np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return cloth, *shared_vertices(*stack_meshes([(V, F) for _, V, F in cloth]))
