"""Newton solver (sim/newton.py) through the Simulator: quadratic convergence with the
exact Hessian, exact pins, pin motion, and one-shot convergence on a quadratic problem."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import pytest

from sim.model import bspline_model
from sim.materials import Material
from sim.patches import Patch
from garment.scene import loads_scene
from sim import linsolve
from sim.energies import BendingEnergy, ExternalForceEnergy
from sim.linsolve import neumann, pcg
from sim.newton import NewtonOptions, _extrapolate, minimize
from sim.pins import PinGroup, select
from sim.potential import IncrementalPotential
from sim.quadrature import span_centres
from sim.rest import point_data
from sim.stats import StepStats
from garment.build import build_simulator
from sim.simulator import Simulator

SHEET = Patch.rectangle("sheet", (0.3, 0.3), (8, 8))


def tension_sheet(membrane: str, project: bool = False, speed: float = 0.5) -> Simulator:
    """A small sheet whose sides u0 and u1 are pulled apart: a well-posed, stretched state."""
    left = select(SHEET.shape, sides=("u0",))
    right = select(SHEET.shape, sides=("u1",))
    pins = [PinGroup(left, np.array([-speed, 0.0, 0.0])), PinGroup(right, np.array([speed, 0.0, 0.0]))]
    opts = NewtonOptions(project=project, record_gradients=True, tol=1e-12, max_iterations=20)
    return Simulator(bspline_model([SHEET], [Material(membrane=membrane)], pins, newton=opts))


# ------------------------------------------------------------------ quadratic convergence


@pytest.mark.parametrize("membrane", ("fbw", "stvk"))
def test_newton_step_error_is_quadratic(membrane):
    """From a converged step's solution C*, perturb the free DOFs by delta d and take one
    exact Newton step: the new error must scale like delta^2 (slope 2 in log-log, a
    constant ratio e1 / e0^2). A wrong or projected Hessian gives slope 1."""
    sim = tension_sheet(membrane)
    for _ in range(3):
        stats = sim.step()
        assert stats.converged
    ip = sim.model.potential  # the inertia target of the last step is still set
    C_star = sim.C.copy()
    free = ip.free_points
    g_star = np.linalg.norm(ip.gradient(C_star)[free])
    d = np.random.default_rng(0).standard_normal((free.size, 3))
    d /= np.abs(d).max()

    def newton_error(delta, project):
        C = C_star.copy()
        C[free] += delta * d
        g = ip.gradient(C)[free].ravel()
        ip.assemble(C, project)
        ip.solver.factorize(ip.matrix)
        C[free] -= ip.solver.solve(g).reshape(-1, 3)
        return np.abs(C - C_star).max()

    deltas = np.array([3e-5, 1e-5, 3e-6])
    e1 = np.array([newton_error(x, False) for x in deltas])
    # Errors far above the accuracy of C* (g* is at round-off) ...
    assert g_star < 1e-9
    assert e1.min() > 1e-10
    # ... contract quadratically: e1 ~ c delta^2 with one constant c.
    slopes = np.diff(np.log(e1)) / np.diff(np.log(deltas))
    assert np.all((slopes > 1.9) & (slopes < 2.1)), slopes
    c = e1 / deltas**2
    assert c.max() / c.min() < 1.2
    assert np.all(e1 < 0.05 * deltas)  # a real contraction at these sizes
    # Control: the PSD-projected Hessian is not the exact one here (FBW shear / StVK
    # compressed transverse fibres), so its step contracts only linearly: slope 1.
    p1 = np.array([newton_error(x, True) for x in deltas])
    slopes_p = np.diff(np.log(p1)) / np.diff(np.log(deltas))
    assert np.all((slopes_p > 0.8) & (slopes_p < 1.2)), slopes_p


@pytest.mark.parametrize("membrane", ("fbw", "stvk"))
def test_recorded_gradient_norms_converge_quadratically(membrane):
    """Dynamic steps with the exact Hessian, judged from the recorded ||g|| sequence:

    - round-off (1e-10 g_0) is reached within 7 iterations: a linearly convergent method
      would need a contraction factor below 0.04 at every iteration to do that;
    - every checked iteration obeys the quadratic bound g_{k+1} <= K g_k^2, K = 100 / N
      (the asymptotic constant of this sheet is about 0.01 / N along a random direction,
      pre-asymptotic iterations reach about 10 / N). Where g_k <= 2e-3 N this rules out
      any linear rate above 0.2 (at least two such iterations are required).

    Iterations with g_k < 1e-5 N are not checked: there the predicted decrease g.p / 2
    can fall below the round-off of the energy (about 1e-15 |E|) and the Armijo test may
    reject the full Newton step (see test_tight_tolerance_is_reachable)."""
    sim = tension_sheet(membrane)
    K = 100.0
    n_small = 0
    for _ in range(3):
        stats = sim.step()
        G = np.asarray(stats.extra["gradient_norms"])
        assert stats.converged
        assert G.size == stats.newton_iterations <= 7
        assert G[-1] < 1e-10 * G[0]
        checked = [k for k in range(G.size - 1) if G[k] >= 1e-5]
        assert len(checked) >= 2
        for k in checked:
            assert G[k + 1] <= K * G[k] ** 2, (k, G)
        n_small += sum(G[k] <= 2e-3 for k in checked)
    assert n_small >= 2


def test_projected_newton_converges_with_default_settings():
    """The production setting (projected Hessian, paper tolerance) converges quickly too."""
    left = select(SHEET.shape, sides=("u0",))
    sim = Simulator(bspline_model([SHEET], [Material()], [PinGroup(left, np.zeros(3))]))
    for _ in range(3):
        stats = sim.step()
        assert stats.converged and stats.newton_iterations <= 10
        assert stats.residual < sim.model.newton.tol


def test_tight_tolerance_is_reachable():
    """Exact Newton from a small perturbation of a converged StVK step must reach
    ||dC||_inf / dt < 1e-9 m/s (dC < 1e-11 m on a 0.3 m sheet, far above round-off)."""
    sim = tension_sheet("stvk")
    for _ in range(3):
        sim.step()
    ip = sim.model.potential
    free = ip.free_points
    d = np.random.default_rng(0).standard_normal((free.size, 3))
    C = sim.C.copy()
    C[free] += 3e-3 * d / np.abs(d).max()
    stats = StepStats()
    path = []
    C_end = minimize(ip, C, NewtonOptions(tol=1e-9, dt=sim.dt, project=False, max_iterations=30), stats, path)
    assert stats.converged and stats.newton_iterations <= 10
    # The way it went: the start, then one point per iteration that moved (the last one
    # only tests convergence); no bodies here.
    assert len(path) == stats.newton_iterations and path[-1][0] is C_end and path[1][1] is None
    np.testing.assert_array_equal(path[0][0], C)
    # A solve carried on from there (stepper._within_reach) counts on from the first.
    first = stats.newton_iterations
    minimize(ip, C_end, NewtonOptions(tol=1e-9, dt=sim.dt, project=False, max_iterations=30), stats)
    assert stats.newton_iterations == first + 1


# ------------------------------------------------------------------ pins


def test_pins_are_exact_and_move_for_their_duration():
    n, m = SHEET.shape
    dt = 0.01
    still = PinGroup(select(SHEET.shape, corners=("u0v0",)), np.zeros(3))
    moving = PinGroup(select(SHEET.shape, corners=("u1v1",)), np.array([0.3, -0.2, 0.5]), 0.0, 0.025)
    delayed = PinGroup(select(SHEET.shape, corners=("u0v1",)), np.array([0.0, 0.0, -1.0]), 0.015, 1.0)
    sim = Simulator(bspline_model([SHEET], [Material()], [still, moving, delayed], dt=dt))
    W = SHEET.world.reshape(-1, 3)
    free = ~sim.model.pinned
    assert sim.model.pinned.sum() == 3
    for k in range(1, 6):
        before = sim.C.copy()
        stats = sim.step()
        t = k * dt
        assert stats.converged
        # Exact: pinned points equal their targets bit for bit.
        targets = sim.pin_targets(sim.t)
        assert np.array_equal(sim.C[sim.model.pinned], targets[sim.model.pinned])
        assert np.array_equal(sim.C[still.indices], W[still.indices])
        # Moving pins: velocity * (active time), clipped to [start, start + duration].
        expect = W[moving.indices] + moving.velocity * min(t, 0.025)
        assert np.abs(sim.C[moving.indices] - expect).max() < 1e-15
        expect = W[delayed.indices] + delayed.velocity * max(t - 0.015, 0.0)
        assert np.abs(sim.C[delayed.indices] - expect).max() < 1e-15
        step = sim.C[moving.indices] - before[moving.indices]
        if k <= 2:
            assert np.allclose(step, moving.velocity * dt, atol=1e-15)
        elif k >= 4:
            assert np.array_equal(step, np.zeros_like(step))  # stopped after its duration
        # The free points respond (gravity, pulled corner).
        assert np.abs(sim.C[free] - before[free]).max() > 1e-6


def test_simulator_mass_and_nodal_areas():
    sim = Simulator(bspline_model([SHEET], [Material()]))
    area = 0.3 * 0.3
    assert sim.model.areas.sum() == pytest.approx(area, rel=1e-12)
    assert sim.model.mass.sum() == pytest.approx(Material().areal_density * area, rel=1e-12)
    assert np.all(sim.model.mass > 0)
    # A free fall step with no pins: every point falls by g dt^2 (implicit Euler, from rest),
    # since elastic forces vanish on a rigid translation.
    stats = sim.step()
    assert stats.converged
    drop = SHEET.world.reshape(-1, 3) - sim.C
    assert np.abs(drop[:, :2]).max() < 1e-12
    assert np.allclose(drop[:, 2], 9.81 * sim.dt**2, rtol=1e-6)


# ------------------------------------------------------------------ quadratic problems


def plate(nc: int):
    return Patch.rectangle("plate", (1.0, 1.0), (nc, nc))


def test_bending_only_potential_converges_in_one_newton_step():
    """Bending + a dead load is quadratic: one Newton step solves it to round-off."""
    p = plate(10)
    n, m = p.shape
    pd = point_data(p.rest, span_centres(n, m), second_order=True)
    D = 0.17
    forces = np.zeros((p.n_control_points, 3))
    forces[:, 2] = 1e-2
    pinned = np.zeros(p.n_control_points, bool)
    pinned[select(p.shape, sides=("u0", "u1", "v0", "v1"))] = True
    ip = IncrementalPotential([BendingEnergy(pd, np.full(pd.n_points, D), p.n_control_points),
                               ExternalForceEnergy(forces)], ~pinned)
    stats = StepStats()
    C = minimize(ip, p.world.reshape(-1, 3), NewtonOptions(tol=1e-9, dt=0.01, record_gradients=True), stats)
    G = stats.extra["gradient_norms"]
    assert stats.converged and stats.newton_iterations <= 2
    assert G[-1] < 1e-10 * G[0]
    assert np.array_equal(C[pinned], p.world.reshape(-1, 3)[pinned])
    assert C[:, 2].max() > 1e-3  # it did deflect


def test_quasistatic_plate_converges_in_two_iterations():
    """The plate benchmark (docs/design.md section 7) with a negligible membrane: the Newton
    loop needs one step plus the convergence check, and the deflection is close to the
    Kirchhoff value w_max = 0.00406 q a^4 / D."""
    E, nu, h, q = 2e6, 0.03, 0.01, 9.81
    mat = Material(E_st=1e-6, E_sh=5e-9, E_bd=E, nu=nu, h=h, rho=1.0)
    p = plate(12)
    pins = [PinGroup(select(p.shape, sides=("u0", "u1", "v0", "v1")), np.zeros(3))]
    sim = Simulator(bspline_model([p], [mat], pins, gravity=(0.0, 0.0, 0.0), pressure=q, mode="quasistatic",
                    newton=NewtonOptions(tol=1e-6, record_gradients=True)))
    stats = sim.step()
    assert stats.converged and stats.newton_iterations <= 2
    G = stats.extra["gradient_norms"]
    assert G[-1] < 1e-8 * G[0]
    w = np.abs(sim.positions("plate")[:, 2]).max()
    w_ref = 0.00406 * q / mat.bending_stiffness
    assert abs(w / w_ref - 1) < 0.02


def test_pcg_solves_spd_systems_and_every_iterate_descends():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((40, 40))
    A = A @ A.T + 0.1 * np.eye(40)
    b = rng.standard_normal(40)
    jacobi = 1.0 / np.diag(A)
    x, k, ok = pcg(lambda v: A @ v, b, lambda r: jacobi * r, np.zeros(40), 1e-10, 400)
    assert ok and np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b)
    # Stopped early, the iterate still lowers the quadratic model (a descent direction).
    x3, _, ok3 = pcg(lambda v: A @ v, b, lambda r: jacobi * r, np.zeros(40), 1e-14, 3)
    assert not ok3 and 0.5 * x3 @ A @ x3 - b @ x3 < 0.0


def test_neumann_series_converges_when_the_splitting_contracts():
    rng = np.random.default_rng(4)
    M = np.diag(rng.uniform(2.0, 3.0, 30))
    N = 0.05 * rng.standard_normal((30, 30))
    N = N + N.T  # ||M^-1 N|| well below 1
    A = M - N
    b = rng.standard_normal(30)
    inv = 1.0 / np.diag(M)
    x, k, ok = neumann(lambda v: A @ v, b, lambda r: inv * r, inv * b, 1e-12, 200)
    assert ok and k < 60 and np.linalg.norm(A @ x - b) <= 1e-12 * np.linalg.norm(b)


class _Line:
    """A potential along one coordinate for _extrapolate: E(C) = f(C[0, 0]); collision-free
    up to `wall`."""

    def __init__(self, f, wall=np.inf):
        self.f, self.wall, self.variable = f, wall, [True]

    def value(self, C):
        return self.f(C[0, 0])

    def max_step(self, C0, C1):
        return min(1.0, (self.wall - C0[0, 0]) / (C1[0, 0] - C0[0, 0]))


@pytest.mark.parametrize("f, wall, reached", [
    (lambda x: -x, np.inf, 16.0),             # linear: every doubling pays, up to the limit
    (lambda x: (x - 3.0) ** 2, np.inf, 2.0),  # minimum at 3: 2 is lower than 1, 4 is not
    (lambda x: -x, 5.0, 4.0),                 # the collision test stops the doubling at 4
])
def test_extrapolation_doubles_a_full_step_while_the_energy_falls(f, wall, reached):
    ip, stats = _Line(f, wall), StepStats()
    C = np.zeros((2, 3))
    C[0, 0] = 1.0  # the full step p = (1, 0, 0) already taken from 0
    step = np.zeros((2, 3))
    step[0, 0] = 1.0
    C_new, E_new = _extrapolate(ip, C, f(1.0), step, np.arange(2), 4, stats)
    assert C_new[0, 0] == reached and E_new == f(reached)
    assert np.all(C_new[1] == 0.0) and C[0, 0] == 1.0  # the input is not modified
    assert stats.extra.get("extrapolations", 0) == int(np.log2(reached))


def test_large_factorizations_get_more_blas_threads_and_give_them_back():
    lib = linsolve._OPENBLAS
    if lib is None or linsolve.LARGE_THREADS <= 1:
        pytest.skip("CHOLMOD does not call the system OpenBLAS here, or one core")
    before = lib.openblas_get_num_threads()
    with linsolve.blas_threads(linsolve.PARALLEL_ROWS - 1):
        assert lib.openblas_get_num_threads() == before
    with linsolve.blas_threads(linsolve.PARALLEL_ROWS):
        assert lib.openblas_get_num_threads() == linsolve.LARGE_THREADS
    assert lib.openblas_get_num_threads() == before
    # The factorization inside still solves: a large SPD system, residual at round-off.
    n = linsolve.PARALLEL_ROWS
    A = sp.diags([np.full(n - 1, -1.0), np.full(n, 2.5)], [-1, 0], format="csc")
    b = np.ones(n)
    x = linsolve.solve_once(A, b)
    A_full = A + sp.tril(A, -1).T
    assert np.abs(A_full @ x - b).max() < 1e-12


SLIDING = """
[material]
preset = "cotton"
[[cloth]]
name = "under"
size = [0.1, 0.1]
control_points = [5, 5]
origin = [-0.05, -0.05, 0.0]
velocity = [-1.0, 0.0, 0.0]
[[cloth]]
name = "over"
size = [0.1, 0.1]
control_points = [5, 5]
origin = [-0.05, -0.05, 2e-5]
velocity = [1.0, 0.0, -0.05]
[load]
gravity = [0, 0, 0]
[contact]
dhat = 1e-3
kappa = 1e8
mu = 1.0
[time]
dt = 0.01
max_newton_iterations = 1
"""


def _longest_ccd_move(max_speed: float) -> tuple[float, int]:
    """Two sheets 20 um apart sliding past each other at 2 m/s, pressed by a stiff
    barrier: the lagged friction mu lambda meets only inertia along the slip. Returns the
    longest move handed to CCD in the first Newton iteration, and the capped iterations."""
    sim = build_simulator(loads_scene(SLIDING), NewtonOptions(max_speed=max_speed))
    moves, ccd = [0.0], sim.model.potential.max_step

    def max_step(C0, C1, B1=None, driven=False):
        moves.append(float(np.abs(C1 - C0).max()))
        return ccd(C0, C1, B1, driven)

    sim.model.potential.max_step = max_step
    st = sim.step()
    return max(moves), st.extra.get("capped_steps", 0)


def test_line_search_starts_within_max_speed_of_a_pressed_sliding_contact():
    # Uncapped, Newton proposes about a metre (CCD's broad phase grows every box by that).
    free, _ = _longest_ccd_move(np.inf)
    assert free > 0.5
    capped, count = _longest_ccd_move(10.0)
    assert count >= 1
    assert capped <= 10.0 * 0.01 * (1 + 1e-12)


# ------------------------------------------------------------------ forcing (settling)


def _falling_sheet(relative: float) -> Simulator:
    """A sheet held at two corners, thrown down at 1 m/s: it swings under gravity."""
    return build_simulator(loads_scene(f"""
[[cloth]]
size = [0.3, 0.3]
control_points = [10, 10]
velocity = [0.0, 0.0, -1.0]
[[pin]]
corners = ["u0v1", "u1v1"]
[time]
dt = 0.01
newton_relative_tol = {relative}
"""))


def test_relative_tolerance_follows_the_speed_and_falls_back_to_the_absolute_one():
    from sim.newton import tolerance

    opts = NewtonOptions(tol=1e-2, dt=0.01, relative_tol=0.1)
    origin = np.zeros((4, 3))
    assert tolerance(opts, origin, origin) == 1e-2  # at rest: the paper's rule
    C = origin + 0.01 * np.array([0.3, 0.0, 0.4])  # moved at an RMS speed of 0.5 m/s
    assert tolerance(opts, C, origin) == pytest.approx(0.05)
    assert tolerance(NewtonOptions(tol=1e-2, dt=0.01), C, origin) == 1e-2  # off unless asked for
    assert tolerance(opts, C, None) == 1e-2


def test_relative_tolerance_saves_iterations_and_stays_within_its_bound():
    """Steps solved to 10 % of a 1 m/s fall take fewer Newton iterations; the cloth ends
    within that tolerance's reach (0.1 x 1 m/s x dt a step) of the fully solved one."""
    exact, loose = _falling_sheet(0.0), _falling_sheet(0.1)
    its = [0, 0]
    for _ in range(3):
        its[0] += exact.step().newton_iterations
        st = loose.step()
        its[1] += st.newton_iterations
        assert st.converged
    assert its[1] < its[0]
    assert np.abs(loose.C - exact.C).max() < 3 * 0.1 * 1.0 * 0.01
