"""Everything that evolves over a run, in one object: what a checkpoint saves and loads.

The model (sim/model.py) is rebuilt from its scene and never changes; a `State` holds the
rest: control points C and velocities V, time t, the step counter, the current time step,
the obstacle vertices (bodies lag behind their targets when cloth blocks them) and their
targets, the barrier stiffness kappa and the adaptive-stiffness memory, Newton's
projection back-off, the seams' multipliers, which matched seam vertices are sewn, and
which pleat faces no longer wait. What each step rebuilds from these (inertia target,
friction's lagged contacts, body targets from t) is not stored, so loading a state makes
the following steps identical to an uninterrupted run (same thread count).

On disk: one NPZ, written to a temporary name in the same folder and `os.replace`d, so a
crash never leaves a half-written file under the final name.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from .errors import InputError, printable
from .files import atomic_write, read_npz

FORMAT = 2  # bump when the set of fields changes


@dataclass
class State:
    C: np.ndarray  # (n_cp, 3) m
    V: np.ndarray  # (n_cp, 3) m/s
    t: float = 0.0  # s
    step_count: int = 0
    dt: float = 0.01  # s, the current time step (halved while a step is split)
    projection_backoff: tuple[int, int] = (0, 1)  # sim/newton.py
    # With contact only:
    obstacle_vertices: np.ndarray | None = None  # (Vo, 3) m
    drive_target: np.ndarray | None = None  # (Vo, 3) m
    kappa: float | None = None  # Pa
    stiffness_floor: float | None = None  # Pa
    stiffness_prev_d: float | None = None  # m
    # With seams only:
    seam_multipliers: np.ndarray | None = None  # (S, 3) N/m
    seam_gaps: np.ndarray | None = None  # (S,) m, at the multipliers' last update
    seam_level_pushes: np.ndarray | None = None  # (S,) pushes of a gap that stopped shrinking
    seam_pushed_gaps: np.ndarray | None = None  # (S,) m, the widest a levelled gap was pushed at
    seam_low_gaps: np.ndarray | None = None  # (S,) m, a levelled gap's low since it last closed or was loaded
    seam_pairs: np.ndarray | None = None  # (P,) matched vertex pairs: sim.seams.contact OPEN/SEWN/BLOCKED
    pleat_faces: np.ndarray | None = None  # (F,) bool: a seam onto a pleat no longer waits

    def copy(self) -> "State":
        return copy.deepcopy(self)

    def without_seams(self) -> "State":
        """A copy with every seam field (`seam_*`) cleared, for a model whose seams are
        sampled and meshed anew (a refined garment): its multipliers build up again and
        its closed seams merge again at the first step."""
        state = self.copy()
        for f in fields(self):
            if f.name.startswith("seam_"):
                setattr(state, f.name, None)
        return state

    # ------------------------------------------------------------------ on disk
    def to_arrays(self) -> dict[str, np.ndarray]:
        """The fields as named arrays (None fields left out)."""
        out = {"format": np.int64(FORMAT)}
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None:
                out[f.name] = np.asarray(value)
        return out

    @classmethod
    def from_arrays(cls, d) -> "State":
        """Inverse of to_arrays; `d` maps names to arrays (an open NPZ)."""
        if int(d["format"]) != FORMAT:
            raise ValueError(f"state format {int(d['format'])}, this version reads {FORMAT}")
        values = {}
        for f in fields(cls):
            if f.name not in d:
                continue
            a = np.array(d[f.name])
            if a.ndim == 0:
                a = a.item()
            elif f.name == "projection_backoff":
                a = tuple(int(x) for x in a)
            values[f.name] = a
        return cls(**values)

    def save(self, path: str | os.PathLike, **extra) -> Path:
        """Write the state (and `extra` scalars or arrays, e.g. a frame index) atomically."""
        return write_npz(path, self.to_arrays() | {k: np.asarray(v) for k, v in extra.items()})

    @classmethod
    def load(cls, path: str | os.PathLike) -> "State":
        """Read a state; InputError naming the file when it is missing or unreadable."""
        return load_npz(path, cls.from_arrays)


def write_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray]) -> Path:
    """Write `arrays` to an NPZ atomically, its data on disk before the rename."""
    with atomic_write(path, fsync=True) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)  # a file object: np.savez would append ".npz" to a path
    return Path(path)


def load_npz(path: str | os.PathLike, read):
    """read(arrays by name) on the NPZ at `path`; any failure becomes an InputError naming it."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such state file")
    arrays = read_npz(path, "state file")
    try:
        return read(arrays)
    except InputError:
        raise
    except (KeyError, ValueError, TypeError, IndexError, OverflowError) as e:  # inf to int
        raise InputError(f"{path}: not a readable state file ({printable(e, 200)})") from None
