"""One time step: implicit Euler (or a quasi-static load increment) solved by projected
Newton, advancing a State on a Model."""

from __future__ import annotations

import time as _time

import numpy as np

from .model import Model
from .newton import minimize, rms
from .state import State
from .stats import StepStats


def step(model: Model, state: State) -> StepStats:
    """Advance `state` by state.dt in place; returns the step's statistics."""
    start = _time.perf_counter()
    t_next = state.t + state.dt
    if model.dt != state.dt:
        model.set_dt(state.dt)
    sewing = model.sewing
    model.potential.restart()
    stats = StepStats(step=state.step_count + 1, time=t_next)
    if sewing is not None and sewing.ramp(t_next):
        model.potential.refresh_constant()
    stats.extra["seam_pairs_sewn"] = float(model.merge_seams(state.C))
    blocked = model.blocked_pairs(state.C)
    stats.extra["seam_pairs_blocked"] = float(blocked.sum()) if blocked is not None else 0.0
    screened = model.screened_samples(state.C)
    held = model.held_pairs(state.C)
    if sewing is not None and sewing.hold(state.C, state.t, state.pleat_faces, held, screened):
        model.potential.refresh_constant()
    if sewing is not None and model.barrier is not None:
        contact = model.barrier.contact
        if sewing.route(state.C, contact.obstacle_vertices, contact.body_faces):
            model.potential.refresh_constant()
        stats.extra["seam_samples_routed"] = float(sewing.energy.routed.sum())
    model.loads.set_time(t_next)
    model.drawstring.set_time(t_next)
    targets = model.pin_targets(state.C, t_next)
    # Predictor C + dt V: the inertia target in dynamics, the secant (last increment)
    # predictor in quasi-statics (wrinkle 20x47: 41 -> 33 Newton iterations per load step).
    C_hat = state.C + state.dt * state.V
    if model.inertia is not None:
        model.inertia.target = C_hat
    x0 = np.where(model.pinned[:, None], targets, C_hat)
    reach, path = None, None
    if model.barrier is not None:
        model.drive.set_time(t_next)
        reach = contact_reach(model, state, x0)
        model.barrier.contact.focus(state.C, model.drive.target, reach + model.barrier.dhat)
        # Each step starts from fully built collision sets: one built from a line-search
        # segment's candidates sums in another order, and a run resumed from a checkpoint
        # would then differ from the straight one in the last bits.
        model.barrier.forget()
        # The predictor must not tunnel through a barrier thinner than one step of
        # motion: move only the collision-free fraction of the way (CCD), bodies
        # included; Newton carries on with whatever body motion remains.
        if model.friction is not None:
            model.friction.lag(state.C)
        C_start = np.where(model.pinned[:, None], targets, state.C)
        t_ccd = _time.perf_counter()
        alpha = model.potential.max_step(C_start, x0, model.drive.target if model.drive.pending else None,
                                         driven=model.drive.pending)
        stats.t_ccd += _time.perf_counter() - t_ccd
        x0 = C_start + alpha * (x0 - C_start)
        path = [(C_start, model.barrier.contact.obstacle_vertices)]  # the way the step goes (_within_reach)
        model.drive.advance(alpha)
        if model.stiffness is not None:
            stats.extra["kappa"] = model.stiffness.update(model.potential, x0)
    pulled_shut = sewing is not None and sewing.pulled_shut(t_next, state.dt)
    newton = sewing.newton(model.newton) if pulled_shut else model.newton
    C_new = minimize(model.potential, x0, newton, stats, path, origin=state.C)
    if reach is not None:
        C_new = _within_reach(model, state, path, C_new, reach, stats, newton)
    if sewing is not None:
        stats.extra["seam_gap_max"] = sewing.after_step(C_new)
    if model.barrier is not None:
        stats.extra["contact_count"] = float(model.barrier.n_collisions)
        stats.extra["min_distance"] = model.barrier.min_distance(C_new)
    state.V = (C_new - state.C) / state.dt
    # RMS control-point speed of the step, before velocities are dropped or damped: how
    # far from rest the cloth is.
    stats.extra["speed_rms"] = rms(state.V)
    if pulled_shut:
        state.V[:] = 0.0
        stats.extra["pulled_shut"] = 1.0
    elif (kept := model.drag.kept(t_next, state.dt)) < 1.0:
        state.V *= kept
    state.C = C_new
    state.t = t_next
    state.step_count += 1
    model.record(state)
    stats.t_total = _time.perf_counter() - start
    return stats


REACH = 0.03  # m: the least cloth motion per step the contact region allows for


class BeyondReach(RuntimeError):
    """The cloth moved farther in a step than its contact region reached, and through
    an obstacle left out of it. The model keeps the motion seen (cloth_motion), so the
    step taken again gets a region that reaches that far (sim/recovery.py)."""


def contact_reach(model: Model, state: State, x0: np.ndarray) -> float:
    """How far (m) the cloth may move in this step with the contact region it gets
    (ContactMesh.focus): REACH, or twice the last step's motion or the predictor's, if more.
    A step that moves farther fails and is split (sim/recovery.py)."""
    return max(REACH, 2.0 * model.cloth_motion, 2.0 * _largest_motion(model, state.C, x0))


def _within_reach(model: Model, state: State, path: list, C_new, reach: float, stats: StepStats,
                  newton) -> np.ndarray:
    """C_new, when the cloth stayed within `reach` of where it started. Otherwise obstacle
    triangles beyond reach were left out of the step: with them added, the way the cloth
    went (`path`, minimize's) must be collision free (else BeyondReach: the step is taken
    again with the region widened, see sim/recovery.py), and Newton carries on from C_new
    with every contact it can have."""
    moved = _largest_motion(model, state.C, C_new)
    stats.extra["cloth_motion"] = model.cloth_motion = moved
    if moved <= reach:
        return C_new
    contact = model.barrier.contact
    B_end = contact.obstacle_vertices
    contact.move_obstacles(path[0][1])
    widened = contact.focus(state.C, B_end, 2.0 * moved + model.barrier.dhat)
    # The chord first (one CCD): only when it cuts through an obstacle, the iterates.
    free = not widened or model.potential.max_step(path[0][0], C_new, B_end) >= 1.0 \
        or _went_clear(model.potential, contact, path)
    contact.move_obstacles(B_end)
    if not widened:
        return C_new
    if not free:
        raise BeyondReach(f"the cloth moved {moved:.3g} m in one step, beyond the contact reach of "
                           f"{reach:.3g} m, and through an obstacle left out")
    if model.friction is not None:
        model.friction.lag(state.C)
    return minimize(model.potential, C_new, newton, stats, origin=state.C)


def _went_clear(potential, contact, path: list) -> bool:
    """Whether each segment of `path` [(C, B)] is collision free on the contact mesh as it
    is now. The iterates', not only the chord from the start to the end: Newton's steps go
    round a body the chord cuts through (jumpsuit_04's first gravity step moved the cloth
    41.5 mm, beyond the 30 mm reach; its chord crossed a body triangle left out, its 26
    iterates did not, and the step was taken again for the same 26 iterations)."""
    for (Ca, Ba), (Cb, Bb) in zip(path, path[1:]):
        if Ba is not None:
            contact.move_obstacles(Ba)
        bodies = None if Bb is None or Bb is Ba else Bb
        if Ca is Cb and bodies is None:
            continue
        if potential.max_step(Ca, Cb, bodies) < 1.0:
            return False
    return True


def _largest_motion(model: Model, C0: np.ndarray, C1: np.ndarray) -> float:
    d = model.barrier.contact.W @ (C1 - C0)
    return float(np.sqrt((d * d).sum(axis=1).max(initial=0.0)))
