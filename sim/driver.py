"""The frame loop: frames to sinks, with checkpoints, resuming, step splitting and a
clean stop on request (signals).

Checkpoints are taken at frame boundaries only. A stop request is honoured before the
next step; when it comes in the middle of a frame (steps_per_frame > 1) the partial frame
is discarded, so the checkpoint, the recording and the per-frame files all end at the
same completed frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

from .checkpoint import Checkpoint, write_checkpoint
from .recovery import Interrupted, StepFailure, raise_failure, step_with_recovery
from .sinks import Frame
from .stats import StepStats


@dataclass
class RunResult:
    stats: list[StepStats] = field(default_factory=list)
    last_frame: int = 0  # index of the last completed frame
    stopped: bool = False  # a stop request ended the run early
    checkpoints: int = 0  # checkpoint files written
    splits: int = 0  # warnings about split steps


@dataclass
class CheckpointPolicy:
    path: Path | None = None
    every: int = 10  # frames; 0: only at the end, on a stop or a failure
    scene_hash: str = ""


def drive(sim, frames: int, steps_per_frame: int = 1, sinks: Iterable = (), *,
          resume: Checkpoint | None = None, checkpoint: CheckpointPolicy | None = None,
          should_stop: Callable[[], bool] = lambda: False, floor: float | None = None,
          on_step: Callable[[StepStats], None] | None = None,
          on_warning: Callable[[str], None] | None = None, split: bool = True,
          frame_time: float | None = None) -> RunResult:
    """Run frames (resume.frame, frames] of `steps_per_frame` steps each (from frame 0
    when not resuming), emitting the start frame first. With `frame_time` (s), a frame
    is that long instead, in as many steps of the current dt as fit (at least one): the
    caller may change the time step between frames (sim.set_dt, from on_step).

    Sinks are opened here and always closed. A step failing at the split floor raises
    SimulationError after a checkpoint of the last completed frame is written; with
    split=False steps are taken as they come (no retry, no failure check).
    """
    checkpoint = checkpoint or CheckpointPolicy()
    result = RunResult()
    if resume is not None:
        sim.state = resume.state.copy()
        result.last_frame = resume.frame

    def warn(msg):  # counts the splits; None keeps recovery's default (warnings.warn)
        result.splits += 1
        on_warning(msg)

    def save():
        if checkpoint.path is not None:
            write_checkpoint(checkpoint.path, sim.state, result.last_frame, checkpoint.scene_hash)
            result.checkpoints += 1

    sinks = list(sinks)
    opened = []
    try:
        for s in sinks:
            s.open(sim.topologies())
            opened.append(s)
        emit(sim, sinks, result.last_frame, [])
        for k in range(result.last_frame + 1, frames + 1):
            frame_start = sim.state.copy()
            steps = []
            n = steps_per_frame if frame_time is None else max(1, round(frame_time / sim.dt))
            for _ in range(n):
                if should_stop():
                    sim.state = frame_start  # drop the partial frame
                    result.stopped = True
                    save()
                    return result
                if not split:
                    sub = [sim.step()]
                else:
                    try:
                        sub = step_with_recovery(sim, floor, warn if on_warning is not None else None, should_stop)
                    except Interrupted:  # stopped inside a split step: as if before it
                        sim.state = frame_start
                        result.stopped = True
                        save()
                        return result
                    except StepFailure as e:
                        sim.state = frame_start
                        save()
                        raise_failure(e, k, str(checkpoint.path) if checkpoint.path else None)
                steps.extend(sub)
                if on_step is not None:
                    on_step(sub[-1])
            result.stats.extend(steps)
            emit(sim, sinks, k, steps)
            result.last_frame = k
            if checkpoint.every and k % checkpoint.every == 0 and k < frames:
                save()
        save()  # the end state: a later --resume with more --frames extends the run
    finally:
        for s in opened:
            s.close()
    return result


def emit(sim, sinks, index: int, steps: list[StepStats]) -> None:
    if sinks:
        frame = Frame(index, sim.t, sim.positions() | sim.obstacle_positions(), steps)
        for s in sinks:
            s.write(frame)


class SkipExisting:
    """Wraps a MeshExportSink on resume: frames whose files are all on disk are kept
    as they are (they hold the same values; files are written atomically, so an existing
    file is complete)."""

    def __init__(self, sink):
        self.sink = sink

    def open(self, meshes) -> None:
        self.sink.open(meshes)

    def write(self, frame: Frame) -> None:
        if not all(os.path.exists(self.sink.path(name, frame.index)) for name in frame.positions):
            self.sink.write(frame)

    def close(self) -> None:
        self.sink.close()


def _part(rrd: Path, k: int) -> Path:
    return rrd if k == 1 else rrd.with_name(f"{rrd.stem}.part{k}{rrd.suffix}")


def segment_path(rrd: Path) -> Path:
    """Recording file of a resumed run: `run.rrd` if free, else the first free
    `run.part2.rrd`, `run.part3.rrd`, ... (earlier segments are never rewritten)."""
    k = 1
    while _part(rrd, k).exists():
        k += 1
    return _part(rrd, k)


def segments(rrd: Path) -> list[Path]:
    """The recording files of a run and its resumed parts: `run.rrd`, `run.part2.rrd`,
    ... as long as they exist."""
    out = []
    while (p := _part(rrd, len(out) + 1)).exists():
        out.append(p)
    return out
