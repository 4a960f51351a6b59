"""BVH motion capture: a joint hierarchy with rest offsets, then one line of channel values
per frame (Biovision's format, as the CMU conversions, MotionBuilder and Blender write it).

A joint's local rotation is the product of its rotation channels in the order listed
(intrinsic: "Zrotation Xrotation Yrotation" is Rz Rx Ry), in degrees. The rest pose is
every channel at zero: world orientations are the identity and joint positions the sums
of the offsets. The root's position channels place it; position channels of other joints
are read but not used (retargeting keeps the mesh's own bone lengths). Units are whatever
the file used (CMU: about 0.45 x inches, others cm or inches): retargeting scales by leg
length, never by a guessed unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.budget import require_memory
from sim.errors import InputError, printable
from sim.files import input_file

from .rotations import euler_matrix, matrix_quaternion, quaternion_matrix, slerp

MAX_BYTES = 256 * 2**20  # a longer capture is better trimmed than read whole
MAX_JOINTS = 1000
MAX_FRAME_TIME = 1.0  # s; a "frame time" above it is a frame rate or garbage
CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")


@dataclass
class BvhClip:
    """A parsed BVH file. names, parents (J,) (-1 for the root, parents before children),
    offsets (J, 3) in file units, channels per joint, values (T, C) in file units and
    degrees, frame_time in s."""

    path: Path
    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[str, ...]]
    values: np.ndarray
    frame_time: float
    end_sites: dict[int, np.ndarray] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return len(self.values)

    @property
    def duration(self) -> float:
        return (self.n_frames - 1) * self.frame_time

    def rest_positions(self) -> np.ndarray:
        """(J, 3) joint positions with every channel at zero."""
        p = np.zeros((len(self.names), 3))
        for j, parent in enumerate(self.parents):
            p[j] = self.offsets[j] + (p[parent] if parent >= 0 else 0.0)
        return p

    def local_rotations(self, frames: np.ndarray) -> np.ndarray:
        """(n, J, 3, 3) local rotations at the frame indices given."""
        frames = np.asarray(frames, int)
        out = np.broadcast_to(np.eye(3), (len(frames), len(self.names), 3, 3)).copy()
        col = 0
        for j, chans in enumerate(self.channels):
            rot = [k for k, c in enumerate(chans) if c.endswith("rotation")]
            if rot:
                axes = "".join(chans[k][0].lower() for k in rot)
                out[:, j] = euler_matrix(axes, self.values[frames][:, [col + k for k in rot]])
            col += len(chans)
        return out

    def root_positions(self, frames: np.ndarray) -> np.ndarray:
        """(n, 3) root positions (file units) at the frame indices given: its position
        channels where it has them, its offset otherwise."""
        p = np.broadcast_to(self.offsets[0], (len(frames), 3)).copy()
        for k, c in enumerate(self.channels[0]):
            if c.endswith("position"):
                p[:, "XYZ".index(c[0])] = self.values[np.asarray(frames, int), k]
        return p

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (n, J, 3, 3) relative to the rest pose and root positions (n, 3)
        at `times` (s from the first frame, clamped to the clip): local rotations are
        interpolated along the great circle (slerp), the root position linearly."""
        s = np.clip(np.asarray(times, float) / self.frame_time, 0.0, self.n_frames - 1)
        i0 = np.minimum(np.floor(s).astype(int), self.n_frames - 1)
        i1 = np.minimum(i0 + 1, self.n_frames - 1)
        w = s - i0
        q = slerp(matrix_quaternion(self.local_rotations(i0)), matrix_quaternion(self.local_rotations(i1)),
                  np.broadcast_to(w[:, None], (len(w), len(self.names))))
        local = quaternion_matrix(q)
        root = (1.0 - w)[:, None] * self.root_positions(i0) + w[:, None] * self.root_positions(i1)
        return world_rotations(self.parents, local), root


def world_rotations(parents: np.ndarray, local: np.ndarray) -> np.ndarray:
    """(n, J, 3, 3) world rotations from local ones (parents listed before children)."""
    world = np.empty_like(local)
    for j, p in enumerate(parents):
        world[:, j] = local[:, j] if p < 0 else world[:, p] @ local[:, j]
    return world


def read_bvh(path) -> BvhClip:
    """Parse and check a BVH file; InputError naming the file and the line otherwise."""
    path = input_file(path, "BVH motion")
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise InputError(f"{path}: {size / 2**20:.0f} MB is more motion than a scene needs (at most "
                         f"{MAX_BYTES // 2**20} MB); trim the clip")
    require_memory(40 * size, f"reading {path}", "trim the clip")  # text split into tokens
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not a BVH text file (byte {e.start} is not UTF-8)") from None
    head, sep, motion = text.partition("MOTION")
    if not sep:
        raise InputError(f"{path}: no MOTION section (truncated? a BVH file has HIERARCHY, then MOTION with the "
                         "frames)")
    names, parents, offsets, channels, ends = _hierarchy(path, head)
    values, frame_time = _motion(path, motion, sum(len(c) for c in channels), head.count("\n") + 1)
    return BvhClip(path, names, np.asarray(parents), np.asarray(offsets, float), channels, values,
                   frame_time, ends)


class _Tokens:
    """The hierarchy's words with their line numbers, for messages."""

    def __init__(self, path: Path, text: str):
        self.path = path
        self.words = [(w, n) for n, line in enumerate(text.splitlines(), 1) for w in line.split()]
        self.i = 0

    def next(self, what: str) -> str:
        if self.i >= len(self.words):
            raise InputError(f"{self.path}: the hierarchy ends early, where {what} was expected (truncated?)")
        self.i += 1
        return self.words[self.i - 1][0]

    def fail(self, problem: str):
        line = self.words[min(self.i, len(self.words)) - 1][1] if self.words else 1
        raise InputError(f"{self.path}:{line}: {problem}")

    def expect(self, word: str) -> None:
        got = self.next(repr(word))
        if got != word:
            self.fail(f"expected {word!r}, got {_quote(got)}")

    def number(self, what: str) -> float:
        word = self.next(what)
        try:
            x = float(word)
        except ValueError:
            self.fail(f"{what}: {_quote(word)} is not a number")
        if not math.isfinite(x):
            self.fail(f"{what}: non-finite number {_quote(word)}")
        return x


def _quote(word: str) -> str:
    return repr(printable(word[:40]))


def _hierarchy(path: Path, text: str):
    t = _Tokens(path, text)
    t.expect("HIERARCHY")
    t.expect("ROOT")
    names, parents, offsets, channels, ends = [], [], [], [], {}
    stack = [-1]  # the joint whose block is open; -1: outside the root
    name = t.next("the root's name")
    while True:
        if len(names) >= MAX_JOINTS:
            t.fail(f"more than {MAX_JOINTS} joints")
        if name in names:
            t.fail(f"joint {_quote(name)} appears twice")
        names.append(name)
        parents.append(stack[-1])
        t.expect("{")
        t.expect("OFFSET")
        offsets.append([t.number(f"{name} OFFSET") for _ in range(3)])
        t.expect("CHANNELS")
        count = t.number(f"{name} CHANNELS count")
        if count not in range(7):
            t.fail(f"joint {_quote(name)}: {count:g} channels (a joint has 0 to 6)")
        chans = tuple(t.next(f"{name}'s channel names") for _ in range(int(count)))
        for c in chans:
            if c not in CHANNELS:
                t.fail(f"joint {_quote(name)}: unknown channel {_quote(c)} (valid: {', '.join(CHANNELS)})")
        if len(set(chans)) < len(chans):
            t.fail(f"joint {_quote(name)}: a channel is listed twice")
        channels.append(chans)
        stack.append(len(names) - 1)
        while True:  # the joint's children, end sites and closing braces
            word = t.next("JOINT, End Site or '}'")
            if word == "JOINT":
                name = t.next("a joint name")
                break
            if word == "End":
                t.expect("Site")
                t.expect("{")
                t.expect("OFFSET")
                ends.setdefault(stack[-1], np.array([t.number("End Site OFFSET") for _ in range(3)]))
                t.expect("}")
            elif word == "}":
                stack.pop()
                if len(stack) == 1:
                    rest = t.words[t.i:]
                    if rest:
                        t.i += 1
                        t.fail(f"{_quote(rest[0][0])} after the root's closing brace (one skeleton per file)")
                    return names, parents, offsets, channels, ends
            else:
                t.fail(f"expected JOINT, End Site or '}}', got {_quote(word)}")


def _motion(path: Path, text: str, n_channels: int, first_line: int) -> tuple[np.ndarray, float]:
    lines = text.splitlines()
    header, k = [], 0
    while len(header) < 2 and k < len(lines):
        if lines[k].strip():
            header.append((lines[k].strip(), first_line + k))
        k += 1
    if len(header) < 2 or not header[0][0].startswith("Frames:") or not header[1][0].startswith("Frame Time:"):
        raise InputError(f"{path}:{first_line}: MOTION must be followed by 'Frames: N' and 'Frame Time: s'")
    try:
        frames = int(header[0][0].split(":", 1)[1])
        frame_time = float(header[1][0].split(":", 1)[1])
    except ValueError:
        raise InputError(f"{path}:{header[0][1]}: 'Frames:' needs a whole number and 'Frame Time:' a number "
                         f"of seconds") from None
    if frames < 1:
        raise InputError(f"{path}:{header[0][1]}: the clip has no frames")
    if not (0.0 < frame_time <= MAX_FRAME_TIME):
        raise InputError(f"{path}:{header[1][1]}: frame time {frame_time:g} s is not a time between frames "
                         f"(0 to {MAX_FRAME_TIME:g} s; 120 fps is 0.0083333)")
    require_memory(8.0 * frames * max(n_channels, 1), f"reading {path} ({frames} frames)", "trim the clip")
    body = [(line, first_line + k + n) for n, line in enumerate(lines[k:]) if line.strip()]
    if len(body) < frames:
        raise InputError(f"{path}: declares {frames} frames but holds {len(body)} (truncated?)")
    if len(body) > frames:
        raise InputError(f"{path}:{body[frames][1]}: more lines than the {frames} frames declared")
    words = text[text.index(header[1][0]) + len(header[1][0]):].split()
    if len(words) != frames * n_channels:
        for f, (line, n) in enumerate(body):
            if len(line.split()) != n_channels:
                raise InputError(f"{path}:{n}: frame {f} has {len(line.split())} values, the hierarchy "
                                 f"declares {n_channels} channels")
    try:
        values = np.array(words, dtype=float).reshape(frames, n_channels)
    except ValueError:
        for f, (line, n) in enumerate(body):
            for w in line.split():
                try:
                    float(w)
                except ValueError:
                    raise InputError(f"{path}:{n}: frame {f}: {_quote(w)} is not a number") from None
        raise
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        f = int(np.flatnonzero(bad)[0])
        raise InputError(f"{path}:{body[f][1]}: frame {f} has a non-finite value (NaN or inf; "
                         f"{int(bad.sum())} such frames)")
    if np.abs(values).max(initial=0.0) > 1e9:
        f = int(np.flatnonzero((np.abs(values) > 1e9).any(axis=1))[0])
        raise InputError(f"{path}:{body[f][1]}: frame {f} has a value beyond 1e9, not a position or an angle")
    return values, frame_time
