"""Projected Newton with backtracking line search (paper section 5.1, IPC's solver).

Minimises the incremental potential over the free control points; pinned points keep
the values they enter with, so pins hold exactly. Stops when ||dC||_inf / dt < tol (the
paper's rule, tol in m/s).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .linsolve import neumann, pcg, solve_once
from .potential import IncrementalPotential
from .stats import StepStats


class Interrupted(Exception):
    """The caller's stop condition (a wall-clock limit) came true during a step
    (IncrementalPotential.should_stop, asked before every iteration)."""


@dataclass
class NewtonOptions:
    tol: float = 1e-2  # m/s
    # Newton may stop at this fraction of the step's RMS speed so far instead (0: tol
    # only; see tolerance()).
    relative_tol: float = 0.0
    dt: float = 0.01  # s, scales the step-size criterion
    max_iterations: int = 100
    armijo: float = 1e-4
    min_step: float = 1e-12
    project: bool | str = "auto"  # True: always PSD-project; "auto": only when not PD
    projection: str = "clamp"  # how projected Hessians treat negative eigenvalues (energies/base.py)
    record_gradients: bool = False  # keep ||g_free|| per iteration (convergence tests)
    pcg_rtol: float = 1e-8  # CG on the exact Hessian when contact couplings leave the pattern
    pcg_max_iterations: int = 30  # an early stop still gives a descent direction
    # Couplings outside the pattern: "merge" (into the Hessian, analysed and factored
    # anew), "auto" (partial factorization: CG or merge by the Gershgorin bound),
    # "neumann" (the same with a Neumann series instead of CG), "diagonal" (keep them on
    # the diagonal only). Merging pays now that only the nonzeros are factored
    # (linsolve.CholeskySolver): dress_02, 20 sewing steps after t = 0.25 s, 159 Newton
    # iterations, 52.6 s with "auto" (4 CG iterations a solve) against 44.4 s.
    off_pattern: str = "merge"
    # Doublings of a full step tried when the energy falls much faster than the Newton
    # model predicts (sliding friction: see _extrapolate); 0 turns them off.
    extrapolate: int = 0
    # With contact, the line search starts at most max_speed * dt from the iterate. Along
    # a sliding contact's slip only inertia meets the lagged friction force mu lambda, so
    # a contact pressed hard gives a Newton step of metres (the dress at 32 mm during
    # sewing: 125 m, from a pair 18 um apart); CCD's broad phase grows every box by the
    # step, and that one call met 27M candidates and ran for minutes. 10 m/s is faster
    # than any cloth on a dancing body moves; a capped step is followed by another.
    max_speed: float = 10.0

    @classmethod
    def for_time(cls, time_spec, given: NewtonOptions | None = None) -> NewtonOptions:
        """`given` (or the defaults) with a scene's [time] Newton settings."""
        opts = given or cls()
        opts.tol, opts.max_iterations = time_spec.newton_tol, time_spec.max_newton_iterations
        opts.extrapolate = time_spec.newton_extrapolate or 0  # None: a TimeSpec not read from a scene
        opts.relative_tol = time_spec.newton_relative_tol
        return opts


def minimize(ip: IncrementalPotential, C: np.ndarray, opts: NewtonOptions, stats: StepStats,
             path: list | None = None, origin: np.ndarray | None = None) -> np.ndarray:
    """Returns the minimiser reached from C; fills the timing and iteration fields of stats.

    origin: where the step started (the state's positions), for opts.relative_tol.

    path: when given, every point the solve moves the cloth and the bodies through is
    appended as (C, B) (B: the obstacle vertices then, None without bodies), C included:
    straight segments, each collision free against the contact mesh of the solve."""
    C = C.copy()
    free = ip.free_points
    E = ip.value(C)
    history = []
    drive = ip.drive
    done = stats.newton_iterations  # a solve carried on (stepper._within_reach) counts on

    def passed(C):
        if path is not None:
            path.append((C, None if drive is None else drive.mesh.obstacle_vertices))

    passed(C)
    moving = drive is not None and drive.pending
    auto = opts.project == "auto"
    # Iterations to go projected, and the next back-off after a failure; carried over
    # between steps, so a cloth that stays indefinite rarely pays for failed attempts.
    skip, wait = ip.projection_backoff
    for it in range(opts.max_iterations):
        if ip.should_stop is not None and ip.should_stop():
            raise Interrupted(f"stopped after {it} Newton iterations")
        try_exact = auto and skip == 0
        skip = max(skip - 1, 0)
        t0 = time.perf_counter()
        g = ip.gradient(C)[free].ravel()
        # Projection on demand: the exact Hessian keeps Newton's fast convergence where
        # projection would slow it (compressed membrane: sphere scene at 20^2, 293 -> 232
        # iterations over 31 contact steps) and is used whenever it is positive definite;
        # only when a factorization fails is the PSD-projected Hessian assembled instead,
        # and the exact one retried after 1, 2, 4, ... iterations (a failed attempt costs
        # a factorization).
        ip.assemble(C, project=bool(opts.project) and not try_exact and opts.projection)
        stats.t_assembly += time.perf_counter() - t0
        p = _direction(ip, C, g, drive if moving else None, opts, stats, allow_fail=try_exact)
        if try_exact:
            skip, wait = (wait, min(2 * wait, 64)) if p is None else (0, 1)
        if p is None:
            stats.extra["exact_failures"] = stats.extra.get("exact_failures", 0) + 1
            t1 = time.perf_counter()
            ip.assemble(C, project=opts.projection)
            stats.t_assembly += time.perf_counter() - t1
            p = _direction(ip, C, g, drive if moving else None, opts, stats, allow_fail=False)
        t3 = time.perf_counter()
        stats.newton_iterations = done + it + 1
        if opts.record_gradients:
            history.append(float(np.linalg.norm(g)))
        stats.residual = float(np.abs(p).max(initial=0.0)) / opts.dt
        if stats.residual < tolerance(opts, C, origin) and not moving:
            stats.converged = True
            break
        # Backtracking (Armijo) line search on the full potential, started from the
        # largest collision-free fraction of the step (CCD) when there is contact.
        slope = float(g @ p)
        step = p.reshape(-1, 3)
        trial = C.copy()
        if ip.variable:
            # (Not while bodies are on their way: CCD moves them along the same fraction.)
            longest = float(np.abs(step).max(initial=0.0))
            reach = 1.0 if moving else min(1.0, opts.max_speed * opts.dt / max(longest, 1e-300))
            if reach < 1.0:
                stats.extra["capped_steps"] = stats.extra.get("capped_steps", 0) + 1
            trial[free] = C[free] + reach * step
            t_ccd = time.perf_counter()
            alpha = reach * ip.max_step(C, trial, drive.target if moving else None, driven=moving)
            t_ccd = time.perf_counter() - t_ccd
            stats.t_ccd += t_ccd
            t3 += t_ccd  # the line-search time below excludes CCD
        else:
            alpha = 1.0
        if moving:
            # Prescribed motion: go as far as CCD allows, without the energy test.
            trial[free] = C[free] + alpha * step
            drive.advance(alpha)
            C, E = trial, ip.value(trial)
            passed(C)
            stats.line_search_steps += 1
            stats.t_line_search += time.perf_counter() - t3
            # A body stopped by trapped cloth stays behind for this step: one pinched
            # contact holds the joint motion at a sliver (a circle skirt on a forearm
            # held the whole growing body 1e-9 m short for 30 steps), so past that
            # every body vertex goes as far as the cloth around it allows, and the
            # ordinary iterations let the cloth give way.
            moving = drive.pending and alpha > BLOCKED
            if drive.pending and not moving:
                _advance_each(ip, drive, C, stats)
                E = ip.value(C)
                passed(C)
            continue
        while True:
            trial[free] = C[free] + alpha * step
            E_new = ip.value(trial)
            stats.line_search_steps += 1
            # Near the minimum the predicted decrease drops below the round-off of E;
            # accept steps that do not increase E beyond that round-off.
            noise = 16.0 * np.finfo(float).eps * max(abs(E), abs(E_new))
            if E_new <= E + opts.armijo * alpha * slope + noise or alpha < opts.min_step:
                break
            alpha *= 0.5
        stats.t_line_search += time.perf_counter() - t3
        if alpha < opts.min_step:
            break  # no descent possible along p: stationary to round-off
        if opts.extrapolate and alpha == 1.0 and E - E_new > EXTRAPOLATE_RATIO * -0.5 * slope:
            trial, E_new = _extrapolate(ip, trial, E_new, step, free, opts.extrapolate, stats)
        C, E = trial, E_new
        passed(C)
        if ip.on_iterate is not None and ip.on_iterate(C):
            E = ip.value(C)
    if drive is not None and drive.animated:
        stats.extra["body_lag"] = drive.lag()
    ip.projection_backoff = (skip, wait)
    stats.energy = E
    if opts.record_gradients:
        stats.extra["gradient_norms"] = history
    return C


def tolerance(opts: NewtonOptions, C: np.ndarray, origin: np.ndarray | None) -> float:
    """Newton's stopping tolerance at the iterate C of a step from `origin`: opts.tol, or
    with opts.relative_tol that fraction of the RMS speed (C - origin) / dt if larger.
    Settling wants the rest shape, not the path there: a skirt falling at 0.4 m/s gains
    nothing from steps solved to 1 cm/s, where projected Newton on buckling cloth crawls
    (dress_06's first step once sewn: 66 iterations, the last 40 moving fewer than 20
    control points). As the cloth comes to rest the absolute tol is back in force."""
    if opts.relative_tol <= 0.0 or origin is None:
        return opts.tol
    return max(opts.tol, opts.relative_tol * rms(C - origin) / opts.dt)


def rms(X: np.ndarray) -> float:
    """Root mean square of the rows' lengths of X (N, 3): a displacement's or velocity's
    size over the control points."""
    return float(np.sqrt(np.mean(np.sum(X * X, axis=1)))) if len(X) else 0.0


# A drive iteration whose CCD fraction is below this counts as blocked (measured on
# dress_04 and dress_06, which froze with every iteration a drive one at 1e-3..1e-9).
BLOCKED = 0.01
# Of its clearance, the share a blocked body vertex moves: the rest of the gap is left
# for the barrier to push the cloth out before the next step's drive.
CLEARANCE_SHARE = 0.5


def _advance_each(ip, drive, C, stats):
    """Move each obstacle vertex on its own by up to CLEARANCE_SHARE of its clearance
    from the cloth at C (IncrementalPotential.body_clearance)."""
    t0 = time.perf_counter()
    limit = ip.body_clearance(C, drive.lag())
    if limit is not None:
        drive.advance_each(CLEARANCE_SHARE * limit)
        stats.extra["blocked_drives"] = stats.extra.get("blocked_drives", 0) + 1
    stats.t_ccd += time.perf_counter() - t0


# Doublings tried by default (NewtonOptions.extrapolate, a scene's newton_extrapolate).
# Where the clamped Hessian sees no curvature along a buckling mode, full steps crawl down
# it: the frictionless sheet on a sphere, 75^2, 45 steps, 28.8 -> 21.1 Newton iterations
# a step (10.5 -> 9.0 s); the seeded hanging sheet, 53 steps, 9.57 -> 8.68 (2.27 -> 1.91 s).
EXTRAPOLATE = 4
# ... but not inside a narrow friction band, where the doublings cost more than they save
# (the dress on the dancer with eps_v 1e-3: 456 -> 520 iterations; docs/findings.md).
EXTRAPOLATE_MIN_EPS_V = 1e-2  # m/s


def default_doublings(mu: float, eps_v: float) -> int:
    """Doublings to try when a scene does not say: EXTRAPOLATE unless friction (mu > 0)
    has a band narrower than EXTRAPOLATE_MIN_EPS_V."""
    return 0 if mu > 0.0 and eps_v < EXTRAPOLATE_MIN_EPS_V else EXTRAPOLATE


# Actual over predicted decrease of a full step above which longer steps are tried. The
# model predicts -g.p / 2 for a Newton step p; along a direction where the energy is
# linear the actual decrease is -g.p, twice that.
EXTRAPOLATE_RATIO = 1.5


def _extrapolate(ip, C, E, step, free, limit, stats):
    """Double a full step p (C = start + p) up to `limit` times while the energy keeps
    falling and stays collision-free. Returns the point reached and its energy.

    Sliding friction is linear along the slip, but its lagged Hessian has the curvature
    mu lambda / |u| across it (u the slip so far): a contact about to slide a new way gets
    Newton steps of about |u|, which grow by some 20 % per iteration (the dress at 16 mm:
    tens of iterations, each decreasing the energy by twice the prediction)."""
    # One collision test for the longest extension; every shorter one is a prefix of it.
    span = 2.0**limit - 1.0
    far = C.copy()
    far[free] += span * step
    t0 = time.perf_counter()
    reach = span * (ip.max_step(C, far) if ip.variable else 1.0)
    stats.t_ccd += time.perf_counter() - t0
    t0 = time.perf_counter()
    start, length = C, 1.0
    while 2.0 * length - 1.0 <= reach:
        far = start.copy()
        far[free] += (2.0 * length - 1.0) * step
        E_far = ip.value(far)
        stats.line_search_steps += 1
        if not E_far < E:
            break
        C, E, length = far, E_far, 2.0 * length
        stats.extra["extrapolations"] = stats.extra.get("extrapolations", 0) + 1
    stats.t_line_search += time.perf_counter() - t0
    return C, E


def _direction(ip, C, g, drive, opts, stats, allow_fail):
    """Newton direction from the assembled Hessian, or None if it is not positive definite
    and `allow_fail`. Times factorization and solve into stats."""
    t0 = time.perf_counter()
    rhs = g
    if drive is not None:
        # Bodies still on their way (sim/contact/drive.py): the cloth step includes the
        # first-order push of the remaining body motion.
        rhs = g + ip.coupling(C, drive.remaining())[ip.free_points].ravel()
    # Contact couplings outside the fixed pattern (distant parts of a cloth, or two
    # pieces) sit on the diagonal of the assembled matrix so one symbolic analysis serves
    # every iteration. Partial factorization (paper section 5.3): when they are weak
    # (Gershgorin bound on ||D^-1 B|| < 1) solve the exact system by CG preconditioned
    # with that factor; otherwise merge them and factor once.
    exact = ip.correction is not None and opts.off_pattern != "diagonal"
    if exact and (opts.off_pattern == "merge" or ip.coupling_bound() >= 1.0):
        p = solve_once(ip.exact_lower(), rhs, allow_shift=not allow_fail)
        stats.factorizations += 1
        stats.t_factorization += time.perf_counter() - t0
        if p is None:
            return None
        stats.extra["merged_solves"] = stats.extra.get("merged_solves", 0) + 1
        return -p
    stats.factorizations += 1
    if allow_fail:
        if not ip.solver.try_factorize(ip.matrix):
            stats.t_factorization += time.perf_counter() - t0
            return None
    else:
        ip.solver.factorize(ip.matrix)
    t1 = time.perf_counter()
    p = -ip.solver.solve(rhs)
    if exact:
        iterate = neumann if opts.off_pattern == "neumann" else pcg
        p, k, ok = iterate(ip.apply_hessian, -rhs, ip.solver.solve, p, opts.pcg_rtol, opts.pcg_max_iterations)
        stats.extra["pcg_solves"] = stats.extra.get("pcg_solves", 0) + 1
        stats.extra["pcg_iterations"] = stats.extra.get("pcg_iterations", 0) + k
        stats.extra["pcg_failures"] = stats.extra.get("pcg_failures", 0) + (not ok)
    stats.t_factorization += t1 - t0
    stats.t_solve += time.perf_counter() - t1
    return p
