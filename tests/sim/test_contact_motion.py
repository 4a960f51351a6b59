"""Contact with moving things: animated bodies, spinning obstacles with friction, and
momentum in a collision between two cloths. Every frame is checked for intersections
with the independent brute-force test (tests/support/intersections.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from garment.bench.common import scene
from sim.errors import InputError
from garment.io.bodies import load_sequence
from garment.scene import load_scene, loads_scene
from sim.newton import NewtonOptions
from garment.build import build_simulator
from sim.simulator import Simulator

from tests.support.intersections import intersecting_pairs
from tests.support.paths import SCENES

PUSH = """
[[cloth]]
name = "sheet"
size = [0.4, 0.4]
control_points = [10, 10]
origin = [-0.2, -0.2, 0.0]
[[pin]]
cloth = "sheet"
corners = ["u0v0", "u1v0", "u0v1", "u1v1"]
[[obstacle]]
name = "ball"
animation = "{path}"
[contact]
dhat = 1e-3
kappa = "adaptive"
[time]
dt = 0.01
"""


def _ball_sequence(path: Path, frames: int = 12, rise: float = 0.02, frame_dt: float = 0.02) -> Path:
    """An icosphere (r = 6 cm) rising `rise` m per frame from below the sheet."""
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.06)
    verts = np.stack([m.vertices + [0.0, 0.0, -0.08 + rise * k] for k in range(frames)])
    np.savez(path, verts=verts.astype(np.float32), faces=m.faces.astype(np.int32), frame_dt=np.float32(frame_dt))
    return path


def _check_frame(sim: Simulator) -> None:
    """No NaN, no cloth triangle through a body triangle, another piece or itself."""
    pieces = [(sim.positions(p.name), p.topology.faces) for p in sim.model.pieces]
    bodies = sim.obstacle_positions()
    for x, f in pieces:
        assert np.all(np.isfinite(x))
        assert intersecting_pairs(x, f) == 0
        for o in sim.model.obstacles:
            assert intersecting_pairs(x, f, bodies[o.name], o.faces) == 0
    for i in range(len(pieces)):
        for j in range(i + 1, len(pieces)):
            assert intersecting_pairs(*pieces[i], *pieces[j]) == 0


def test_animated_body_pushes_the_cloth_without_passing_through(tmp_path):
    path = _ball_sequence(tmp_path / "ball.npz")
    sim = build_simulator(loads_scene(PUSH.format(path=path.as_posix())))
    seq = sim.model.obstacles[0].sequence
    for _ in range(18):  # the ball meets the sheet at about step 4, then lifts it 7 cm
        st = sim.step()
        _check_frame(sim)
        # The body reaches its frame position every step (linear within frames).
        np.testing.assert_allclose(sim.obstacle_positions()["ball"], seq.at(sim.t), atol=1e-12)
        assert st.extra["body_lag"] == 0.0
    ball = sim.obstacle_positions()["ball"]
    centre = ball.mean(axis=0)
    assert centre[2] > 0.09  # the ball rose 10 cm above the sheet's rest plane...
    x = sim.positions("sheet")
    near = x[np.linalg.norm(x[:, :2] - centre[:2], axis=1) < 0.03]
    d = np.linalg.norm(near - centre, axis=1)
    assert near.shape[0] >= 4 and np.all(d > 0.06 - 1e-3)  # ...the sheet stays outside it...
    assert 0.0 < st.extra["min_distance"] < 2e-3  # ...and rests on it (the pole touches a triangle)


def test_two_plates_conserve_momentum():
    scene = load_scene(SCENES / "two_plates.toml")
    sim = build_simulator(scene)
    P0 = (sim.model.mass[:, None] * sim.V).sum(axis=0)
    scale = float((sim.model.mass * np.linalg.norm(sim.V, axis=1)).sum())
    contacts = 0
    for _ in range(12):  # they meet at step 4 and stay in contact
        st = sim.step()
        _check_frame(sim)
        contacts += st.extra["contact_count"] > 0
        P = (sim.model.mass[:, None] * sim.V).sum(axis=0)
        assert np.linalg.norm(P - P0) / scale < 1e-6
    assert contacts >= 6
    # The collision slowed both plates: momentum moved between them, not out of the system.
    v_floor = sim.V[sim.model.pieces[0].slice, 2].mean()
    v_wall = sim.V[sim.model.pieces[1].slice, 2].mean()
    assert v_floor < 0.45 and v_wall > -0.45


SPIN = """
[material]
E_bd = 8e3
[[cloth]]
name = "sheet"
size = [0.16, 0.16]
control_points = [7, 7]
origin = [-0.08, -0.08, 0.1505]
[[obstacle]]
name = "ball"
sphere = {{radius = 0.15, center = [0.0, 0.0, 0.0], subdivisions = 3}}
spin = {{axis = [0, 0, 1], speed = 3.0, start = 0.0, ramp = 0.05}}
[contact]
dhat = 1e-3
kappa = "adaptive"
mu = {mu}
eps_v = 1e-3
[time]
dt = 0.01
"""


def _turned_angle(mu: float, steps: int = 10) -> float:
    sim = build_simulator(loads_scene(SPIN.format(mu=mu)))
    x0 = sim.positions("sheet")
    for _ in range(steps):
        sim.step()
        _check_frame(sim)
    x = sim.positions("sheet")
    far = np.linalg.norm(x0[:, :2], axis=1) > 0.05
    a0 = np.arctan2(x0[far, 1], x0[far, 0])
    a1 = np.arctan2(x[far, 1], x[far, 0])
    return float(np.mean(np.angle(np.exp(1j * (a1 - a0)))))


def test_friction_lets_a_spinning_sphere_turn_the_cloth():
    """A sheet resting on top of a sphere that starts to spin: with friction it turns
    along, without friction it stays put."""
    with_friction = _turned_angle(0.5)
    without = _turned_angle(0.0)
    ball_angle = 3.0 * (0.10 - 0.025)  # sphere's own turn after 10 steps (ramp 0.05 s)
    assert abs(without) < 0.05 * ball_angle  # facets of the meshed sphere still nudge it
    assert with_friction > 0.2 * ball_angle


def test_obj_directory_sequence_matches_npz(tmp_path):
    path = _ball_sequence(tmp_path / "ball.npz", frames=3)
    data = np.load(path)
    frames = tmp_path / "frames"
    frames.mkdir()
    for k, V in enumerate(data["verts"]):
        trimesh.Trimesh(V, data["faces"], process=False).export(frames / f"f{k + 1}.obj")
    a = load_sequence(path)
    b = load_sequence(frames, fps=50.0)
    np.testing.assert_allclose(b.frames, a.frames, atol=1e-6)
    # Natural order (f10 after f9), linear interpolation within a frame, hold at the end.
    np.testing.assert_allclose(a.at(0.01), 0.5 * (a.frames[0] + a.frames[1]))
    np.testing.assert_allclose(a.at(10.0), a.frames[-1])


def test_y_up_and_scale(tmp_path):
    V = np.array([[0.0, 0, 0], [100, 0, 0], [0, 170, 0]])
    np.savez(tmp_path / "b.npz", verts=V[None], faces=np.array([[0, 1, 2]]), frame_dt=0.04)
    seq = load_sequence(tmp_path / "b.npz", scale=0.01, up="y")
    np.testing.assert_allclose(seq.frames[0][2], [0.0, 0.0, 1.7])  # +Y becomes +Z


@pytest.mark.parametrize("case, message", [
    ("missing_faces", "lacks faces"),
    ("nan", "frame 1 has non-finite"),
    ("centimetres", "not in metres"),
    ("bad_index", "faces index vertex"),
    ("no_frame_time", "give `fps`"),
])
def test_bad_body_sequences_name_the_problem(tmp_path, case, message):
    m = trimesh.creation.icosphere(subdivisions=1, radius=0.1)
    verts = np.stack([m.vertices, m.vertices])
    faces = np.asarray(m.faces)
    arrays = {"verts": verts, "faces": faces, "frame_dt": 0.04}
    if case == "missing_faces":
        del arrays["faces"]
    elif case == "nan":
        verts[1, 3, 0] = np.nan
    elif case == "centimetres":
        arrays["verts"] = verts * 100.0
    elif case == "bad_index":
        arrays["faces"] = faces + 1000
    elif case == "no_frame_time":
        del arrays["frame_dt"]
    np.savez(tmp_path / "body.npz", **arrays)
    with pytest.raises(InputError, match=message) as err:
        load_sequence(tmp_path / "body.npz")
    assert "body.npz" in str(err.value)


def test_obj_frames_with_different_topology_are_rejected(tmp_path):
    a = trimesh.creation.icosphere(subdivisions=1)
    b = trimesh.creation.icosphere(subdivisions=2)
    a.export(tmp_path / "f1.obj")
    b.export(tmp_path / "f2.obj")
    with pytest.raises(InputError, match="f2.obj: frame topology differs"):
        load_sequence(tmp_path, fps=25)


@pytest.mark.parametrize("mode", ["merge", "diagonal"])
def test_off_pattern_couplings_modes(mode):
    """Contacts between two pieces fall outside the fixed pattern. Solving with them
    (merged) keeps momentum to round-off; leaving them on the diagonal does not: that is
    what the partial factorization's exact solves buy."""
    sim = build_simulator(load_scene(SCENES / "two_plates.toml"), NewtonOptions(off_pattern=mode))
    P0 = (sim.model.mass[:, None] * sim.V).sum(axis=0)
    scale = float((sim.model.mass * np.linalg.norm(sim.V, axis=1)).sum())
    for _ in range(6):
        sim.step()
    drift = np.linalg.norm((sim.model.mass[:, None] * sim.V).sum(axis=0) - P0) / scale
    assert sim.model.potential.moved_entries > 0
    assert (drift < 1e-9) if mode == "merge" else (drift > 1e-4)


@pytest.mark.slow
def test_sphere_scene_sheet_rests_on_the_sphere():
    """The paper's cloth-on-sphere scene (assets/scenes/sphere.toml) at 20^2: every frame
    intersection-free with positive distance, and after 0.8 s the sheet rests on the
    sphere's top."""
    sim = build_simulator(scene("sphere", (20, 20)))
    for _ in range(80):
        st = sim.step()
        _check_frame(sim)
        if st.extra["contact_count"] > 0:
            assert st.extra["min_distance"] > 0.0
    x = sim.positions("sheet")
    centre = x[np.argmin(np.linalg.norm(x[:, :2], axis=1))]
    assert 0.30 < centre[2] < 0.30 + 0.005  # sphere top at 0.30 m
    assert np.abs(sim.V).max() < 1.0  # no vertex flying off


def test_a_body_stops_short_of_cloth_that_cannot_give_way(tmp_path):
    """The rising ball meets a sheet pinned at every control point: it must stop a
    round-off-safe distance short of it (and lag), never creep into it by 90 % of the gap
    each step (1e-17 m after a dozen steps) or cross it."""
    path = _ball_sequence(tmp_path / "ball.npz")
    text = PUSH.format(path=path.as_posix()).replace('corners = ["u0v0", "u1v0", "u0v1", "u1v1"]',
                                                     "box = [[0, 0], [1, 1]]")
    sim = build_simulator(loads_scene(text))
    for _ in range(16):  # the ball reaches the sheet at about step 4, then is held back
        st = sim.step()
        _check_frame(sim)
    assert st.extra["body_lag"] > 0.05  # held back by most of its 12 cm rise
    assert sim.model.barrier.min_distance(sim.C) >= 0.9e-6 * sim.model.barrier.dhat


def test_a_blocked_body_part_does_not_hold_back_the_rest(tmp_path):
    """Two balls rise as one body's parts: one into a sheet pinned at every control point
    (blocked), one beside it through open air. Bodies move by one CCD fraction while
    nothing blocks them; once one contact pins that fraction near zero, every vertex goes
    as far as its own clearance allows: the free ball keeps to its animation, the blocked
    one stays a round-off-safe distance short of the sheet, and nothing crosses."""
    blocked = _ball_sequence(tmp_path / "blocked.npz")
    free = np.load(_ball_sequence(tmp_path / "free.npz"))
    np.savez(tmp_path / "free.npz", verts=free["verts"] + np.float32([0.5, 0.0, 0.0]),
             faces=free["faces"], frame_dt=free["frame_dt"])
    text = PUSH.format(path=blocked.as_posix()).replace('corners = ["u0v0", "u1v0", "u0v1", "u1v1"]',
                                                        "box = [[0, 0], [1, 1]]")
    text += f'\n[[obstacle]]\nname = "free"\nanimation = "{(tmp_path / "free.npz").as_posix()}"\n'
    sim = build_simulator(loads_scene(text))
    seq = {o.name: o.sequence for o in sim.model.obstacles}
    blocked_steps = 0
    for _ in range(16):  # the ball meets the sheet at about step 4, then is held back
        st = sim.step()
        _check_frame(sim)
        blocked_steps += st.extra.get("blocked_drives", 0) > 0
    bodies = sim.obstacle_positions()
    assert blocked_steps >= 8
    np.testing.assert_allclose(bodies["free"], seq["free"].at(sim.t), atol=1e-9)
    assert np.abs(bodies["ball"] - seq["ball"].at(sim.t)).max() > 0.05  # held back
    assert sim.model.barrier.min_distance(sim.C) >= 0.9e-6 * sim.model.barrier.dhat
