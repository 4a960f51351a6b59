"""The sewing policy: how seams pull over a run.

Seams stiffen geometrically over the pre-roll (`ramp`) from `ramp_start`: full-strength
springs across 26 cm gaps yank panels shut in one step (kN on grams of cloth), which
costs 100 Newton iterations and CCD-limited steps; weak springs close them over the
pre-roll, and the rising stiffness then holds them below 1 mm. The start is absolute, not
a fraction of k: it is what grams of cloth across open gaps can take.

An open sample whose straight path to its partner passes through a body pulls both sides
to a waypoint beside the body instead (`route`, sim/seams/routes.py). One whose path passes
through another piece's cloth does not pull while the seams stiffen (`screened`): the cloth
between its sides would be pinned there.

Once a matched contact-vertex pair is nearly closed it merges (sim/seams/contact.py); a
pair that cannot merge without cloth passing through cloth is blocked, and where cloth
lies between its sides the samples nearest to it pull with `held_fraction` of the
stiffness (SeamContact.to_hold). A seam sewn onto a folded pleat's face (a waistband),
or a dart across its layers, pulls only once the pleat's tucks are within
`pleat_wait_gap`, or from `pleat_wait_end` (the pre-roll's end) on: pulled earlier, the
other panel comes down into the fold and its layers hold a tuck open, or a layer is
caught between the dart's legs (docs/findings.md, "Folded pleats"). A gathered seam (one
side 1.5x the other or more) waits the same way for the seams of the piece it is
gathered onto that meet it at a corner (a sleeve gathered onto a cuff, for the cuff's
side seam): pulled at once, the gathered cloth's corner hangs into the cuff's open slit
and the side seam closes on it (`_gather_waits`). Once at full stiffness, seam
multipliers close what a penalty leaves open (sim/seams/energy.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..intersect import Triangles
from .energy import SeamEnergy
from .routes import MIN_GAP, junction_waypoints, through_cloth, waypoints
from .spec import SeamSpec, side_length


@dataclass
class SewingOptions:
    """Filled from a scene's [sewing] table and its pre-roll (garment/build.py)."""

    ramp: float = 0.0  # s, the stiffness ramp (0: full stiffness from the start)
    ramp_start: float = 10.0  # N/m^2, stiffness at the ramp's start
    quasistatic: bool = False  # drop velocities after each step of the ramp (and of the pre-roll)
    preroll: float = 0.0  # s: with quasistatic, velocities are dropped up to here too
    multipliers: bool = True  # augmented-Lagrangian multipliers once at full stiffness
    multiplier_step: float = 2.0  # one multiplier update adds at most this many E h
    block_reach: float = 10.0  # d_hat: open pairs closer than this are tested for blocking
    held_fraction: float = 0.01  # of the stiffness, on samples next to a held blocked pair (to_hold)
    pleat_wait_gap: float = 3e-3  # m, tucks this close release a pleat face's seam
    # s, or from this time on; None: the end of the pre-roll (or of the sewing ramp), when
    # the body is whole and the garment must hold together; with neither, only the tucks
    # release it.
    pleat_wait_end: float | None = None
    # Newton iterations per quasi-static sewing step: its steps are a path to the sewn
    # shape, each starting where the last stopped, so none needs to converge. Cloth pressed
    # to a shrunk body between a seam's pull and the barrier (a dress at 3e-6 m) takes
    # 60-100 iterations per step to converge, 0.3 s each on a 10K-DOF jumpsuit. At 20 the
    # sewing phase of the slowest designs was 85 % of their 10 minutes; at 8, dress_02's
    # took 297 s instead of 510 s, with its seams as closed (0.30 mm) by the pre-roll's end.
    iterations: int = 8


class Sewing:
    """The policy for one model's seams. seams: SeamSpec list; energy: their SeamEnergy;
    sample_pair (S,): each sample's nearest matched contact-vertex pair (P: none);
    stiffness: the ramp's end, N/m^2."""

    def __init__(self, seams: list[SeamSpec], energy: SeamEnergy, sample_pair: np.ndarray,
                 stiffness: float, options: SewingOptions, dt: float, C0: np.ndarray | None = None):
        self.seams = seams
        self.energy = energy
        self.sample_pair = sample_pair
        self.stiffness = float(stiffness)
        self.options = options
        counts = [len(s.uv_a) for s in seams]
        self.start = np.cumsum([0] + counts)  # seam k's samples: start[k]:start[k + 1]
        self.faces = self._pleat_faces()
        sides = None if C0 is None else (energy.samples.Na @ C0, energy.samples.Nb @ C0)
        self.junctions = _junctions(seams, self.start, sides)
        if C0 is not None:  # gathered seams wait like a pleat's face (_gather_waits)
            self.faces += _gather_waits(seams, self.start, self.junctions, energy.samples, C0)
        if options.ramp > 0.0:
            energy.set_scale(self.scale(dt))  # the first step's

    @property
    def wait_end(self) -> float:
        """When a waiting seam pulls whatever its pleat's tucks (or its junction) do, s."""
        o = self.options
        if o.pleat_wait_end is not None:
            return o.pleat_wait_end
        return max(o.preroll, o.ramp) or np.inf

    def scale(self, t: float) -> float:
        """Fraction of the full stiffness at time t (the ramp)."""
        o = self.options
        start = min(o.ramp_start / self.stiffness, 1.0)
        return start ** max(1.0 - t / o.ramp, 0.0)

    def ramp(self, t_next: float) -> bool:
        """Stiffen for the step ending at t_next; True when the energy changed."""
        if self.options.ramp > 0.0 and self.energy.scale < 1.0:
            self.energy.set_scale(self.scale(t_next))
            return True
        return False

    def hold(self, C: np.ndarray, t: float, released: np.ndarray, held_pairs: np.ndarray | None,
             screened: np.ndarray | None = None) -> bool:
        """Pull weakly the samples whose nearest matched pair is held (held_pairs (P,)
        bool, None without contact: SeamContact.to_hold), not at all those of seams still waiting for
        their pleat's tucks, nor during the ramp those whose path passes through other
        cloth (screened (S,) bool: `screened`), fully the others. `released` (F,) is
        updated in place. Returns whether the energy changed."""
        held = np.zeros(self.energy.active.size, bool)
        if held_pairs is not None:
            held = np.append(held_pairs, False)[self.sample_pair]
        waiting = self._waiting_samples(C, t, released)
        if screened is not None:
            waiting |= screened
        return self.energy.hold(~held & ~waiting, held & ~waiting)

    def route(self, C: np.ndarray, body_V: np.ndarray, body_F: np.ndarray) -> bool:
        """Send the open samples whose straight path passes through a body (body_V,
        body_F: every obstacle as it stands) round it (sim/seams/routes.py). Returns
        whether the stiffness changed."""
        e = self.energy
        a, b, check = self._open(C)
        routed, points = np.zeros(len(a), bool), np.zeros_like(a)
        if len(check) and len(body_F):
            previous = np.where(e.routed[:, None], e.waypoints, np.nan)
            body = Triangles(body_V, body_F)  # one tree for every path tested this step
            routed[check], points[check] = waypoints(a[check], b[check], body, self._tangents(a)[check],
                                                     previous[check])
            is_open = np.zeros(len(a), bool)
            is_open[check] = True
            groups = [g[is_open[g]] for g in self.junctions]
            junction_waypoints([g for g in groups if len(g) > 1], a, b, routed, points, body, previous)
        if not routed.any() and not e.routed.any():
            return False
        return e.route(routed, points)

    def screened(self, C: np.ndarray, x: np.ndarray, faces: np.ndarray, face_piece: np.ndarray,
                 piece_index: dict[str, int]) -> np.ndarray | None:
        """(S,) bool: during the ramp, open samples whose straight path passes through the
        cloth (contact vertices x, cloth faces of piece face_piece) of a piece other than
        its own two; None at full stiffness. Pulled shut during the ramp, such a seam
        closes round that cloth and pins it between its sides (upper_garment_06's torso
        side seams round its bell sleeves, laid flat between the front and back torso
        panels: every pair blocked, the seams held 2-4 mm open)."""
        if self.energy.scale >= 1.0:
            return None
        # Every open sample, not only the pulled ones: a screened sample is not pulled,
        # and tested only while pulled it was released every other step (jumpsuit_777_03's
        # cuff seam, its path through the other leg's cuff, screened on alternate steps).
        a, b, check = self._open(C, pulled=False)
        out = np.zeros(len(a), bool)
        if len(check):
            own = np.array([[piece_index[s.piece_a], piece_index[s.piece_b]] for s in self.seams])
            pieces = np.repeat(own, np.diff(self.start), axis=0)
            out[check] = through_cloth(a[check], b[check], pieces[check], x, faces, face_piece)
        return out

    def _open(self, C: np.ndarray, pulled: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Both sides of every sample (S, 3) each, and the indices of the samples (pulled
        ones only, unless `pulled` is False) still open by more than MIN_GAP (closing
        seams lie on the cloth: not checked)."""
        e = self.energy
        a, b = e.samples.Na @ C, e.samples.Nb @ C
        wide = np.linalg.norm(a - b, axis=1) > MIN_GAP
        return a, b, np.flatnonzero(e.active & wide if pulled else wide)

    def _tangents(self, a: np.ndarray) -> np.ndarray:
        """(S, 3) each sample's direction along its seam (side a; zero for a seam of one
        sample): central differences of its neighbours, one-sided at the ends."""
        t = np.zeros_like(a)
        for lo, hi in zip(self.start[:-1], self.start[1:]):
            if hi - lo > 1:
                t[lo:hi] = np.gradient(a[lo:hi], axis=0)
        return t

    def after_step(self, C_new: np.ndarray) -> float:
        """Multiplier update at the end of a step; returns the largest seam gap, m."""
        gap = float(self.energy.samples.gaps(C_new).max(initial=0.0))
        if self.options.multipliers and self.energy.scale >= 1.0:
            self.energy.update_multipliers(C_new)
        return gap

    def pulled_shut(self, t_next: float, dt: float) -> bool:
        """Drop velocities after this step: quasi-static sewing during the ramp and the
        rest of the pre-roll. Pulled shut, not thrown: seams closing 30 cm gaps around a
        body would fling the panels onto it, pinning them at 1e-5 m and stalling Newton
        (shirt_mean); a shrunk body growing back pushes the cloth out, not off."""
        o = self.options
        return o.quasistatic and t_next < max(o.ramp, o.preroll) - 1e-9 * dt

    def newton(self, options):
        """Newton's options for a quasi-static sewing step (pulled_shut)."""
        return replace(options, max_iterations=min(options.max_iterations, self.options.iterations))

    def gaps(self, C: np.ndarray) -> dict[str, float]:
        """Largest gap (m) of each seam, by name (seams without one: their index)."""
        gaps, start = self.energy.samples.gaps(C), self.start
        return {s.name or str(k): float(gaps[start[k]:start[k + 1]].max(initial=0.0)) for k, s in enumerate(self.seams)}

    def _pleat_faces(self) -> list[tuple[np.ndarray, list[slice]]]:
        """Per seam that waits for a pleat: its samples on the pleat (within the tucks'
        span of parameters on that piece; a seam may run on past the pleat; a dart of
        the pleated piece itself, all of them) and the tucks' sample ranges."""
        start, seams = self.start, self.seams
        faces = []
        for k, s in enumerate(seams):
            if not s.after:
                continue
            piece = seams[s.after[0]].piece_a
            if s.piece_a == s.piece_b == piece:  # a dart across the pleat's layers: all of it waits
                on = np.ones(len(s.uv_a), bool)
            else:
                tuck_uv = np.concatenate([np.r_[seams[j].uv_a, seams[j].uv_b] for j in s.after])
                lo, hi = tuck_uv.min(axis=0) - 1e-6, tuck_uv.max(axis=0) + 1e-6
                uv = np.asarray(s.uv_a if s.piece_a == piece else s.uv_b, float)
                on = np.all((uv >= lo) & (uv <= hi), axis=1)
            faces.append((start[k] + np.flatnonzero(on), [slice(start[j], start[j + 1]) for j in s.after]))
        return faces

    def _waiting_samples(self, C: np.ndarray, t: float, released: np.ndarray) -> np.ndarray:
        """(S,) bool: samples on a pleat whose tucks have not yet closed to pleat_wait_gap.
        Once they have, the seam pulls for good (`released`, part of the State): without
        the face's pull a small pleat can spring back open and the wait restart."""
        waiting = np.zeros(self.energy.active.size, bool)
        if released.all():
            return waiting
        o = self.options
        gaps = self.energy.samples.gaps(C)
        for k, (samples, tucks) in enumerate(self.faces):
            if released[k]:
                continue
            if t >= self.wait_end or all(gaps[s].max(initial=0.0) <= o.pleat_wait_gap for s in tucks):
                released[k] = True
            else:
                waiting[samples] = True
        return waiting


def _junctions(seams: list[SeamSpec], start: np.ndarray,
               sides: tuple[np.ndarray, np.ndarray] | None = None) -> list[np.ndarray]:
    """Groups (arrays of sample indices, two or more) of samples that share a side point:
    the same parameters on the same piece, where seams meet at a panel corner. With the
    sides' laid-out positions (a, b: (S, 3) each), seam ends on one piece less than JOIN
    apart meet too: conforming drops a seam shorter than the boundary fit
    (conform/seams.py, below_resolution), and the seams on either side of it then end
    about its length apart, not at one point (jumpsuit_00's side dart and armhole meet
    across a 1 mm stitch)."""
    owner: dict[tuple, int] = {}
    parent = np.arange(start[-1])

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    ends = []  # (piece, sample, position) of each seam side's two ends
    for k, s in enumerate(seams):
        for side, (piece, uv) in enumerate(((s.piece_a, s.uv_a), (s.piece_b, s.uv_b))):
            for j, key in enumerate(map(tuple, np.round(np.asarray(uv, float), 9))):
                i = start[k] + j
                other = owner.setdefault((piece, key), i)
                parent[root(i)] = root(other)
            if sides is not None and start[k + 1] > start[k]:
                for i in (start[k], start[k + 1] - 1):
                    ends.append((piece, i, sides[side][i]))
    for n, (piece, i, x) in enumerate(ends):
        for piece_j, j, y in ends[n + 1:]:
            if piece_j == piece and np.linalg.norm(x - y) < JOIN:
                parent[root(i)] = root(j)
    roots = np.array([root(i) for i in range(len(parent))], np.int64)
    _, inverse, counts = np.unique(roots, return_inverse=True, return_counts=True)
    order = np.argsort(inverse, kind="stable")
    groups = np.split(order, np.cumsum(counts)[:-1])
    return [g for g in groups if len(g) > 1]


JOIN = 3e-3  # m: seam ends on one piece this close at layout meet at a corner (_junctions)

GATHER = 1.5  # a seam whose one side is this much longer than the other gathers it


def _gather_waits(seams: list[SeamSpec], start: np.ndarray, junctions: list[np.ndarray], samples,
                  C0: np.ndarray) -> list[tuple[np.ndarray, list[slice]]]:
    """Per gathered seam (one side GATHER x or more longer than the other on the laid-out
    panels C0): its samples, and the seams it waits for (as a pleat's face waits for its
    tucks): those meeting it at a junction that join the gathered-on piece to any piece
    but the gathered one, as a cuff's side seam under a sleeve gathered onto the cuff.
    Pulled at once, the gathered cloth's corner hangs into the cuff's open slit and the
    side seam closes on it (upper_garment_06's right cuff, docs/dressing.md stop 62)."""
    a, b = samples.Na @ C0, samples.Nb @ C0
    seam_of = np.repeat(np.arange(len(seams)), np.diff(start))

    la = np.array([side_length(a[start[k]:start[k + 1]]) for k in range(len(seams))])
    lb = np.array([side_length(b[start[k]:start[k + 1]]) for k in range(len(seams))])
    gathered = (np.diff(start) >= 2) & (np.maximum(la, lb) >= GATHER * np.maximum(np.minimum(la, lb), 1e-9))
    out = []
    for k in np.flatnonzero(gathered):
        s, lo, hi = seams[k], int(start[k]), int(start[k + 1])
        long_piece, short_piece = (s.piece_a, s.piece_b) if la[k] > lb[k] else (s.piece_b, s.piece_a)
        wait = set()
        for g in junctions:
            if lo not in g and hi - 1 not in g:
                continue
            for j in seam_of[g]:  # never on another gathered seam: both would wait to the end
                pieces = {seams[j].piece_a, seams[j].piece_b}
                if not gathered[j] and short_piece in pieces and long_piece not in pieces:
                    wait.add(int(j))
        if wait:
            out.append((np.arange(lo, hi), [slice(int(start[j]), int(start[j + 1])) for j in sorted(wait)]))
    return out
