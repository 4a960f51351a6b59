"""From a validated scene (garment/scene) to a simulator: garments conformed or read,
bodies loaded and timed for the pre-roll, pins selected, options filled in."""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import fields, is_dataclass
from pathlib import Path

import numpy as np

from sim.budget import require_memory, simulation_bytes
from sim.drag import Drag
from sim.errors import InputError
from sim.linear.model import cloth_mesh, linear_model, select_vertices
from sim.linear.mesh import TriangleMesh
from sim.model import ContactOptions, bspline_model
from sim.newton import NewtonOptions
from sim.patches import Patch
from sim.pins import PinGroup, select
from sim.seams.sewing import SewingOptions
from sim.seams.spec import SeamSpec
from sim.simulator import Simulator

from .io.garments import load_garment
from .io.obstacles import load_obstacle


def build_simulator(scene, newton: NewtonOptions | None = None, keep_crossings: bool = False) -> Simulator:
    """The B-spline simulation of `scene` (garment.scene.Scene). keep_crossings: see
    sim.model.Model (states handed over from a coarser run only)."""
    check_memory(scene)  # before the cloths' nets are even allocated
    patches = [c.patch() for c in scene.cloths]
    groups = _pins(scene, [p.shape for p in patches], [p.n_control_points for p in patches],
                   lambda pin, shape: select(shape, pin.corners, pin.sides, pin.box, pin.depth))
    directions = _pressure_directions(scene)
    materials = [c.material for c in scene.cloths]
    seams, stiffness = [], []
    garment_patches = {}
    for g in scene.garments:
        ps = garment_patches[g.name] = load_garment(g)
        name = {p.name: f"{g.name}.{p.name}" for p in ps.patches}
        for p in ps.patches:
            if not (np.all(np.isfinite(p.rest)) and np.all(np.isfinite(p.world))):
                raise InputError(f"{g.source}: garment {g.name!r}: patch {p.name} has non-finite control points")
            patches.append(Patch(name[p.name], p.rest, p.world))
            materials.append(g.material)
            directions.append(np.array([0.0, 0.0, 1.0]))
        index = {s.name: len(seams) + k for k, s in enumerate(ps.seams)} if g.pleat_wait else {}
        seams += [SeamSpec(name[s.patch_a], s.uv_a, name[s.patch_b], s.uv_b, s.name,
                           tuple(index[a] for a in s.after if a in index)) for s in ps.seams]
        stiffness += [g.seam_stiffness] * len(ps.seams)
    tm = scene.time
    obstacles = [load_obstacle(o, tm) for o in scene.obstacles]
    check_memory(scene, garment_patches, sum(len(o.vertices) for o in obstacles))
    # Pre-roll: bodies hold their first pose while the seams close; inset bodies grow
    # back in its second half, once the seams are sewn.
    sewn = 0.5 * tm.preroll if any(o.inset > 0.0 or o.raise_arms > 0.0 for o in scene.obstacles) else tm.preroll
    for o, spec in zip(obstacles, scene.obstacles):
        # A rigged body's sequence starts with its blend from the bind pose, played at the
        # end of the pre-roll.
        o.delay = tm.preroll - (o.sequence.lead_in if o.sequence is not None else 0.0)
        o.inset, o.raise_arms, o.grow = spec.inset, spec.raise_arms, (sewn, tm.preroll)
    model = bspline_model(
        patches, materials, groups, scene.load.gravity, scene.load.pressure, directions, tm.dt, tm.mode,
        NewtonOptions.for_time(tm, newton), None if scene.garments else scene.output.mesh_resolution,
        contact_options(scene.contact), obstacles, seams, stiffness or 1e6, sewing_options(scene, sewn, tm.preroll),
        keep_crossings, Drag(tm.settle_drag, tm.preroll))
    model.loads.window = (scene.load.start, scene.load.start + scene.load.ramp)
    V0 = np.zeros_like(model.C0)
    for c, piece in zip(scene.cloths, model.pieces):
        V0[piece.slice] = np.asarray(c.velocity, float)
    return Simulator(model, model.initial_state(V0))


def build_linear_simulator(scene, resolution=None, layout: str = "grid",
                           newton: NewtonOptions | None = None) -> Simulator:
    """The linear-FEM baseline of `scene`: each cloth a `layout` mesh with `resolution`
    vertices per side (default: its control-point count), pins mapped to vertices by
    position."""
    meshes = [cloth_mesh(c.size, resolution or c.control_points, layout) for c in scene.cloths]
    worlds = [cloth_world(c, m) for c, m in zip(scene.cloths, meshes)]
    groups = _pins(scene, meshes, [m.n_vertices for m in meshes],
                   lambda pin, mesh: select_vertices(mesh, pin.corners, pin.sides, pin.box, pin.depth))
    tm = scene.time
    model = linear_model(meshes, worlds, [c.material for c in scene.cloths], groups, scene.load.gravity,
                         scene.load.pressure, _pressure_directions(scene), tm.dt, tm.mode,
                         NewtonOptions.for_time(tm, newton), contact_options(scene.contact),
                         [load_obstacle(o, tm) for o in scene.obstacles], [c.name for c in scene.cloths])
    return Simulator(model)


def check_memory(scene, garments: dict | None = None, obstacle_vertices: int = 0) -> None:
    """Refuse a scene whose simulation would not fit in memory (sim/budget.py), naming the
    setting to change: the largest cloth's control_points or garment's knot_span_mm.
    garments: name -> PatchSet once conformed (before: cloths only)."""
    parts = [(c.control_points[0] * c.control_points[1],
              f"control_points of cloth {c.name!r} (now {c.control_points[0]} x {c.control_points[1]})")
             for c in scene.cloths]
    specs = {g.name: g for g in scene.garments}
    parts += [(sum(p.n_control_points for p in ps.patches),
               f"raise knot_span_mm of garment {name!r} (now {specs[name].knot_span * 1e3:g} mm)")
              for name, ps in (garments or {}).items()]
    if not parts:
        return
    total = sum(n for n, _ in parts)
    contact = scene.contact.mesh_density * total + obstacle_vertices if scene.contact.enabled else 0
    largest = max(parts)[1]
    fix = largest if largest.startswith("raise") else f"reduce {largest}"
    where = scene.path if scene.path is not None else scene.name
    require_memory(simulation_bytes(total, int(contact)),
                   f"{where}: simulating {total} control points ({3 * total} DOFs)", fix)


def contact_options(spec) -> ContactOptions:
    """sim's contact options from a scene's [contact] table."""
    return ContactOptions(**{f.name: getattr(spec, f.name) for f in fields(ContactOptions)})


def sewing_options(scene, ramp: float, preroll: float = 0.0) -> SewingOptions:
    """The sewing policy from a scene's [sewing] table, its sewing mode, the ramp and the
    pre-roll (s)."""
    given = {f.name: getattr(scene.sewing, f.name) for f in fields(scene.sewing)}
    return SewingOptions(ramp=ramp, quasistatic=scene.time.sewing == "quasistatic", preroll=preroll, **given)


def _pins(scene, shapes, sizes, pick) -> list[PinGroup]:
    """Pin groups with global indices; pick(pin, shapes[k]) gives cloth k's local ones."""
    offsets = np.cumsum([0] + list(sizes))
    by_name = {c.name: k for k, c in enumerate(scene.cloths)}
    groups = []
    for pin in scene.pins:
        k = by_name[pin.cloth]
        local = pick(pin, shapes[k])
        groups.append(PinGroup(local + offsets[k], np.asarray(pin.velocity, float), pin.start, pin.duration))
    return groups


def _pressure_directions(scene) -> list[np.ndarray]:
    load = scene.load
    return [np.asarray(load.pressure_direction, float) if load.pressure_direction is not None else c.normal
            for c in scene.cloths]


def cloth_world(cloth, mesh: TriangleMesh) -> np.ndarray:
    """Initial world vertices of a scene cloth (garment.scene.ClothSpec) on `mesh`."""
    au = np.asarray(cloth.axis_u, float)
    av = np.asarray(cloth.axis_v, float)
    au, av = au / np.linalg.norm(au), av / np.linalg.norm(av)
    X = mesh.rest
    world = np.asarray(cloth.origin, float) + X[:, :1] * au + X[:, 1:] * av
    if cloth.perturbation is not None:
        st = mesh.normalized
        wu, wv = cloth.perturbation.waves
        wave = [np.sin(np.pi * w * x) if w else np.ones_like(x) for w, x in ((wu, st[:, 0]), (wv, st[:, 1]))]
        world += (cloth.perturbation.amplitude * wave[0] * wave[1])[:, None] * cloth.normal
    return world


# --------------------------------------------------------------------------- scene identity


def scene_hash(scene) -> str:
    """SHA-256 over what determines the simulation: the validated scene (frame count and
    outputs excluded, so a resumed run may go further or write elsewhere) and the bytes
    of every mesh or body file it reads."""
    h = hashlib.sha256()
    spec = dataclasses.replace(scene, path=None, output=dataclasses.replace(scene.output, rrd=None, mesh_dir=None),
                               time=dataclasses.replace(scene.time, frames=0))
    h.update(_canonical(spec).encode())
    for o in scene.obstacles:
        rigged = [o.skin.mesh, o.skin.rig, o.skin.weights, o.skin.motion] if o.skin else \
            [o.smpl.model, o.smpl.motion] if o.smpl else []
        for p in [o.mesh, o.animation, *rigged]:
            if p is not None:
                for f in sorted(Path(p).rglob("*")) if Path(p).is_dir() else [Path(p)]:
                    if f.is_file():
                        h.update(f.name.encode())
                        h.update(f.read_bytes())
    return h.hexdigest()


def _canonical(x) -> str:
    """A repr that does not abbreviate arrays and names every field."""
    if is_dataclass(x):
        return f"{type(x).__name__}(" + ",".join(f"{f.name}={_canonical(getattr(x, f.name))}" for f in fields(x)) + ")"
    if isinstance(x, (list, tuple)):
        return "[" + ",".join(_canonical(v) for v in x) + "]"
    if isinstance(x, dict):
        return "{" + ",".join(f"{k!r}:{_canonical(v)}" for k, v in sorted(x.items())) + "}"
    if isinstance(x, np.ndarray):
        return f"array({x.dtype},{x.shape},{x.tobytes().hex()})"
    if isinstance(x, Path):
        return repr(str(x))
    return repr(x)
