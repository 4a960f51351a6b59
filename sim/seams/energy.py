"""Seams: matched samples of two patch boundary curves held together by stiff springs.

E = k/2 sum_s w_s |S_a(u_s, v_s) - S_b(u'_s, v'_s)|^2, each side a fixed combination of
control points (S = N C), so E = 1/2 tr(C^T K C) with the constant K = k D^T diag(w) D,
D = N_a - N_b. Quadratic, so its Hessian is precomputed once and is PSD. w_s is the seam
length each sample stands for (rest metres), so k is a stiffness per unit seam length
(N/m^2) and refining the samples does not change the seam. One energy holds every seam.

A penalty rather than welded control points: it works for any pairing of control nets,
pulls separated panels together during the stitching phase (the gap shrinks as the
force k w |gap| meets the cloth's resistance), and keeps them closed after.

A penalty alone leaves the gap at force / k, and eased seams need force: a dart whose
sides differ by 2 mm in 3 cm must squeeze the cloth, and at k = 1e7 N/m^2 the dress_knife
darts stayed 1.9 mm open. Once sewn, each sample also carries a multiplier lambda_s (N/m,
the seam's holding force per unit length; augmented Lagrangian, Nocedal & Wright 17.3):
E += sum_s w_s lambda_s . g_s with g_s = S_a - S_b, and after each step
lambda_s += k_s g_s. The gradient gains the constant D^T (w lambda), the Hessian nothing,
and the gap shrinks by K_cloth / (K_cloth + k) per step towards zero rather than to
force / k. A multiplier grows while its gap still shrinks (by 10 % per step), and once
it stops shrinking above LEVEL_GAP, LEVEL_PUSHES more times that the gap does not give
way to (a push it answers, shrinking by 3 % or more, is free), no more: where contact
blocks a seam (a pleat's folded layers between its edges) pushing without bound would
only press the layers together (dress_knife's waist tucks: Newton at its cap every step,
contacts at 36 nm), while a gap that merely levelled off above 1 mm (jumpsuit_04's
stitch48 at 1.09 mm) needs a few more pushes to close, and pushing every step kept
jumpsuit_02 moving until 3.3 s instead of 1.2. Two kinds of push are free, as the cap
would otherwise stop a seam that is not blocked: one the gap answers (jumpsuit_02's
four-seam waist junction closed 5-10 % a push, spent its cap and rested 1 mm open), and
one at a gap LOADED x wider than it was ever pushed at, a new load (the same junction,
capped while sewing, opened from 0.4 to 0.96 mm as gravity came on; with both free,
0.49 mm). The count starts anew at each new low 3 % below the last (a gap still closing,
if slowly, answered its pushes), when the gap closes and under a new load
(jumpsuit_777_02's back-waist junction, spent while sewn shut and then opened by gravity:
1.005-1.13 mm at rest with none left, 0.86 mm with its count anew). A blocked seam never
closes and makes a new low or a new widest only a few times, so its pushes stay bounded.
And one update adds at most `max_step` to a multiplier (the simulator: twice what the
cloth carries at 100 % strain, 2 E h): the first update (lambda = k g everywhere at once)
would otherwise double the pull on every seam still held open by contact or by a patch
too coarse to follow it (dress_knife at the end of its sewing ramp: 843 samples at 6-20
kN/m, up to 30x E h, and Newton at its cap down to dt / 8); later updates keep adding
while the gap keeps shrinking.

A sample whose straight path passes through a body pulls each side to a waypoint p_s
instead (sim/seams/routes.py): k/2 w_s (|S_a - p_s|^2 + |S_b - p_s|^2), still quadratic.
Its Hessian k w_s (N_a^T N_a + N_b^T N_b) changes only with the set of routed samples;
moving p_s changes only the linear term, so no constant Hessian is re-assembled for it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..energies.quadratic import QuadraticEnergy

LEVEL_GAP = 0.5e-3  # m: a gap that stopped shrinking above this still gets pushed ...
LEVEL_PUSHES = 3  # ... this many times (at most this x max_step more force), no more
HELPED = 0.97  # a levelled gap that shrank below this fraction since the last push gave way to it
LOADED = 1.03  # a levelled gap this much wider than it was ever pushed at is under a new load


@dataclass
class SeamSamples:
    """Matched seam samples: rows of the interpolation matrices of both sides (S x n_cp)
    and their weights (S,) in metres of rest seam length."""

    Na: sp.csr_matrix
    Nb: sp.csr_matrix
    weights: np.ndarray

    def gaps(self, C: np.ndarray) -> np.ndarray:
        """(S,) distances between matched points, m."""
        return np.linalg.norm(self.Na @ C - self.Nb @ C, axis=1)


class SeamEnergy(QuadraticEnergy):
    """stiffness: k in N/m^2, one for all samples or one per sample (S,) (garments sewn
    with different seams)."""

    def __init__(self, samples: SeamSamples, stiffness, max_step=np.inf, held_fraction: float = 0.01):
        """max_step: the largest change of a multiplier per update, N/m (one or one per
        sample); held_fraction: of the stiffness, on held samples (`hold`)."""
        self.samples = samples
        self.held_fraction = float(held_fraction)
        D = (samples.Na - samples.Nb).tocsr()
        self.D = D
        k = np.broadcast_to(np.asarray(stiffness, float), samples.weights.shape)
        self.k = k
        self.max_step = np.broadcast_to(np.asarray(max_step, float), samples.weights.shape)
        self.active = np.ones(D.shape[0], bool)
        self.held = np.zeros(D.shape[0], bool)
        # Samples whose straight path passes through a body pull both sides to a waypoint
        # instead (sim/seams/routes.py): E_s = k_s w_s / 2 (|a - p|^2 + |b - p|^2).
        self.routed = np.zeros(D.shape[0], bool)
        self.waypoints = np.zeros((D.shape[0], 3))
        self._route_linear = np.zeros((D.shape[1], 3))  # -N^T (k w p) of both sides, full stiffness
        self._route_constant = 0.0
        self.K0 = self._stiffness()
        self.K = self.K0
        self.scale = 1.0
        self.multipliers = np.zeros((D.shape[0], 3))  # lambda, N/m per sample
        self.last_gaps = np.full(D.shape[0], np.inf)  # m, at the last multiplier update
        self.level_pushes = np.zeros(D.shape[0], np.int64)  # updates of a gap that stopped shrinking
        self.pushed_gaps = np.zeros(D.shape[0])  # m, the widest a levelled gap was pushed at
        self.low_gaps = np.full(D.shape[0], np.inf)  # m, its low since it last closed or was loaded

    def value(self, C):
        return (super().value(C) + float(np.sum(self._weighted_multipliers() * (self.D @ C)))
                + self.scale * (float(np.sum(self._route_linear * C)) + self._route_constant))

    def add_gradient(self, C, out):
        super().add_gradient(C, out)
        out += self.D.T @ self._weighted_multipliers()
        out += self.scale * self._route_linear

    def _stiffness(self) -> sp.csr_matrix:
        routed = self.active & self.routed
        pull = (self.active & ~routed) + self.held_fraction * self.held  # disjoint (hold)
        K = self.D.T @ sp.diags(self.k * self.samples.weights * pull) @ self.D
        if routed.any():
            r = sp.diags(self.k * self.samples.weights * routed)
            Na, Nb = self.samples.Na, self.samples.Nb
            K = K + Na.T @ r @ Na + Nb.T @ r @ Nb
        return K.tocsr()

    def route(self, routed: np.ndarray, points: np.ndarray) -> bool:
        """Pull the samples in `routed` (S,) bool to `points` (S, 3) from both sides
        rather than straight to each other (sim/seams/routes.py). Returns whether the
        stiffness changed (the caller must then re-assemble constant Hessians); new
        points alone change only the linear term."""
        routed = np.asarray(routed, bool)
        changed = not np.array_equal(routed, self.routed)
        self.routed, self.waypoints = routed, np.asarray(points, float)
        self._route_terms()
        if changed:
            self.multipliers[routed] = 0.0
            self.last_gaps[routed] = np.inf
            self.K0 = self._stiffness()
            self.K = self.K0 * self.scale
        return changed

    def hold(self, active: np.ndarray, held: np.ndarray | None = None) -> bool:
        """Pull the samples in `active` (S,) bool, those in `held` with held_fraction x
        the stiffness only (held open by contact: let go entirely, a held seam drifted
        apart and tore on, dress_knife's seam66 19 mm, while a full pull presses the
        layers between its sides together without bound), the others not at all; multipliers of all but the active start
        again from zero. Returns whether anything changed (the caller must then
        re-assemble constant Hessians, IncrementalPotential.refresh_constant)."""
        active = np.asarray(active, bool)
        held = np.zeros_like(active) if held is None else np.asarray(held, bool) & ~active
        if np.array_equal(active, self.active) and np.array_equal(held, self.held):
            return False
        self.active, self.held = active, held
        self.multipliers[~active] = 0.0
        self.last_gaps[~active] = np.inf
        self.K0 = self._stiffness()
        self.K = self.K0 * self.scale
        self._route_terms()
        return True

    def _route_terms(self) -> None:
        """The routed samples' linear and constant energy terms at full stiffness."""
        r = (self.k * self.samples.weights * (self.routed & self.active))[:, None] * self.waypoints
        self._route_linear = -(self.samples.Na.T @ r + self.samples.Nb.T @ r)
        self._route_constant = float(np.sum(r * self.waypoints))

    def _weighted_multipliers(self) -> np.ndarray:
        return self.samples.weights[:, None] * self.multipliers

    def update_multipliers(self, C: np.ndarray) -> None:
        """lambda += k g at the state C that ended a step, where the gap shrank by 10 %
        since the last update or levelled off above LEVEL_GAP (LEVEL_PUSHES unanswered
        pushes per sample, plus those at a new widest gap; full stiffness only: during
        the ramp the gaps are the sewing's, not the seams' error), by at most max_step."""
        g = self.D @ C
        gaps = np.linalg.norm(g, axis=1)
        shrinking = gaps < 0.9 * self.last_gaps
        # A levelled gap 3 % wider than it was ever pushed at carries a new load (gravity
        # coming on after the sewing): pushed again whatever its count, for free. A blocked
        # seam swinging about one width passes its record only a few times.
        loaded = (self.pushed_gaps > 0) & (gaps > LOADED * self.pushed_gaps)
        # The count starts anew once the gap answered its pushes, if slowly: at each new
        # low HELPED x below the last (still closing) and when it closed (LEVEL_GAP); and
        # under a new load (jumpsuit_777_02's back-waist junction: spent while sewn shut,
        # then opened by gravity; or spent at 1.1 mm and at rest at 1.005 mm). A seam
        # pressed onto the layer between its sides never closes and makes a new low or a
        # new widest only a few times: its pushes stay bounded.
        crept = (gaps < HELPED * self.low_gaps) & (gaps > LEVEL_GAP)
        anew = crept | (gaps <= LEVEL_GAP) | loaded
        self.level_pushes[anew] = 0
        self.low_gaps[anew] = np.inf
        self.low_gaps[crept] = gaps[crept]
        level = ~shrinking & (gaps < 1.1 * self.last_gaps) & (gaps > LEVEL_GAP)
        level &= (self.level_pushes < LEVEL_PUSHES) | loaded
        closing = (shrinking | level) & self.active & ~self.routed
        # Only a push the gap did not answer counts against the cap: a gap that still
        # gives way (below HELPED x the last one) is pushed on until it is under LEVEL_GAP.
        pushed = closing & level
        counted = pushed & (gaps > HELPED * self.last_gaps) & ~loaded
        self.level_pushes[counted] += 1
        self.low_gaps[counted] = np.minimum(self.low_gaps[counted], gaps[counted])
        self.pushed_gaps[pushed] = np.maximum(self.pushed_gaps[pushed], gaps[pushed])
        step = self.k[closing, None] * g[closing]
        size = np.linalg.norm(step, axis=1)
        step *= np.minimum(1.0, self.max_step[closing] / np.maximum(size, 1e-300))[:, None]
        self.multipliers[closing] += step
        self.last_gaps = gaps

    def set_scale(self, scale: float) -> None:
        """Stiffness = scale x the full stiffness (a stitching ramp); the caller must
        re-assemble constant Hessians (IncrementalPotential.refresh_constant)."""
        self.scale = float(scale)
        self.K = self.K0 * self.scale

    def stencils(self):
        """Control points of both sides of each sample (both, even where they cancel in
        D: a routed sample pulls each side on its own)."""
        D = (abs(self.samples.Na) + abs(self.samples.Nb)).tocsr()
        counts = np.diff(D.indptr)
        out = -np.ones((D.shape[0], max(int(counts.max(initial=0)), 1)), np.int64)
        rows = np.repeat(np.arange(D.shape[0]), counts)
        out[rows, np.arange(D.indices.size) - D.indptr[rows]] = D.indices
        return [out]
