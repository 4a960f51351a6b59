"""Step splitting: a time step whose Newton solve fails is retried as two half steps,
recursively, down to a floor; only then does the run stop, with a diagnosis.

A solve fails when Newton hits its iteration cap, the line search stalls before the
tolerance is met, the result is not finite, or the linear algebra raises. Halving dt
shrinks the motion per step (CCD, line search and the inertia-dominated Hessian all
behave better), which rescues most transient failures: a fast impact, a body
accelerating, a stiff contact forming.
"""

from __future__ import annotations

import math
import warnings
from typing import Callable

import numpy as np
from sksparse.cholmod import CholmodError

from sim.errors import SimulationError

from .newton import Interrupted
from .stats import StepStats
from .stepper import BeyondReach

# Numerical failures worth a retry; anything else is a bug and keeps its traceback.
# MemoryError: ipctk's broad phase throws std::bad_alloc when a step's motion makes every
# box overlap every other (a demo step at t = 1.24 s); half the motion needs far less.
RECOVERABLE = (ArithmeticError, np.linalg.LinAlgError, CholmodError, ValueError, RuntimeError, MemoryError)
DEFAULT_SPLITS = 4  # floor = dt / 2^4
# A body closer to its pose than this (in d_hat) is there: the drive stops bodies a hair
# short of cloth (barrier.DRIVE_FLOOR, 1e-9 m), so a step can end with a lag of that
# size while Newton fails for another reason. The 61K-DOF dress's hand-over (stop 87)
# was reported as a body 6.9e-10 m behind its pose, "cloth trapped against it"; its trace
# showed the body at its pose after 20 iterations of the whole step, and Newton
# 0.02-0.04 m/s from the 0.01 m/s tolerance for the other 80.
LAG_NOTICE = 1e-3


class StepFailure(Exception):
    """A step failed at the floor; `cause` is a sentence for the user."""

    def __init__(self, time: float, cause: str):
        self.time, self.cause = time, cause
        super().__init__(f"t = {time:.6g} s: {cause}")


class SplitWarning(UserWarning):
    """A step was retried as two half steps."""


def step_with_recovery(sim, floor: float | None = None,
                       on_warning: Callable[[str], None] | None = None,
                       should_stop: Callable[[], bool] | None = None) -> list[StepStats]:
    """Advance `sim` by one step of its dt; returns the stats of the (sub)steps taken.

    floor: smallest time step tried (default dt / 2^DEFAULT_SPLITS). Raises StepFailure
    with `sim` restored to the state before the step when even steps of `floor` fail.
    Warnings go to `on_warning`, or through `warnings.warn` (SplitWarning) when None.
    should_stop: asked before every retry and sub-step and every Newton iteration (one
    step of a garment pressed to a body can take minutes); when true, raises Interrupted
    with `sim` restored to the state before the step.
    """
    dt = sim.dt
    floor = dt / 2**DEFAULT_SPLITS if floor is None else floor
    start = sim.state.copy()
    warn = on_warning or (lambda msg: warnings.warn(msg, SplitWarning, stacklevel=3))
    potential = sim.model.potential
    potential.should_stop = should_stop
    try:
        stats = _advance(sim, dt, floor, warn, should_stop or (lambda: False))
    except (StepFailure, Interrupted):
        sim.state = start  # (dt is back: _advance restores it on the way out)
        raise
    finally:
        potential.should_stop = None
    # Two halves add up to dt only to round-off: keep the time grid of unsplit runs.
    if len(stats) > 1:
        sim.state.t = start.t + dt
    return stats


def _advance(sim, dt: float, floor: float, warn, stop, sub: bool = False, again: bool = True) -> list[StepStats]:
    if sub and stop():  # the caller asked before the whole step; sub-steps ask again
        raise Interrupted(f"stopped at t = {sim.state.t:.6g} s")
    before = sim.state.copy()
    try:
        st = sim.step()
        problem = failure(sim, st)
    except BeyondReach as e:
        # The contact region was too small for this step's motion (a seam pulling cloth
        # 5 cm in a sewing step): once, the same step again with a region that reaches
        # as far as the cloth moved, which costs one solve where a split costs two.
        sim.state = before
        if again and not stop():
            return _advance(sim, dt, floor, warn, stop, sub, again=False)
        st, problem = None, f"the solver raised {type(e).__name__}: {e}"
    except RECOVERABLE as e:
        st, problem = None, f"the solver raised {type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    if problem is None:
        return [st]
    sim.state = before
    if dt / 2 < floor * (1 - 1e-9):
        raise StepFailure(before.t, diagnose(sim, st, problem, dt))
    warn(f"t = {before.t:.6g} s: {problem}; retrying as two steps of {dt / 2:.3g} s")
    sim.set_dt(dt / 2)
    try:
        return _advance(sim, dt / 2, floor, warn, stop, True) + _advance(sim, dt / 2, floor, warn, stop, True)
    finally:
        sim.set_dt(dt)


def failure(sim, st: StepStats) -> str | None:
    """Why the step just taken is not acceptable, or None."""
    if not (np.isfinite(sim.C).all() and np.isfinite(sim.V).all()):
        return "non-finite positions (NaN or inf)"
    if not math.isfinite(st.energy):
        return "non-finite energy"
    if not st.converged:
        if st.extra.get("pulled_shut"):
            # Quasi-static sewing drops the velocities after every step: the steps are a
            # path to the sewn shape, not a trajectory, and every iterate is collision
            # free with a lower energy. Cloth pressed between a seam's pull and the body
            # can keep Newton from its tolerance for many steps (a dress at 2e-8 m from
            # the body); the next step carries on from here.
            return None
        if st.newton_iterations >= sim.model.newton.max_iterations:
            return (f"Newton hit its iteration cap ({sim.model.newton.max_iterations}; last step "
                    f"{st.residual:.2g} m/s, tolerance {sim.model.newton.tol:g})")
        if st.residual < 10.0 * sim.model.newton.tol:
            return None  # a stall at round-off next to the tolerance: converged in effect
        return f"the line search stalled (residual {st.residual:.2e} m/s, tolerance {sim.model.newton.tol:g})"
    return None


def diagnose(sim, st: StepStats | None, problem: str, dt: float) -> str:
    """The failure plus its most likely cause, from what the last attempt saw."""
    extra = st.extra if st is not None else {}
    if sim.model.barrier is not None and extra.get("body_lag", 0.0) > LAG_NOTICE * sim.model.barrier.dhat:
        cause = (f"an animated body could not reach its pose (it lags {extra['body_lag']:.3g} m behind): "
                 "cloth is trapped against it, or the body moves through or starts inside the garment")
    elif "non-finite" in problem:
        cause = "the time step is likely too large for the material stiffness, or a material value is extreme"
    elif sim.model.barrier is not None and extra.get("min_distance", math.inf) < 1e-3 * sim.model.barrier.dhat:
        cause = ("the cloth is squeezed against an obstacle or itself (closest distance "
                 f"{extra['min_distance']:.2g} m): check for a body starting inside the garment "
                 "or for layers pressed together")
    elif "iteration cap" in problem:
        cause = "the step is too large for this motion: reduce [time].dt or raise [time].max_newton_iterations"
    else:
        cause = "the solve could not make progress: reduce [time].dt or loosen [time].newton_tol"
    return f"{problem} even with time steps of {dt:.3g} s; likely cause: {cause}"


def raise_failure(e: StepFailure, frame: int, checkpoint: str | None) -> None:
    """Turn a StepFailure into the user-facing SimulationError."""
    where = f"; state after frame {frame - 1} saved in {checkpoint}" if checkpoint else ""
    raise SimulationError(f"frame {frame} ({e}){where}") from None
