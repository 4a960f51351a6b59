"""Linear FEM baseline (sim/linear): meshes, Bergou bending and the triangle membrane
against finite differences and closed forms, plate convergence, a tiny hanging run."""

from __future__ import annotations

import numpy as np
import pytest

from garment.bench import compare, compare_ablation, compare_locking, compare_plate
from garment.bench.common import scene
from garment.bench.plate import navier_coefficient
from garment.build import build_linear_simulator, build_simulator
from sim.energies import MembraneFBW, MembraneStVK, membrane_params
from sim.linear import equilateral_mesh, grid_mesh
from sim.linear.bending_bergou import bergou_bending
from sim.linear.membrane import triangle_points
from sim.linear.model import select_vertices
from sim.materials import Material
from sim.state import State

from tests.support.fd import bound, fd_directional, gradient, hessian

MAT = Material()


def flat(mesh) -> np.ndarray:
    return np.c_[mesh.rest, np.zeros(mesh.n_vertices)]


def check_fd(energy, C, scale, rng):
    """Value -> gradient and gradient -> Hessian along a random direction (relative)."""
    pattern = bound(energy, C.shape[0])
    g = gradient(energy, C).ravel()
    H = hessian(energy, pattern, C)
    d = rng.standard_normal(C.shape)
    fd, fd_H = fd_directional(energy, C, d, 1e-6 * scale)
    assert fd == pytest.approx(g @ d.ravel(), rel=1e-5)
    fd_H = fd_H.ravel()
    np.testing.assert_allclose(H @ d.ravel(), fd_H, rtol=1e-5, atol=1e-6 * np.abs(fd_H).max())


def test_meshes_cover_the_rectangle():
    for mesh in (grid_mesh((1.0, 0.8), (7, 5)), equilateral_mesh((1.0, 0.8), 9)):
        assert mesh.areas().min() > 0.0
        assert mesh.areas().sum() == pytest.approx(0.8, rel=1e-12)
        # Interior edges: every face has 3 edges, boundary edges belong to one face.
        T = mesh.faces.shape[0]
        boundary = 3 * T - 2 * mesh.interior_edges().shape[0]
        edges = np.sort(np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]], mesh.faces[:, [2, 0]]]), axis=1)
        uniq, count = np.unique(edges, axis=0, return_counts=True)
        assert (count == 1).sum() == boundary
        perimeter = np.linalg.norm(mesh.rest[uniq[count == 1, 0]] - mesh.rest[uniq[count == 1, 1]], axis=1).sum()
        assert perimeter == pytest.approx(3.6, rel=1e-12)
    eq = equilateral_mesh((1.0, 1.0), 21)
    a, b, c = (eq.rest[eq.faces[:, k]] for k in range(3))
    sides = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)])
    interior = np.abs(sides.max(0) / sides.min(0) - 1.0) < 0.05
    assert interior.mean() > 0.9  # near-equilateral except the half triangles on the sides


def test_bergou_fd_and_rigid_invariance():
    rng = np.random.default_rng(1)
    mesh = equilateral_mesh((0.6, 0.5), 6)
    E = bergou_bending(mesh, 1.0)
    C = flat(mesh) + 0.02 * rng.standard_normal((mesh.n_vertices, 3))
    check_fd(E, C, 0.6, rng)
    # Flat and rigidly moved flat meshes carry no bending energy; a bent one does.
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    for mesh in (grid_mesh((1.0, 1.0), (9, 9)), equilateral_mesh((1.0, 1.0), 9)):
        E = bergou_bending(mesh, 1.0)
        assert abs(E.value(flat(mesh))) < 1e-12
        assert abs(E.value(flat(mesh) @ Q.T + [0.3, -1.0, 2.0])) < 1e-11
        assert np.abs(gradient(E, flat(mesh) @ Q.T)).max() < 1e-10
    bent = flat(mesh)
    bent[:, 2] = 0.1 * bent[:, 0] ** 2
    assert E.value(bent) > 1e-3


@pytest.mark.parametrize("layout", ["grid", "equilateral"])
def test_bergou_cylinder_matches_smooth_energy(layout):
    # Isometric bending to a cylinder of radius R: the smooth energy D/2 int (1/R)^2 dA.
    mesh = grid_mesh((1.0, 1.0), (81, 81)) if layout == "grid" else equilateral_mesh((1.0, 1.0), 81)
    E = bergou_bending(mesh, 1.0)
    R = 0.5
    for axis in (0, 1):
        s, t = mesh.rest[:, axis], mesh.rest[:, 1 - axis]
        P = np.zeros((mesh.n_vertices, 3))
        P[:, axis], P[:, 1 - axis], P[:, 2] = R * np.sin(s / R), t, R * (1.0 - np.cos(s / R))
        # Measured: grid 0.987, equilateral 0.989 / 0.993; the error is O(h).
        assert E.value(P) == pytest.approx(0.5 / R**2, rel=0.02)


@pytest.mark.parametrize("model", ["fbw", "stvk"])
def test_linear_membrane_fd(model):
    rng = np.random.default_rng(2)
    mesh = grid_mesh((0.6, 0.5), (5, 6))
    pts = triangle_points(mesh)
    mat = MAT.with_(membrane=model, E_sh=1e6)
    cls = MembraneFBW if model == "fbw" else MembraneStVK
    E = cls(pts, np.tile(membrane_params(mat), (pts.n_points, 1)), mesh.n_vertices)
    A = np.array([[1.05, 0.1], [-0.05, 0.97], [0.2, 0.1]])
    C = mesh.rest @ A.T + 0.01 * rng.standard_normal((mesh.n_vertices, 3))
    check_fd(E, C, 0.6, rng)


def test_linear_membrane_homogeneous_stretch():
    # A uniform 10 % stretch along x: F = diag(1.1, 1), FBW energy k_st h (0.1)^2 * area.
    mesh = equilateral_mesh((1.0, 1.0), 7)
    pts = triangle_points(mesh)
    E = MembraneFBW(pts, np.tile(membrane_params(MAT), (pts.n_points, 1)), mesh.n_vertices)
    C = np.c_[1.1 * mesh.rest[:, 0], mesh.rest[:, 1], np.zeros(mesh.n_vertices)]
    assert E.value(C) == pytest.approx(MAT.h * MAT.k_st * 0.01, rel=1e-10)


def plate_error(n: int, layout: str) -> float:
    sc = scene("plate")
    cloth = sc.cloths[0]
    sim = build_linear_simulator(sc, n, layout)
    sim.step()
    mesh = sim.model.pieces[0].mesh
    k, bary = mesh.locate((0.5, 0.5))
    w = float(bary @ (sim.C - sim.model.C0)[mesh.faces[k]] @ np.asarray(sc.load.pressure_direction))
    ref = navier_coefficient() * sc.load.pressure * cloth.size[0] ** 4 / cloth.material.bending_stiffness
    return abs(w - ref) / ref


def test_plate_linear_fem_converges_on_equilateral_meshes():
    # Measured: 9.9 %, 6.2 %, 2.3 % at 9, 17, 33 vertices a side (1.2 % at 65).
    errors = [plate_error(n, "equilateral") for n in (9, 17, 33)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.03
    # Alternating right triangles converge to the wrong plate (paper section 6.2): ~25 %.
    assert plate_error(33, "grid") > 0.2


def test_pins_map_by_position():
    mesh = grid_mesh((1.0, 1.0), (5, 5))
    assert list(select_vertices(mesh, corners=("u0v0", "u1v1"))) == [0, 24]
    assert list(select_vertices(mesh, sides=("v0",))) == [0, 5, 10, 15, 20]
    assert len(select_vertices(mesh, sides=("u1",), depth=2)) == 10
    eq = equilateral_mesh((1.0, 1.0), 9)
    side = select_vertices(eq, sides=("u0",))
    assert np.all(eq.rest[side, 0] == 0.0) and len(side) > 5


def test_tiny_hanging_run():
    sim = build_linear_simulator(scene("hanging"), 12)
    assert sim.model.pinned.sum() == 2
    for _ in range(3):
        st = sim.step()
        assert st.converged
    pins = np.flatnonzero(sim.model.pinned)
    np.testing.assert_allclose(sim.C[pins], sim.pin_targets(sim.t)[pins])
    free = ~sim.model.pinned
    assert np.mean(sim.C[free, 2] - sim.model.C0[free, 2]) < -1e-3  # falls under gravity
    assert sim.positions("sheet").shape == (144, 3)


def test_compare_benchmark_pair_and_plate_rows(tmp_path):
    rows = compare.run((8,), steps=1, case="hanging", out=tmp_path)
    (row,) = rows
    assert (row["resolution"], row["linear_resolution"]) == (8, 12)
    for key in ("seconds_per_step_bspline", "seconds_per_step_linear", "speedup", "hausdorff_mm"):
        assert row[key] > 0.0
    assert row["speedup"] == pytest.approx(row["seconds_per_step_linear"] / row["seconds_per_step_bspline"])
    assert row["hausdorff_mm"] < 50.0  # one step of the same fall
    assert (tmp_path / "compare.json").exists() and (tmp_path / "compare.md").exists()
    rows = compare_plate.run({"reduced": (8, 16)}, {"equilateral": (9, 17)})
    summary = [r for r in rows if r["method"] == "equal-accuracy"]
    assert summary and all(r["rel_error_bspline"] <= r["rel_error_linear"] for r in summary)


def test_compare_locking_and_ablation_rows():
    (row,) = compare_locking.run((2e6,), n=8, steps=2, shear_ratios=(5e-3,))
    for key in ("sag_m_bspline", "sag_m_linear_aligned", "sag_m_linear_crossing"):
        assert 0.0 < row[key] < 1.0  # falling, still above the pins' reach
    rows = compare_ablation.run(n=8, steps=1)
    assert [r["variant"] for r in rows] == list("ABCDE")
    # (E) is linear FEM at the same resolution: the same unknowns as (A)-(D).
    assert len({r["dofs"] for r in rows}) == 1
    assert all(r["seconds_per_iteration"] > 0.0 for r in rows)


@pytest.mark.parametrize("name", ["hanging", "sphere"])
def test_both_discretisations_continue_bit_for_bit_from_a_saved_state(name, tmp_path, one_ipc_thread):
    # Both are a sim.model.Model stepped by sim.stepper: one State holds everything either
    # evolves, so a state saved and loaded into a fresh simulator continues identically.
    sc = scene(name, (8, 8))
    for build in (lambda: build_simulator(sc), lambda: build_linear_simulator(sc, 8)):
        a = build()
        a.step()
        a.step()
        path = a.state.save(tmp_path / "state.npz")
        b = build()
        b.state = State.load(path)
        for _ in range(2):
            a.step()
            b.step()
        assert np.array_equal(a.C, b.C) and np.array_equal(a.V, b.V) and a.t == b.t
