"""Seams whose straight closing path passes through a body go round it (sim/seams/routes.py)."""

from __future__ import annotations

import numpy as np
import trimesh

import sim.seams.sewing as sewing_module
from garment.io.obstacles import ObstacleGeometry
from sim.materials import PRESETS
from sim.model import ContactOptions, bspline_model
from sim.patches import Patch
from sim.intersect import Triangles
from sim.seams.routes import junction_waypoints, through_cloth, waypoints
from sim.seams.sewing import SewingOptions, _junctions
from sim.seams.spec import SeamSpec
from sim.simulator import Simulator

from tests.support.fd import fd_directional, fd_gradient, gradient
from tests.support.intersections import assert_garment_clean
from tests.support.scenes import two_panels


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from the point p to the segment ab (closed form)."""
    t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(a + t * (b - a) - p))


def test_a_path_through_a_ball_gets_a_waypoint_whose_legs_clear_it():
    r = 0.1
    ball = trimesh.creation.icosphere(subdivisions=3, radius=r)
    V, F = np.asarray(ball.vertices), np.asarray(ball.faces, np.int32)
    a = np.array([[-0.2, 0.0, 0.0], [-0.2, 0.0, 0.15]])  # the first passes through the centre
    b = np.array([[0.2, 0.0, 0.0], [0.2, 0.0, 0.15]])  # the second passes 5 cm above the ball
    routed, w = waypoints(a, b, Triangles(V, F))
    assert routed.tolist() == [True, False]
    np.testing.assert_allclose(w[1], 0.5 * (a[1] + b[1]))
    # Both legs clear the ball (the icosphere lies within 0.5 % of the sphere), by a detour
    # no higher than the next height after the tangents' meeting point (0.2 tan 30 deg).
    for end in (a[0], b[0]):
        assert _segment_distance(np.zeros(3), end, w[0]) > 0.99 * r
    assert 0.2 * np.tan(np.pi / 6) - 1e-9 < np.linalg.norm(w[0]) < 0.18
    # A seam running along z goes round across itself (within 30 degrees of y), not along.
    routed, w = waypoints(a[:1], b[:1], Triangles(V, F), tangent=np.array([[0.0, 0.0, 1.0]]))
    assert routed[0] and abs(w[0, 2]) <= 0.5 * np.linalg.norm(w[0]) + 1e-12
    for end in (a[0], b[0]):
        assert _segment_distance(np.zeros(3), end, w[0]) > 0.99 * r


def test_a_routed_path_keeps_its_side_of_the_ball_once_it_comes_clear_on_the_other():
    # Routed over a ball at the last step (previous waypoint above it), a path that has
    # slid under the ball is clear, but closing it there would close the seam round the
    # other side: it stays routed, over the top.
    r = 0.1
    ball = trimesh.creation.icosphere(subdivisions=3, radius=r)
    V, F = np.asarray(ball.vertices), np.asarray(ball.faces, np.int32)
    a, b = np.array([[-0.15, 0.0, -0.12]]), np.array([[0.15, 0.0, -0.12]])
    routed, w = waypoints(a, b, Triangles(V, F))
    assert not routed[0]  # clear underneath
    routed, w = waypoints(a, b, Triangles(V, F), previous=np.array([[0.0, 0.0, 0.2]]))
    assert routed[0] and w[0, 2] > r
    for end in (a[0], b[0]):
        assert _segment_distance(np.zeros(3), end, w[0]) > 0.99 * r
    # Routed under it before, the same path is simply clear.
    routed, _ = waypoints(a, b, Triangles(V, F), previous=np.array([[0.0, 0.0, -0.2]]))
    assert not routed[0]


def test_seams_meeting_at_a_junction_go_round_a_ball_together():
    # Four corners that become one point, two above a ball's equator and two below, joined
    # in a cycle of four seams (a cuff's and a flounce's side seams and their seams to each
    # other). Each on its own, the upper pair goes over the ball and the lower pair under
    # it, so a corner would be pulled two ways and the corners would stay apart.
    r = 0.1
    ball = trimesh.creation.icosphere(subdivisions=3, radius=r)
    V, F = np.asarray(ball.vertices), np.asarray(ball.faces, np.int32)
    P = np.array([[-0.15, 0.0, 0.03], [0.15, 0.0, 0.03], [-0.15, 0.0, -0.03], [0.15, 0.0, -0.03]])
    pairs = np.array([[0, 1], [2, 3], [0, 2], [1, 3]])
    a, b = P[pairs[:, 0]], P[pairs[:, 1]]
    routed, w = waypoints(a, b, Triangles(V, F))
    assert routed.tolist() == [True, True, False, False]
    assert w[0, 2] > 0.05 and w[1, 2] < -0.05  # over and under
    junction_waypoints([np.arange(4)], a, b, routed, w, Triangles(V, F))
    assert routed.all()
    np.testing.assert_array_equal(w, np.tile(w[0], (4, 1)))  # one point for all
    for corner in P:
        assert _segment_distance(np.zeros(3), corner, w[0]) > 0.99 * r
    # The junction groups come from the seams: samples sharing parameters on one piece.
    seams = [SeamSpec("cuff_f", np.array([[0.0, 0.0], [0.0, 1.0]]), "cuff_b", np.array([[3.0, 0.0], [3.0, 1.0]])),
             SeamSpec("cuff_b", np.array([[3.0, 1.0], [2.0, 1.0]]), "flounce", np.array([[0.0, 0.0], [1.0, 0.0]])),
             SeamSpec("cuff_f", np.array([[5.0, 5.0]]), "flounce", np.array([[4.0, 4.0]]))]
    groups = _junctions(seams, np.array([0, 2, 4, 5]))
    assert [g.tolist() for g in groups] == [[1, 2]]


def test_a_path_through_another_pieces_cloth_is_screened_not_through_its_own():
    # A square of cloth (piece 2) in the plane z = 0; three paths from below to above it:
    # through it (its pieces 0 and 1: screened), through it but sewing piece 2 itself (not
    # screened: a seam's own cloth is not in its way), and beside it (clear).
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    a = np.array([[0.5, 0.5, -0.1], [0.3, 0.6, -0.1], [1.5, 0.5, -0.1]])
    b = a + [0.0, 0.0, 0.2]
    pieces = np.array([[0, 1], [2, 0], [0, 1]])
    hit = through_cloth(a, b, pieces, x, faces, np.array([2, 2]))
    assert hit.tolist() == [True, False, False]


def _facing_panels(others=(), obstacles=()) -> Simulator:
    """Two weightless 0.2 m panels side by side at z = -0.03, 4 cm apart across y = 0,
    sewn along their facing sides (ramped, quasi-static), with the patches `others` and
    the `obstacles`."""
    n = 8
    a = Patch.rectangle("a", (0.2, 0.2), (n, n), (-0.1, -0.22, -0.03), (1, 0, 0), (0, 1, 0))
    b = Patch.rectangle("b", (0.2, 0.2), (n, n), (-0.1, 0.02, -0.03), (1, 0, 0), (0, 1, 0))
    t = np.linspace(0.0, n - 2.0, 30)
    seam = SeamSpec("a", np.c_[t, np.full(30, n - 2.0)], "b", np.c_[t, np.zeros(30)])
    patches = [a, b, *others]
    return Simulator(bspline_model(patches, [PRESETS["cotton"]] * len(patches), gravity=(0.0, 0.0, 0.0), dt=0.01,
                                   contact=ContactOptions(adaptive_kappa=True), obstacles=list(obstacles),
                                   seams=[seam], seam_stiffness=1e6, sewing=SewingOptions(ramp=0.15, quasistatic=True)))


def test_a_seam_screened_by_cloth_in_its_path_stays_screened_while_it_is_there():
    # A third piece stands upright between the two panels: every closing path passes
    # through it. Screened, the seam does not pull on any step (it was released every
    # other step, tested only while pulled), so the panels stay where they are.
    c = Patch.rectangle("c", (0.3, 0.1), (8, 8), (-0.15, 0.0, -0.08), (1, 0, 0), (0, 0, 1))
    sim = _facing_panels([c])
    gap0 = float(sim.model.seam.samples.gaps(sim.C).max())
    for k in range(4):
        sim.step()
        screened = sim.model.screened_samples(sim.C)
        assert screened is not None and screened.all(), (k, screened)
    gap = float(sim.model.seam.samples.gaps(sim.C).max())
    assert abs(gap - gap0) < 1e-6, (gap0, gap)


def test_routed_seam_energy_derivatives_match_finite_differences():
    sim = two_panels(0.02)
    seam = sim.model.seam
    rng = np.random.default_rng(5)
    S = seam.active.size
    routed = np.arange(S) % 3 == 0
    seam.set_scale(0.3)
    assert seam.route(routed, rng.normal(scale=0.05, size=(S, 3)))  # the stiffness changed
    seam.multipliers = rng.normal(scale=50.0, size=seam.multipliers.shape)
    C = sim.C + rng.normal(scale=1e-3, size=sim.C.shape)
    fd = fd_gradient(seam, C, 1e-6)
    g = gradient(seam, C)
    assert np.abs(fd - g).max() < 1e-6 * np.abs(g).max()
    dC = rng.normal(size=C.shape)
    _, fd_dir = fd_directional(seam, C, dC, 1e-6)
    assert np.abs(fd_dir - seam.K @ dC).max() < 1e-6 * np.abs(seam.K @ dC).max()
    # A routed sample pulls both sides to its waypoint: the energy is zero when they are there.
    one = np.zeros(S, bool)
    one[0] = True
    seam.hold(one)
    p = seam.samples.Na[0] @ C
    seam.route(one, np.tile(p, (S, 1)))
    seam.multipliers[:] = 0.0
    E = seam.value(C)
    expected = 0.5 * 0.3 * seam.k[0] * seam.samples.weights[0] * np.sum((seam.samples.Nb[0] @ C - p) ** 2)
    assert abs(E - expected) < 1e-9 * expected


def _over_a_wall() -> Simulator:
    """Two weightless 0.2 m panels either side of a 2 cm thick wall whose top is 3 cm above
    them (and whose foot is far below), sewn along their facing sides: the straight path
    runs through the wall."""
    wall = trimesh.creation.box(extents=(0.5, 0.02, 0.5))
    body = ObstacleGeometry("wall", np.asarray(wall.vertices) + [0.0, 0.0, -0.25], np.asarray(wall.faces, np.int32))
    return _facing_panels(obstacles=[body])


def _sew_over_a_wall(steps: int = 12) -> tuple[float, float]:
    """The largest seam gap (m) and the cloth's highest point (m) after `steps` sewing
    steps, with no crossing (independent check) on any step."""
    sim = _over_a_wall()
    wall = sim.model.obstacles[0]
    for k in range(steps):
        sim.step()
        x = assert_garment_clean(sim.model.pieces, sim.C, f"step {k + 1}", sim.obstacle_positions()["wall"],
                                 wall.faces)
    return float(sim.model.seam.samples.gaps(sim.C).max()), float(x[:, 2].max())


def test_a_seam_closes_over_a_wall_between_its_panels_not_into_it(monkeypatch):
    gap, top = _sew_over_a_wall()
    assert gap < 1e-3 and top > 0.0, (gap, top)  # closed, over the wall's top (z = 0)
    # Pulled straight (no waypoints), the same seam presses its panels into the wall.
    monkeypatch.setattr(sewing_module, "waypoints", lambda a, b, body, t, p: (np.zeros(len(a), bool), 0.5 * (a + b)))
    gap, top = _sew_over_a_wall()
    assert gap > 0.02 and top < 0.0, (gap, top)
