"""IPC contact: mapped derivatives, and no triangle ever passing through another."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from sim.errors import InputError
from garment.io.obstacles import load_obstacle
from garment.scene import loads_scene
from sim.assembly import BlockPattern, add_dof_matrix
from garment.build import build_simulator

from tests.support.fd import dofs, fd_gradient, fd_hessian, gradient
from tests.support.intersections import intersecting_pairs
from tests.support.scenes import DROP


def test_intersection_check_detects_crossings():
    tri = np.array([[0, 1, 2]])
    A = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    B = np.array([[0.2, 0.2, -0.5], [0.2, 0.2, 0.5], [0.8, 0.8, 0.5]])
    assert intersecting_pairs(A, tri, B, tri) == 1
    assert intersecting_pairs(A, tri, B + [0, 0, 0.6], tri) == 0


def test_sheet_on_sphere_never_intersects():
    sim = build_simulator(loads_scene(DROP.format(height=0.2)))
    ball = load_obstacle(loads_scene(DROP.format(height=0.2)).obstacles[0])
    ground_z = 0.0
    faces = sim.model.pieces[0].topology.faces
    for _ in range(22):  # free fall ~0.1 m, then contact with the ball
        st = sim.step()
        x = sim.positions("sheet")
        assert np.all(np.isfinite(x))
        assert intersecting_pairs(x, faces, ball.vertices, ball.faces) == 0
        assert intersecting_pairs(x, faces) == 0
        assert x[:, 2].min() > ground_z
        if st.extra["contact_count"] > 0:
            assert st.extra["min_distance"] > 0.0
    # The sheet reached the ball and is held above it (within a few dhat of its top).
    assert st.extra["contact_count"] > 0
    centre = x[np.argmin(np.linalg.norm(x[:, :2], axis=1))]
    assert 0.16 < centre[2] < 0.16 + 0.01


def test_contact_mesh_density_sets_vertices_per_control_point():
    # 10 x 10 control points: 14 x 14 vertices by default (about 2 per point), 10 x 10 at 1.
    for density, n in (("", 196), ("mesh_density = 1\n", 100), ("mesh_density = 4\n", 400)):
        scene = loads_scene(DROP.format(height=0.2).replace("[time]", density + "[time]"))
        assert build_simulator(scene).model.barrier.contact.n_cloth == n


def test_barrier_derivatives_on_control_points():
    sim = build_simulator(loads_scene(DROP.format(height=0.1605)))
    e = sim.model.barrier
    C = sim.C.copy()
    assert e.value(C) > 0.0  # the sheet's centre is within dhat of the ball's top
    rng = np.random.default_rng(1)
    C = C + 1e-5 * rng.standard_normal(C.shape) * [1, 1, 0]
    g = np.zeros_like(C)
    e.add_gradient(C, g)
    active = np.flatnonzero(np.abs(g).sum(1) > 0)
    assert active.size > 0
    h = 1e-7
    rows = active[:6]
    assert fd_gradient(e, C, h, rows) == pytest.approx(g[rows], rel=1e-4, abs=1e-6 * np.abs(g).max())
    H = e.hessian_matrix(C, project=False).toarray()
    rows = active[:4]
    np.testing.assert_allclose(H[:, dofs(rows)], fd_hessian(e, C, h, rows), rtol=1e-4, atol=1e-5 * np.abs(H).max())


def test_barrier_keeps_the_collision_sets_of_its_last_two_points(one_ipc_thread):
    """Back at the point before a rejected trial, the barrier reuses that point's
    collision set; a third point rebuilds into the older one's."""
    sim = build_simulator(loads_scene(DROP.format(height=0.1605)))
    e = sim.model.barrier
    C1 = sim.C.copy()
    C2 = C1 + [0.0, 0.0, 5e-4]  # lifted past dhat: no contact
    C3 = C1 + [0.0, 0.0, 2e-4]
    E1, set1, n1 = e.value(C1), e.collisions, e.n_collisions
    E2, set2 = e.value(C2), e.collisions
    assert set2 is not set1 and n1 > 0 and e.n_collisions == 0 and E2 == 0.0
    assert e.value(C1) == E1 and e.collisions is set1 and e.n_collisions == n1
    E3 = e.value(C3)
    assert e.collisions is set2 and 0.0 < E3 < E1  # C2's set, rebuilt at C3
    assert e.value(C1) == E1 and e.collisions is set1
    fresh = build_simulator(loads_scene(DROP.format(height=0.1605))).model.barrier
    assert fresh.value(C3) == E3  # the reused set holds exactly C3's collisions


def test_trial_points_on_the_ccd_segment_get_the_collisions_of_a_full_build(one_ipc_thread):
    """The line search's points on the last CCD segment are built from that segment's
    broad phase; they must hold the collisions a full build finds, and a point off the
    segment must not be built from it."""
    scene = DROP.format(height=0.1605)
    e = build_simulator(loads_scene(scene)).model.barrier
    fresh = build_simulator(loads_scene(scene)).model.barrier
    C1 = build_simulator(loads_scene(scene)).C.copy()
    up = C1 + [0.0, 0.0, 5e-3]
    assert e.max_step(up, up + [0.01, 0.0, 0.0]) == 1.0  # far above the ball: no candidates near it
    assert e.value(C1) == pytest.approx(fresh.value(C1), rel=1e-12) and e.n_collisions > 0
    down = C1 - [0.0, 0.0, 2e-4]
    assert e.max_step(up, down) == 1.0
    for t in (0.5, 0.95, 1.0):  # the first point a plain build, the others from the segment's broad phase
        C = up + t * (down - up)
        assert e.value(C) == pytest.approx(fresh.value(C), rel=1e-12)
        assert e.n_collisions == fresh.n_collisions
    assert e.n_collisions > 0
    import ipctk

    assert isinstance(e._segment.candidates, ipctk.Candidates)  # built, and used for 0.95 and 1.0
    aside = C1 + [2e-3, 0.0, 0.0]
    assert e._candidates_at(aside) is None
    assert e.value(aside) == pytest.approx(fresh.value(aside), rel=1e-12) and e.n_collisions == fresh.n_collisions


def test_projected_contact_hessian_stays_psd_in_pattern():
    """Off-pattern contact entries move to the diagonal: the assembled matrix stays PSD."""
    free = np.arange(6)
    pattern = BlockPattern.from_stencils(free, [np.array([[0, 1, 2], [3, 4, 5]])])
    rng = np.random.default_rng(0)
    A = rng.standard_normal((18, 18))
    H = A @ A.T  # dense PSD: couples blocks (0, 3) etc. that the pattern lacks
    data = np.zeros(pattern.nnz)
    moved = add_dof_matrix(pattern, sp.csr_matrix(H), data)
    assert moved > 0
    assert np.linalg.eigvalsh(pattern.full(data).toarray()).min() > -1e-9


def test_initial_intersection_is_an_input_error():
    with pytest.raises(InputError, match="intersect"):
        build_simulator(loads_scene(DROP.format(height=0.1)))


def test_friction_derivatives_on_control_points():
    text = DROP.format(height=0.1605).replace("kappa = 1e5", "kappa = 1e5\nmu = 0.3\neps_v = 1e-2")
    sim = build_simulator(loads_scene(text))
    f = sim.model.friction
    f.lag(sim.C)
    assert f.active
    rng = np.random.default_rng(2)
    # Slide tangentially by more than eps_v dt (dynamic regime) at some points, less at others.
    C = sim.C + 1e-4 * rng.standard_normal(sim.C.shape) * [1, 1, 0]
    g = gradient(f, C)
    rows = np.flatnonzero(np.abs(g).sum(1) > 0)
    assert rows.size > 0 and f.value(C) > 0.0
    # Central differences of value -> gradient and gradient -> Hessian columns.
    rows, h = rows[:4], 1e-8
    H = f.hessian_matrix(C, project=False).toarray()
    assert fd_gradient(f, C, h, rows) == pytest.approx(g[rows], rel=1e-4, abs=1e-4 * np.abs(g).max())
    np.testing.assert_allclose(H[:, dofs(rows)], fd_hessian(f, C, h, rows), rtol=1e-4, atol=1e-4 * np.abs(H).max())


def test_friction_opposes_sliding():
    """The friction force on a sliding sheet points against the slide, with magnitude
    mu x (normal force) once the slide is faster than eps_v."""
    text = DROP.format(height=0.1605).replace("kappa = 1e5", "kappa = 1e5\nmu = 0.3\neps_v = 1e-3")
    sim = build_simulator(loads_scene(text))
    sim.model.friction.lag(sim.C)
    slide = np.array([0.01, 0.0, 0.0])  # 1 m/s over dt = 0.01 s, far above eps_v
    g = np.zeros_like(sim.C)
    sim.model.friction.add_gradient(sim.C + slide, g)
    gb = np.zeros_like(sim.C)
    sim.model.barrier.add_gradient(sim.C, gb)
    assert g[:, 0].sum() > 0.0  # energy grows along the slide: the force opposes it
    assert abs(g[:, 1].sum()) < 0.05 * g[:, 0].sum()  # no sideways force
    normal = np.abs(gb[:, 2].sum())
    assert g[:, 0].sum() == pytest.approx(0.3 * normal, rel=0.05)


GRAZE = """
[[cloth]]
name = "sheet"
size = [0.2, 0.2]
control_points = [6, 6]
origin = [-0.1, -0.1, 1e-8]
[[obstacle]]
name = "ground"
plane = { point = [0, 0, 0], normal = [0, 0, 1], size = 1.0 }
[contact]
dhat = 1e-3
kappa = 1e5
[time]
dt = 0.01
"""


def test_ccd_at_a_graze_is_exact():
    """Cloth 1e-8 m above the ground (dressing pins straps that close to a shoulder): CCD
    lets it slide a centimetre along the ground in one step, and a step down twice the gap
    stops it at the conservative fraction of the first contact (0.9 x 1/2 = 0.45). Tight
    Inclusion, conservative to its 1e-6 m tolerance, returned 0.375 there."""
    sim = build_simulator(loads_scene(GRAZE))
    barrier, C = sim.model.barrier, sim.C.copy()
    assert barrier.max_step(C, C + [0.01, 0.004, 0.0]) == 1.0
    alpha = barrier.max_step(C, C - [0.0, 0.0, 2e-8])
    assert 0.40 < alpha < 0.5
    assert barrier.min_distance(C - alpha * np.array([0.0, 0.0, 2e-8])) > 0.0


def test_a_held_back_body_looks_for_cloth_near_by_and_bounds_the_rest():
    """body_clearance finds pairs only within CLEARANCE_REACH (its broad phase's cost grows
    with the reach); beyond, each body vertex gets a lower bound from the nearest cloth
    vertex. Against ipctk's per-vertex safe distances over the whole reach: never more
    (no vertex may move into cloth), and the ball's top, 14 cm under the sheet, still gets
    more than CLEARANCE_REACH."""
    import ipctk

    from sim.energies.barrier import CLEARANCE_REACH, DRIVE_FLOOR

    e = build_simulator(loads_scene(DROP.format(height=0.3))).model.barrier
    C = build_simulator(loads_scene(DROP.format(height=0.3))).C
    reach, floor = 0.2, DRIVE_FLOOR * e.dhat
    out = e.body_clearance(C, reach)
    x = e.contact.vertices(C)
    candidates = ipctk.Candidates()
    candidates.build(e.contact.mesh, x, reach)
    exact = np.ravel(candidates.compute_per_vertex_safe_distances(e.contact.mesh, x, reach, floor))
    exact = exact[e.contact.n_cloth:]
    assert e.contact.body_ids is None and out.shape == exact.shape
    assert np.all(out <= exact + 1e-12)
    ball = e.contact.obstacle_vertices[:, 2] > 0.15  # the ball's top, 14-15 cm under the sheet
    assert ball.any() and out[ball].min() > CLEARANCE_REACH
