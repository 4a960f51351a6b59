"""Long runs: checkpoints and --resume, step splitting, failure reports, SIGINT/SIGTERM."""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from garment.cli import main
from sim.errors import InputError, SimulationError
from garment.io import read_frame
from garment.scene import loads_scene
from sim.checkpoint import read_checkpoint, write_checkpoint
from sim.state import State
from sim.driver import CheckpointPolicy, drive
from sim.recovery import Interrupted, SplitWarning, StepFailure, step_with_recovery
from sim.stepper import BeyondReach
from garment.build import build_simulator, scene_hash
from sim.simulator import Simulator
from viz.recording import load_recording

from tests.support.paths import ROOT
from tests.support.scenes import HANGING_SHEET

CONTACT = """
[[cloth]]
name = "sheet"
size = [0.3, 0.3]
control_points = [9, 9]
origin = [-0.15, -0.15, 0.012]

[[obstacle]]
name = "ground"
plane = { point = [0, 0, 0], normal = [0, 0, 1], size = 1.0 }

[[obstacle]]
name = "ball"
sphere = { center = [0.0, 0.0, -0.03], radius = 0.04, subdivisions = 2 }
spin = { axis = [0, 0, 1], speed = 3.0 }

[contact]
dhat = 1e-3
kappa = "adaptive"
mu = 0.3

[time]
dt = 0.01
frames = 10
steps_per_frame = 2
"""


def test_resume_repeats_the_uninterrupted_run(tmp_path, one_ipc_thread):
    """Contact with friction, adaptive kappa and a spinning body: N frames straight vs
    N/2, checkpoint, a fresh simulator restored from the file, N/2 more."""
    scene = loads_scene(CONTACT)
    straight = build_simulator(scene)
    result = drive(straight, 10, 2)
    assert max(s.extra.get("contact_count", 0) for s in result.stats) > 0  # the state includes contact
    reference = build_simulator(scene)
    reference.run(10, 2)
    assert np.array_equal(straight.C, reference.C)  # the driver steps exactly like Simulator.run

    path = tmp_path / "run.ckpt.npz"
    first = build_simulator(scene)
    drive(first, 5, 2, checkpoint=CheckpointPolicy(path, 0, scene_hash(scene)))
    ck = read_checkpoint(path)
    assert ck.frame == 5 and ck.scene_hash == scene_hash(scene)
    resumed = build_simulator(scene)
    drive(resumed, 10, 2, resume=ck)
    assert np.abs(resumed.C - straight.C).max() == 0.0
    assert np.abs(resumed.V - straight.V).max() == 0.0
    assert resumed.t == straight.t and resumed.model.barrier.kappa == straight.model.barrier.kappa
    np.testing.assert_array_equal(resumed.obstacle_positions()["ball"], straight.obstacle_positions()["ball"])
    assert not list(tmp_path.glob(".*tmp"))


def test_frames_keep_their_length_when_the_time_step_changes():
    """drive(frame_time=...): a caller that raises dt between frames (garment dress, once
    sewn) gets frames of the same length in fewer steps."""
    sim = build_simulator(loads_scene(HANGING_SHEET))

    class Times:
        def open(self, meshes):
            self.frames = []

        def write(self, frame):
            self.frames.append((frame.time, len(frame.steps)))

        def close(self):
            pass

    def on_step(st):
        if sim.t >= 0.04 - 1e-9:
            sim.set_dt(0.02)

    times = Times()
    drive(sim, 5, 2, [times], on_step=on_step, frame_time=0.02)
    assert [n for _, n in times.frames] == [0, 2, 2, 1, 1, 1]
    np.testing.assert_allclose([t for t, _ in times.frames], [0.0, 0.02, 0.04, 0.06, 0.08, 0.1], atol=1e-12)
    assert sim.dt == 0.02 and sim.step_count == 7


def test_checkpoint_round_trip(tmp_path):
    scene = loads_scene(CONTACT)
    sim = build_simulator(scene)
    drive(sim, 1, 2)
    sim.state.projection_backoff = (3, 8)
    path = write_checkpoint(tmp_path / "c.npz", sim.state, 1, "abc")
    ck = read_checkpoint(path)
    # Save state, load state: every field comes back, with its type.
    for f in dataclasses.fields(State):
        saved, loaded = getattr(sim.state, f.name), getattr(ck.state, f.name)
        if isinstance(saved, np.ndarray):
            assert loaded.dtype == saved.dtype, f.name
            np.testing.assert_array_equal(loaded, saved)
        else:
            assert loaded == saved and type(loaded) is type(saved), f.name
    assert sim.state.kappa is not None and sim.state.obstacle_vertices is not None  # contact state included
    assert (ck.frame, ck.scene_hash) == (1, "abc")
    # A different scene (even one number) has a different hash; frame count and outputs do not count.
    assert scene_hash(loads_scene(CONTACT.replace("mu = 0.3", "mu = 0.2"))) != scene_hash(scene)
    assert scene_hash(loads_scene(CONTACT.replace("frames = 10", "frames = 99"))) == scene_hash(scene)
    # A damaged field that numpy reads but int() cannot (inf) is an InputError naming the file.
    bad = dict(np.load(path))
    bad["threads"] = np.array([np.inf, 1.0])
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(InputError, match="bad.npz: not a readable checkpoint"):
        read_checkpoint(tmp_path / "bad.npz")


def failing_above(sim, dt_max):
    """Make sim.step report non-convergence for steps longer than dt_max."""
    step = sim.step

    def wrapped():
        st = step()
        if sim.dt > dt_max * (1 + 1e-12):
            st.converged = False
            st.residual = 1e3  # a stall far from the tolerance
        return st

    sim.step = wrapped


def test_a_failing_step_is_split_in_halves():
    scene = loads_scene(HANGING_SHEET)
    sim, ref = build_simulator(scene), build_simulator(scene)
    failing_above(sim, 0.005)
    with pytest.warns(SplitWarning, match="retrying as two steps of 0.005 s"):
        stats = step_with_recovery(sim)
    assert len(stats) == 2 and sim.dt == 0.01 and sim.t == 0.01
    ref.set_dt(0.005)
    ref.step()
    ref.step()
    ref.set_dt(0.01)
    assert np.array_equal(sim.C, ref.C) and np.array_equal(sim.V, ref.V)
    # Recursion: quarters when halves fail too.
    failing_above(sim, 0.0025)
    messages = []
    assert len(step_with_recovery(sim, on_warning=messages.append)) == 4
    assert len(messages) == 3 and sim.dt == 0.01


def test_a_step_beyond_its_contact_reach_is_taken_again_whole():
    # The first attempt moves the cloth beyond its contact region (BeyondReach, the model
    # keeping the motion seen); the step is taken again at the same dt, not split.
    scene = loads_scene(HANGING_SHEET)
    sim, ref = build_simulator(scene), build_simulator(scene)
    step, calls = sim.step, []

    def wrapped():
        calls.append(sim.dt)
        if len(calls) == 1:
            step()
            raise BeyondReach("the cloth moved 0.05 m in one step, beyond the contact reach of 0.03 m")
        return step()

    sim.step = wrapped
    stats = step_with_recovery(sim)
    assert len(stats) == 1 and calls == [0.01, 0.01]
    ref.step()
    assert np.array_equal(sim.C, ref.C) and np.array_equal(sim.V, ref.V) and sim.t == ref.t
    # Beyond reach twice: split as any failed step.
    calls.clear()
    sim.step = lambda: (calls.append(sim.dt), (_ for _ in ()).throw(BeyondReach("far")) if sim.dt > 0.006 else step())[1]
    with pytest.warns(SplitWarning, match="BeyondReach"):
        assert len(step_with_recovery(sim)) == 2
    assert calls == [0.01, 0.01, 0.005, 0.005]


def test_quasistatic_sewing_steps_are_kept_unconverged_other_steps_are_split():
    scene = loads_scene(HANGING_SHEET)
    sim = build_simulator(scene)
    step = sim.step

    def unconverged(pulled_shut):
        def wrapped():
            st = step()
            st.converged, st.residual, st.newton_iterations = False, 1e3, sim.model.newton.max_iterations
            if pulled_shut:
                st.extra["pulled_shut"] = 1.0
            return st
        return wrapped

    sim.step = unconverged(True)
    messages = []
    assert len(step_with_recovery(sim, on_warning=messages.append)) == 1 and not messages
    sim.step = unconverged(False)
    with pytest.raises(StepFailure, match="iteration cap"):
        step_with_recovery(sim, on_warning=messages.append)
    assert len(messages) == 4  # halves, quarters, ... down to the floor (dt / 16)


def test_a_failed_step_names_how_far_newton_was_and_blames_a_body_only_when_it_lags():
    """A capped solve says how far its last step was from the tolerance. A body a hair
    short of its pose (the drive's floor, 1e-9 m) is at its pose: the cause lies
    elsewhere. A body held back a centimetre is the cause."""
    from sim.recovery import diagnose, failure
    from sim.stats import StepStats

    sim = build_simulator(loads_scene(CONTACT))
    st = StepStats(step=1, time=0.01)
    st.converged, st.residual, st.newton_iterations = False, 0.043, sim.model.newton.max_iterations
    st.energy = 0.0
    problem = failure(sim, st)
    assert "iteration cap (100; last step 0.043 m/s, tolerance 0.01)" in problem
    st.extra.update(body_lag=6.9e-10, min_distance=1e-4)
    assert "could not reach its pose" not in diagnose(sim, st, problem, 0.000625)
    assert "too large for this motion" in diagnose(sim, st, problem, 0.000625)
    st.extra["body_lag"] = 0.01
    assert "could not reach its pose (it lags 0.01 m behind)" in diagnose(sim, st, problem, 0.000625)


def test_failure_at_the_floor_names_frame_and_cause_and_keeps_a_checkpoint(tmp_path):
    scene = loads_scene(HANGING_SHEET)
    sim = build_simulator(scene)
    step = sim.step

    def explode():  # from the third step on the solve returns NaN
        st = step()
        if sim.step_count >= 3:
            sim.C[:] = np.nan
        return st

    sim.step = explode
    path = tmp_path / "c.npz"
    with pytest.raises(SimulationError) as e, pytest.warns(SplitWarning):
        drive(sim, 4, 2, checkpoint=CheckpointPolicy(path, 0, "h"), floor=0.0025)
    msg = str(e.value)
    assert "frame 2" in msg and "non-finite" in msg and "likely cause" in msg and str(path) in msg
    ck = read_checkpoint(path)
    assert ck.frame == 1 and ck.state.step_count == 2 and np.isfinite(ck.state.C).all()
    with pytest.raises(StepFailure):  # the state is back at the start of the failed step
        step_with_recovery(sim, floor=0.01)
    assert sim.step_count == 2 and np.isfinite(sim.C).all()


def test_cli_failure_exits_3_with_valid_outputs(tmp_path, capsys, monkeypatch):
    step = Simulator.step

    def explode(self):
        st = step(self)
        if self.t > 0.045:  # frame 3 of 4
            self.C[:] = np.nan
        return st

    monkeypatch.setattr(Simulator, "step", explode)
    scene = tmp_path / "s.toml"
    scene.write_text(HANGING_SHEET)
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", str(scene), "-o", str(rrd), "-q", "--max-splits", "1"]) == 3
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error: frame 3" in err and "run.ckpt.npz" in err
    assert load_recording(rrd).frames == [0, 1, 2]
    assert read_checkpoint(tmp_path / "run.ckpt.npz").frame == 2


def test_stop_request_discards_the_partial_frame(tmp_path):
    scene = loads_scene(HANGING_SHEET)
    sim, ref = build_simulator(scene), build_simulator(scene)

    def stop():  # true before the second step of frame 2
        return sim.step_count >= 3

    path = tmp_path / "c.npz"
    result = drive(sim, 4, 2, checkpoint=CheckpointPolicy(path, 0, "h"), should_stop=stop)
    assert result.stopped and result.last_frame == 1
    ref.run(1, 2)
    assert np.array_equal(sim.C, ref.C) and sim.step_count == 2
    ck = read_checkpoint(path)
    assert ck.frame == 1 and np.array_equal(ck.state.C, ref.C)
    sim.state = ck.state  # restoring is idempotent
    assert np.array_equal(sim.C, ref.C)


LONG = HANGING_SHEET.replace("frames = 4", "frames = 5000").replace("steps_per_frame = 2", "steps_per_frame = 1")


def start_run(tmp_path, *extra):
    scene = tmp_path / "long.toml"
    scene.write_text(LONG)
    rrd, frames = tmp_path / "run.rrd", tmp_path / "frames"
    env = dict(os.environ, NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", ".cache/numba"))
    proc = subprocess.Popen([sys.executable, "-m", "garment.cli", "simulate", str(scene), "-o", str(rrd),
                             "--mesh-dir", str(frames), "-q", *extra],
                            stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    # Generous: it only catches a run that never starts (a loaded 2-core machine, cold
    # numba cache, takes well over a minute to import and compile).
    deadline = time.monotonic() + 300
    while len(list(frames.glob("sheet_*.npz"))) < 3:
        assert proc.poll() is None, proc.stderr.read()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    return proc, scene, rrd, frames


def test_sigint_stops_cleanly_and_resume_finishes_the_run(tmp_path, capsys):
    proc, scene, rrd, frames = start_run(tmp_path)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "--resume" in err
    last = read_checkpoint(tmp_path / "run.ckpt.npz").frame
    assert f"stopped after frame {last} of 5000" in err
    # Every completed frame, and nothing else, in the recording and the mesh folder.
    assert load_recording(rrd).frames == list(range(last + 1))
    assert sorted(frames.glob("sheet_*.npz"))[-1].name == f"sheet_{last:05d}.npz"
    assert len(list(frames.glob("sheet_*.npz"))) == last + 1
    assert not list(tmp_path.glob("**/.*tmp"))

    end = last + 2
    assert main(["simulate", str(scene), "-o", str(rrd), "--mesh-dir", str(frames), "--resume",
                 "--frames", str(end), "-q"]) == 0
    assert load_recording(tmp_path / "run.part2.rrd").frames == list(range(last, end + 1))
    sim = build_simulator(loads_scene(LONG))
    sim.run(end, 1)
    verts, _ = read_frame(frames / f"sheet_{end:05d}.npz")
    assert np.abs(verts - sim.positions("sheet")).max() <= 1e-12


@pytest.mark.slow
def test_second_signal_exits_at_once(tmp_path):
    proc, *_ = start_run(tmp_path)
    proc.send_signal(signal.SIGTERM)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and "Traceback" not in err


def test_periodic_checkpoints_and_nothing_left_to_do(tmp_path, capsys):
    scene = loads_scene(HANGING_SHEET)
    path = tmp_path / "run.ckpt.npz"
    result = drive(build_simulator(scene), 4, 2, checkpoint=CheckpointPolicy(path, 2, "h"))
    assert result.checkpoints == 2 and read_checkpoint(path).frame == 4  # after frame 2, and at the end
    toml = tmp_path / "s.toml"
    toml.write_text(HANGING_SHEET)
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", str(toml), "-o", str(rrd), "-q"]) == 0
    assert main(["simulate", str(toml), "-o", str(rrd), "--resume"]) == 0
    assert "nothing to do" in capsys.readouterr().err and not (tmp_path / "run.part2.rrd").exists()


def test_a_stop_request_is_honoured_between_the_sub_steps_of_a_split_step(tmp_path):
    """A split step can take minutes (a wall-clock limit must not wait for it): the stop
    condition is asked before every sub-step, and the run ends at the last whole frame."""
    scene = loads_scene(HANGING_SHEET)
    sim, ref = build_simulator(scene), build_simulator(scene)
    ref.set_dt(0.0025)
    for _ in range(8):  # frame 1 in quarter steps
        ref.step()
    failing_above(sim, 0.0025)  # every step splits into quarters

    def stop():  # true in frame 2's first step, before its first quarter
        return sim.t > 0.02 - 1e-12 and sim.dt < 0.003

    messages = []
    result = drive(sim, 4, 2, should_stop=stop, on_warning=messages.append)
    assert result.stopped and result.last_frame == 1
    assert sim.t == pytest.approx(0.02) and sim.dt == 0.01
    np.testing.assert_allclose(sim.C, ref.C, rtol=0, atol=1e-12)
    with pytest.raises(Interrupted):  # directly: the state is back at the step's start
        step_with_recovery(sim, on_warning=messages.append, should_stop=lambda: True)
    assert sim.t == pytest.approx(0.02) and sim.dt == 0.01


def test_a_stop_request_is_honoured_between_newton_iterations():
    """One step of a garment pressed to a body can take minutes: Newton asks the stop
    condition before every iteration, and the state goes back to the step's start."""
    sim = build_simulator(loads_scene(HANGING_SHEET))
    iterations = sim.step().newton_iterations
    assert iterations >= 2
    before = sim.state.copy()
    asked = []

    def stop():  # asked before each Newton iteration: true before the second
        asked.append(1)
        return len(asked) >= 2

    with pytest.raises(Interrupted, match="after 1 Newton iterations"):
        step_with_recovery(sim, should_stop=stop)
    assert sim.t == before.t and np.array_equal(sim.C, before.C) and np.array_equal(sim.V, before.V)
    assert sim.model.potential.should_stop is None
