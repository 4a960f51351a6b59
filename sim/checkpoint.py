"""Checkpoints: a State on disk with the frame it ends, the scene it belongs to and the
thread counts that wrote it, to resume a run bit for bit (sim/state.py)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .state import State, load_npz


@dataclass
class Checkpoint:
    state: State
    frame: int  # last completed frame index
    scene_hash: str
    threads: tuple[int, int]  # (numba, ipctk) threads of the writing run (results depend on them)


def thread_count() -> tuple[int, int]:
    """(numba, ipctk) thread counts. Numba's reductions are fixed per thread count;
    ipctk's TBB reductions are not (two identical runs differ by ~1e-13 in contact
    scenes) unless ipctk runs on one thread (`garment simulate --deterministic`)."""
    import ipctk
    import numba

    return int(numba.get_num_threads()), int(ipctk.get_num_threads())


def write_checkpoint(path: str | os.PathLike, state: State, frame: int, scene_hash: str) -> Path:
    """Write `state` as the checkpoint after `frame`."""
    return state.save(path, frame=np.int64(frame), scene_hash=np.str_(scene_hash),
                      threads=np.asarray(thread_count(), np.int64))


def read_checkpoint(path: str | os.PathLike) -> Checkpoint:
    """Read a checkpoint; InputError naming the file when it is missing or unreadable."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no checkpoint to resume from (run without --resume first)")

    def read(d):
        return Checkpoint(State.from_arrays(d), int(d["frame"]), str(d["scene_hash"]),
                          tuple(int(x) for x in d["threads"]))

    try:
        return load_npz(path, read)
    except InputError as e:
        raise InputError(str(e).replace("state file", "checkpoint")) from None
