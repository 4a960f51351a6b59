"""Only the obstacle triangles within reach of the cloth take part in contact
(ContactMesh.focus, called once per step): the barrier, its derivatives, CCD and whole
trajectories are those of the whole obstacle, while the broad phases see a fraction of it."""

from __future__ import annotations

import numpy as np
import pytest

from garment.build import build_simulator
from garment.scene import loads_scene
from sim.contact.mesh import ContactMesh

from tests.support.scenes import DROP

# The sheet 3 mm above a fine ball (subdivisions 5: 20,480 triangles) on a 2 m ground.
SCENE = DROP.format(height=0.163).replace("subdivisions = 2", "subdivisions = 5")


def whole(monkeypatch):
    """Make every contact mesh keep all obstacle triangles (focus does nothing)."""
    monkeypatch.setattr(ContactMesh, "focus", lambda self, C, B1, reach: False)


def test_a_focused_step_sees_a_fraction_of_the_ball_and_the_same_contact(monkeypatch):
    sim = build_simulator(loads_scene(SCENE))
    for _ in range(6):
        st = sim.step()
    assert st.extra["contact_count"] > 0
    mesh, barrier = sim.model.barrier.contact, sim.model.barrier
    ball_and_ground = len(mesh.body_faces)
    assert mesh.body_ids is not None
    kept = mesh.faces.shape[0] - mesh.cloth_faces.shape[0]
    assert kept < 0.6 * ball_and_ground  # the ball's lower half is out (measured: 53 % kept)
    C = sim.state.C
    rng = np.random.default_rng(1)
    d = rng.normal(scale=2e-3, size=C.shape)
    focused = (barrier.value(C), None,
               barrier.n_collisions_at(C), barrier.max_step(C, C + d))
    g_focused = np.zeros_like(C)
    barrier.add_gradient(C, g_focused)
    barrier.contact = ContactMesh(mesh.W, mesh.cloth_faces, mesh._rest, mesh.obstacles, mesh.piece_ids,
                                  mesh.self_contact, mesh.excluded)
    barrier.contact.move_obstacles(mesh.obstacle_vertices.copy())
    barrier.forget()
    assert barrier.contact.body_ids is None
    g_whole = np.zeros_like(C)
    barrier.add_gradient(C, g_whole)
    assert barrier.n_collisions_at(C) == focused[2]
    assert barrier.value(C) == pytest.approx(focused[0], rel=1e-12)
    np.testing.assert_allclose(g_focused, g_whole, rtol=0, atol=1e-12 * np.abs(g_whole).max())
    assert barrier.max_step(C, C + d) == focused[3]


def test_trajectories_with_and_without_the_focus_agree(monkeypatch):
    """A drop onto the ball, 20 steps (contact from the 2nd) with and without focusing:
    the same Newton iterations, positions within 1e-5 m (measured 2e-6), a tenth of what
    Newton's tolerance leaves open in a step (||dC|| / dt < 1e-2 m/s: 1e-4 m). The sums
    differ in the order of their terms only; later, as the sheet buckles over the ball,
    round-off decides between two Newton paths and the runs part by up to 0.5 mm."""
    def run():
        sim = build_simulator(loads_scene(SCENE))
        its = [sim.step().newton_iterations for _ in range(20)]
        return sim.state.C.copy(), its

    C_focus, its_focus = run()
    whole(monkeypatch)
    C_whole, its_whole = run()
    assert its_focus == its_whole
    np.testing.assert_allclose(C_focus, C_whole, rtol=0, atol=1e-5)


SPINNING = DROP.format(height=0.1605).replace("subdivisions = 2}", "subdivisions = 2}\nspin = { axis = [1, 0, 0], speed = 3.0 }")


def test_a_rebuilt_mesh_keeps_the_obstacles_rest_shape():
    """ipctk's rest positions give the barrier's area weights: a mesh that focus() rebuilds
    after the ball has turned keeps the ball's rest shape, so the contact energy does not
    depend on when the mesh was last rebuilt (a resumed run rebuilds at another moment)."""
    sim = build_simulator(loads_scene(SPINNING))
    mesh = sim.model.barrier.contact
    rest = np.concatenate([o.vertices for o in mesh.obstacles])
    turned = np.concatenate([o.at(0.2) for o in mesh.obstacles])
    assert np.abs(turned - rest).max() > 0.01  # the ball has turned a lot
    mesh.move_obstacles(turned)
    assert mesh.focus(sim.C, turned, 0.01)  # rebuilt, now with part of the ball
    np.testing.assert_array_equal(mesh.mesh.rest_positions[mesh.n_cloth:], mesh.active(rest))


def test_a_still_body_keeps_the_contact_data_and_a_moved_one_expires_them():
    """A still body is moved onto its target every step: where it already is, nothing
    expires (version kept, the triangles' bounding spheres kept); moved, both renew."""
    sim = build_simulator(loads_scene(SCENE))
    sim.step()
    mesh = sim.model.barrier.contact
    version, (centre, _) = mesh.version, mesh._triangle_spheres()
    mesh.move_obstacles(mesh.obstacle_vertices.copy())
    assert mesh.version == version and mesh._triangle_spheres()[0] is centre
    shift = np.array([0.0, 0.0, 1e-4])
    mesh.move_obstacles(mesh.obstacle_vertices + shift)
    assert mesh.version == version + 1
    np.testing.assert_allclose(mesh._triangle_spheres()[0], centre + shift, rtol=0, atol=1e-15)


def test_a_step_beyond_reach_is_checked_along_the_way_the_cloth_went():
    """The cloth moved beyond its contact region: the way it went, not the chord, decides
    whether it passed through a left-out obstacle (stepper._went_clear). The sheet goes
    from beside the ball to its other side over the top; the chord runs through it."""
    from sim.stepper import _went_clear

    sim = build_simulator(loads_scene(DROP.format(height=0.3)))
    potential, contact = sim.model.potential, sim.model.barrier.contact
    assert contact.body_ids is None  # the whole ball and ground, before any focus
    B = contact.obstacle_vertices
    top = sim.state.C
    start, end = top + [-0.4, 0.0, -0.18], top + [0.4, 0.0, -0.18]  # 4 cm below the ball's top
    assert potential.max_step(start, end) < 1.0
    over = [(start, B), (top + [-0.4, 0.0, 0.0], B), (top + [0.4, 0.0, 0.0], B), (end, B)]
    assert _went_clear(potential, contact, over)
    assert not _went_clear(potential, contact, [over[0], over[-1]])
    through = [(start, B), (top + [0.0, 0.0, -0.18], B), (end, B)]  # into the ball and out
    assert not _went_clear(potential, contact, through)
