"""Gathered seams wait for the seams of the piece they are gathered onto
(sim/seams/sewing.py, _gather_waits): a sleeve gathered onto a cuff waits for the cuff's
side seam, and never for another gathered seam."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp

from sim.seams.sewing import Sewing, SewingOptions, _gather_waits, _junctions
from sim.seams.spec import SeamSpec


def line(u0: float, u1: float, k: int = 3) -> np.ndarray:
    """k parameter samples from (u0, 0) to (u1, 0)."""
    return np.c_[np.linspace(u0, u1, k), np.zeros(k)]


def cuff():
    """A sleeve (60 cm edge) and a second sleeve piece (45 cm) gathered onto the back of a
    cuff (30 cm), whose side seam with the cuff's front starts at the gathers' shared
    corner; the sleeves' underarm seam ends there too. Each sample's sides are laid out
    along x at their pattern lengths."""
    seams = [
        SeamSpec("sleeve", line(0, 1), "cuff_b", line(0, 1), "gather"),
        SeamSpec("cuff_f", line(0, 1), "cuff_b", np.c_[np.zeros(3), np.linspace(0, 1, 3)], "side"),
        SeamSpec("sleeve", np.c_[np.zeros(3), np.linspace(0, 1, 3)], "sleeve2", line(0, 1), "underarm"),
        SeamSpec("sleeve2", line(0, 1), "cuff_b", line(0, 1), "second gather"),
    ]
    lengths = {"gather": (0.6, 0.3), "side": (0.1, 0.1), "underarm": (0.2, 0.2), "second gather": (0.45, 0.3)}
    a = np.concatenate([np.c_[np.linspace(0, lengths[s.name][0], 3), np.zeros((3, 2))] for s in seams])
    b = np.concatenate([np.c_[np.linspace(0, lengths[s.name][1], 3), np.ones((3, 2))] for s in seams])
    C0 = np.concatenate([a, b])
    n = len(a)
    samples = SimpleNamespace(Na=sp.eye(n, 2 * n, format="csr"), Nb=sp.eye(n, 2 * n, k=n, format="csr"))
    start = np.arange(0, 3 * len(seams) + 1, 3)
    return seams, start, samples, C0


def test_a_gathered_seam_waits_for_the_side_seam_of_the_piece_it_is_gathered_onto():
    seams, start, samples, C0 = cuff()
    waits = _gather_waits(seams, start, _junctions(seams, start), samples, C0)
    side = slice(3, 6)
    # The gather (2x) and the second gather (1.5x) wait for the cuff's side seam only:
    # not for the sleeves' underarm seam (it holds the gathered piece) nor for each other.
    assert [(list(s), w) for s, w in waits] == [([0, 1, 2], [side]), ([9, 10, 11], [side])]


def test_an_even_seam_waits_for_nothing():
    seams, start, samples, C0 = cuff()
    C0 = C0.copy()
    C0[:3, 0] *= 0.45 / 0.6  # the first gather 45 onto 30 cm: still 1.5x, still waits
    assert len(_gather_waits(seams, start, _junctions(seams, start), samples, C0)) == 2
    C0[:3, 0] *= 0.4 / 0.45  # 40 onto 30 cm: eased, not gathered
    C0[9:12, 0] *= 0.4 / 0.45
    assert _gather_waits(seams, start, _junctions(seams, start), samples, C0) == []


def test_seam_ends_a_dropped_stitch_apart_meet_at_a_corner():
    """A sleeve gathered onto a torso's armhole ends 1 mm (laid out) from where the torso's
    side seam ends: conforming dropped the 1 mm stitch between them. The two ends meet, so
    the gather waits for the side seam; 5 mm apart, they are separate corners."""
    seams = [
        SeamSpec("sleeve", line(0, 1), "torso_f", line(0, 1), "armhole"),
        SeamSpec("torso_f", line(1.01, 2), "torso_b", line(0, 1), "side"),
    ]
    start = np.array([0, 3, 6])

    def laid_out(apart: float):
        a = np.r_[np.c_[np.linspace(0, 0.5, 3), np.zeros((3, 2))],  # sleeve: 50 cm
                  np.c_[np.linspace(0.2 + apart, 0.4, 3), np.zeros((3, 2))]]  # torso_f, side
        b = np.r_[np.c_[np.linspace(0, 0.2, 3), np.zeros((3, 2))],  # torso_f: armhole 20 cm
                  np.c_[np.linspace(0, 0.2, 3), np.ones((3, 2))]]  # torso_b
        samples = SimpleNamespace(Na=sp.eye(6, 12, format="csr"), Nb=sp.eye(6, 12, k=6, format="csr"))
        return (a, b), samples, np.r_[a, b]

    assert _junctions(seams, start) == []  # different parameters: no shared point
    sides, samples, C0 = laid_out(1e-3)
    groups = _junctions(seams, start, sides)
    assert [sorted(g) for g in groups] == [[2, 3]]  # the armhole's end and the side seam's start
    assert [(list(s), w) for s, w in _gather_waits(seams, start, groups, samples, C0)] == [([0, 1, 2], [slice(3, 6)])]
    sides, samples, C0 = laid_out(5e-3)
    assert _junctions(seams, start, sides) == []


def test_a_waiting_seam_pulls_at_the_latest_when_the_preroll_ends():
    def end(**options):
        return Sewing.wait_end.fget(SimpleNamespace(options=SewingOptions(**options)))

    assert end(ramp=0.3, preroll=0.6) == 0.6  # the pre-roll's end, not the ramp's
    assert end(ramp=0.3) == 0.3  # a ramp without a pre-roll
    assert end(ramp=0.3, preroll=0.6, pleat_wait_end=0.4) == 0.4  # as the scene says
    assert end() == np.inf  # neither: only the tucks (or the junction) release it
