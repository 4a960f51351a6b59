"""A scene file that names a garment and a body and leaves where the garment starts to
the toolkit: it is dressed as `garment dress` dresses (job.py), with the scene's physical
choices; an animated body then moves as the scene says.

    [[garment]] source = "shirt.json"     [[obstacle]] mesh = "body.obj"   (or animation = "dance.npz")

Such a scene gives none of the keys that place a garment by hand (PLACEMENT: the body's
`inset`, `translate` and `raise_arms`, the pre-roll and the sewing mode). It may still
choose the material preset, knot spans, seam stiffness, contact distance and friction,
time step and length of the run, the body's units, up axis and frame rate, and the
outputs (CHOICES). The garment is placed on the body's first pose; an animated body holds
it while the seams close and the body grows back (the pre-roll, DressOptions.sew_time),
then moves, and gravity comes on with the motion; a still body's garment settles under
a drag instead.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.errors import InputError

from ..scene.specs import OBSTACLE_KINDS
from .frame import BodyFrame, read_body

# Keys that place a garment by hand; a scene with any of them is taken as written.
PLACEMENT = {"obstacle": ("inset", "translate", "raise_arms"), "time": ("preroll", "sewing")}

# What else such a scene may say: table -> {key: the DressOptions field it sets (None: used here)}.
CHOICES = {
    "scene": {"name": None, "description": None},
    "material": {"preset": "material"},
    "garment": {"name": None, "source": None, "knot_span_mm": "knot_span_mm", "seam_span_mm": "seam_span_mm",
                "seam_stiffness": "seam_stiffness"},
    "obstacle": {"name": None, "mesh": None, "animation": None, "fps": None, "up": None, "scale": None},
    "contact": {"dhat": "dhat", "mu": "mu", "eps_v": "eps_v", "kappa": None},
    "time": {"dt": "dt", "steps_per_frame": "steps_per_frame", "frames": None},
    "output": None,  # every output key
}


BODY_KINDS = ("mesh", "animation")  # the bodies such a scene may name (a rigged one needs its pre-roll)


def leaves_placement(data: dict) -> bool:
    """Whether a scene (its TOML as read) names one garment `source` on one body (a `mesh`
    or an `animation`) and none of the PLACEMENT keys."""
    garments, obstacles = data.get("garment", []), data.get("obstacle", [])
    if len(garments) != 1 or len(obstacles) != 1 or "cloth" in data or "pin" in data:
        return False
    kinds = [k for k in OBSTACLE_KINDS if k in obstacles[0]]
    if "source" not in garments[0] or len(kinds) != 1 or kinds[0] not in BODY_KINDS:
        return False
    tables = {"obstacle": obstacles[0], "time": data.get("time", {})}
    return not any(k in tables[t] for t, keys in PLACEMENT.items() for k in keys)


def dress_settings(data: dict, source: Path) -> dict:
    """The `garment dress` settings (DressOptions fields) a placement-free scene chooses.
    Raises InputError for a key such a scene cannot take, naming it and the way out."""
    settings = {}
    for table, value in data.items():
        rows = value if isinstance(value, list) else [value]
        allowed = CHOICES.get(table, {})
        for row in rows:
            for key, v in (row.items() if isinstance(row, dict) else ()):
                if allowed is None:
                    continue
                if key not in allowed or (table == "contact" and key == "kappa" and v != "adaptive"):
                    raise InputError(
                        f"{source}: [{table}] {key}: this scene leaves the garment's start to the toolkit "
                        f"(no [time] preroll, no body inset or translate), which sets {key} itself. Remove "
                        f"{key}, or place the garment yourself: give [time] preroll (docs/scenes.md)")
                if allowed[key] is not None:
                    settings[allowed[key]] = v
    return settings


def body_frame(obstacle: dict, body: Path):
    """The body's frame (its units and up axis: the scene's, or found from its shape),
    its vertices in the simulator's frame and its faces."""
    from ..io.bodies import to_scene_frame

    V, F, frame = read_body(body)
    if "up" in obstacle or "scale" in obstacle:
        frame = BodyFrame(float(obstacle.get("scale", 1.0)), obstacle.get("up", "z"), "as given")
    return frame, to_scene_frame(V.astype(float), frame.scale, frame.up), F.astype(np.int32)


def scene_for_run(path: Path, folder: Path, garment_changes: dict | None = None):
    """The scene file at `path` as `garment simulate` runs it: a scene that leaves the
    garment's start to the toolkit (leaves_placement) is dressed, its placed garment
    written to `folder`; any other is read as written. garment_changes: keys set in its
    [[garment]] tables first (None removes one; a benchmark's knot_span_mm)."""
    from ..scene.read import parse_scene, read_scene_data

    data = read_scene_data(Path(path))
    if garment_changes:
        data = {**data, "garment": [{k: v for k, v in {**g, **garment_changes}.items() if v is not None}
                                    for g in data.get("garment", [])]}
    scene = parse_scene(data, Path(path))
    return dressed_scene(data, scene, folder) if leaves_placement(data) else scene


def dressed_scene(data: dict, scene, folder: Path):
    """The scene that dresses the body of a placement-free scene (`scene`, as read from
    its TOML `data`) in its garment: the garment conformed and placed by
    job.place_garment into `folder`/patches.json, then sewn and settled (or danced) on
    job.dress_scene's schedule."""
    from ..io.obstacles import load_obstacle
    from .job import DressFailure, DressOptions, dress_scene, place_garment

    source = scene.path

    options = DressOptions.with_overrides(dress_settings(data, source))
    garment, obstacle = data["garment"][0], data["obstacle"][0]
    pattern = (source.parent / garment["source"]).resolve()
    if not pattern.is_file():
        raise InputError(f"{source}: the garment source {pattern} does not exist")
    still = "mesh" in obstacle
    if still:
        body = (source.parent / obstacle["mesh"]).resolve()
        if not body.is_file():
            raise InputError(f"{source}: the body mesh {body} does not exist")
        frame, V, F = body_frame(obstacle, body)
        table = {"name": obstacle.get("name", "body"), "mesh": str(body), "scale": frame.scale, "up": frame.up}
    else:  # its first pose, in the simulator's frame as the scene turns it (`up`, `scale`)
        geometry = load_obstacle(scene.obstacles[0])
        frame, V, F = BodyFrame(1.0, "z", "m"), geometry.vertices, geometry.faces
        table = dict(obstacle)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        placed = place_garment(pattern, frame, V, F, options, folder)
    except DressFailure as e:  # a pattern that does not conform
        raise InputError(f"{pattern}: {e}") from None
    table["raise_arms"] = placed.raise_arms
    scene_info = data.get("scene", {})
    scene = dress_scene(folder / "patches.json", table, options, frames=data.get("time", {}).get("frames"),
                        name=scene_info.get("name") or source.stem, drag=still, base=source)
    scene.description = scene_info.get("description", scene.description)
    return scene
