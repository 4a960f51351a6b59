"""Bodies posed by a skeleton's motion, as scene obstacles (`[obstacle.skin]`,
`[obstacle.smpl]`) and as the bundled MakeHuman + CMU demo body.

Whatever the source, the result is a BodySequence (garment/io/bodies.py) the rest of the
pipeline already knows. The motion is resampled at a multiple of the simulation's time
step no finer than the motion's own frame time (rotations slerped, so a step lands on a
skinned pose, not between two), only as far as the run needs; `lead` frames before it
blend from the bind pose into the first motion frame at the end of the pre-roll.

Units and axes are checked before any motion is read: a body must be a person's size
after `scale` (MakeHuman exports decimetres: scale = 0.1), and a skinned mesh left
without `up` must not look Y-up. SMPL models are metres and Y-up by definition; the
motion's up axis (AMASS: Z) is found from its first frame's root rotation when not given.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sim.errors import InputError

from .bodies import BodySequence, check_up_axis
from .bvh import read_bvh
from .retarget import retarget
from .rig import read_makehuman, rig_to_scene
from .skinning import posed_sequence
from .smpl import read_model, read_motion, smpl_track, up_axis

# A person's largest extent after scaling (m): arm span or height, a child to a tall adult.
PERSON_M = (0.5, 2.6)
# Units a body file may have been written in (m per unit), most likely first.
BODY_UNITS = (("decimetres (MakeHuman's unit)", 0.1), ("centimetres", 0.01), ("inches", 0.0254),
              ("millimetres", 0.001))

MAKEHUMAN_CMU = Path(__file__).resolve().parents[2] / "assets" / "bodies" / "makehuman_cmu"
# cmu_mb rig -> CMU BVH names; the clavicles stay with the spine (garment/io/retarget.py).
MAKEHUMAN_JOINTS = {"LeftHandFinger1": "LFingers", "RightHandFinger1": "RFingers", "LeftShoulder": "",
                    "RightShoulder": ""}
LIVELY = (417, 777)  # 01_01.bvh frames 3.47-6.47 s: the fastest 3 s of joint motion (two forward jumps)


def rigged_sequence(spec, time=None) -> BodySequence:
    """The frames of a garment.scene.ObstacleSpec of kind "skin" or "smpl"; `time` (a
    TimeSpec) sets the sampling, how much motion is posed and the pre-roll blend
    (None: the whole range at the motion's own frame time, no blend)."""
    if spec.kind == "skin":
        s = spec.skin
        rig = rig_to_scene(read_makehuman(s.mesh, s.group, s.rig, s.weights), spec.scale, spec.up or "z",
                           spec.translate)
        check_person(s.mesh, rig.vertices, spec.scale, spec.up)
        clip = read_bvh(s.motion)
        if spec.fps is not None:
            clip.frame_time = 1.0 / spec.fps
        times, frame_dt, lead = timing(s.motion, s.start, s.end, clip.duration, clip.frame_time, spec.blend, time)
        track = retarget(clip, rig, times, frame_dt, dict(s.joints))
        return posed_sequence(rig, track, lead, str(s.mesh))
    s = spec.smpl
    model = read_model(s.model)
    motion, notes = read_motion(s.motion, model.n_joints, model.shapedirs.shape[2], spec.fps)
    rig = model.rig(motion.betas, spec.scale, spec.translate)
    check_person(s.model, rig.vertices, spec.scale, "y")
    times, frame_dt, lead = timing(s.motion, s.start, s.end, motion.duration, 1.0 / motion.fps, spec.blend, time)
    up = spec.up
    if up is None:
        up = up_axis(motion, times[0])
        notes.append(f"{motion.path.name}: the motion is {up.upper()}-up (from its first frame's root rotation)")
    rig.notes += notes
    track = smpl_track(model, motion.betas, motion, times, frame_dt, up, spec.scale)
    return posed_sequence(rig, track, lead, str(s.model))


def timing(path, start: float, end: float | None, duration: float, motion_dt: float, blend: float | None,
           time=None) -> tuple[np.ndarray, float, int]:
    """(sample times in the motion (s), frame time of the sequence (s), lead frames)."""
    stop = duration if end is None else min(end, duration)
    if start > stop:
        raise InputError(f"{path}: start = {start:g} s is past the motion's end ({duration:g} s)")
    dt = motion_dt if time is None else time.dt
    frame_dt = dt * max(1, math.floor(motion_dt / dt + 1e-9))
    span = stop - start
    if time is not None:
        span = min(span, max(time.frames * time.steps_per_frame * time.dt - time.preroll, 0.0))
    n = math.ceil(span / frame_dt - 1e-9) + 1
    times = start + np.minimum(np.arange(n) * frame_dt, stop - start)
    if blend is None:
        blend = 0.5 * time.preroll if time is not None else 0.0
    return times, frame_dt, math.floor(blend / frame_dt + 1e-9)


def check_person(path, vertices: np.ndarray, scale: float, up: str | None) -> None:
    """InputError unless the bind mesh (m, scene frame) is a person's size and, with no
    `up` given, upright along Z."""
    extent = float(np.ptp(vertices, axis=0).max())
    lo, hi = PERSON_M
    if not lo <= extent <= hi:
        guess = next(((name, f) for name, f in BODY_UNITS if 0.8 <= extent * f <= 2.3), None)
        hint = f"looks like {guess[0]}: set scale = {scale * guess[1]:g}" if guess else \
            "set `scale` to convert the file to metres"
        raise InputError(f"{path}: the body is {extent:.3g} m across after scale = {scale:g}, not a person's "
                         f"{lo:g} to {hi:g} m; {hint}")
    if up is None:
        check_up_axis(path, vertices)


def makehuman_cmu(first: int = LIVELY[0], stop: int = LIVELY[1], fps: float = 30.0, blend: float = 0.0,
                  translate=(0.0, 0.0, 0.0)) -> BodySequence:
    """The bundled CC0 MakeHuman body (assets/bodies/makehuman_cmu) doing CMU motion 01_01
    frames [first, stop) (120 fps), resampled to `fps`, after `blend` s from its A-pose
    into frame `first` (BodySequence.lead_in). Metres, Z-up, feet on z = min of the bind
    pose (about -0.82 m) + translate."""
    d = MAKEHUMAN_CMU
    clip = read_bvh(d / "01_01.bvh")
    if not 0 <= first < stop <= clip.n_frames:
        raise InputError(f"frames [{first}, {stop}) are not within the clip's {clip.n_frames} frames")
    rig = rig_to_scene(read_makehuman(d / "body.obj", "body", d / "rig.cmu_mb.json", d / "weights.cmu_mb.json"),
                       0.1, "y", translate)
    frame_dt = 1.0 / fps
    times = np.arange(first * clip.frame_time, (stop - 1) * clip.frame_time + 1e-9, frame_dt)
    track = retarget(clip, rig, times, frame_dt, MAKEHUMAN_JOINTS)
    return posed_sequence(rig, track, math.floor(blend / frame_dt + 1e-9), "makehuman_cmu")
