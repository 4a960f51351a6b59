"""Graded knot spans: rest control nets packed towards short seams.

The simulator's knots are uniform in parameter space (sim/bspline.py), but the rest map
X(u, v) decides how much cloth a knot span holds. A short seam - a tuck or a dart leg a
span or two long - folds centimetres of cloth within one or two spans at a uniform
resolution, which a quadratic patch cannot close (docs/findings.md, "Garments"). So the conforming
stage may place the integer parameters closer together in material space near short
seams: a Grading maps the parameter along one direction to the fraction of arc length
along the two sides that run that way.

Span sizes grow linearly with the distance d from a short seam, h(d) = h_seam + GROWTH d,
up to the panel's knot span: equidistributed, neighbouring spans differ by a factor of at
most exp(GROWTH) = RATIO.
A direction is fine

- along a side, near each short seam on it (the spans that cut the seam), and
- across a side, near a side that holds any short seam (the rows parallel to it), since
  a tuck's fold reaches into the panel as well as along its edge.

With no short seam a Grading is uniform and the fits are the chord-length fits of
curve_fit.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RATIO = 1.5  # neighbouring spans differ by at most this factor
GROWTH = float(np.log(RATIO))  # span-size growth per unit distance: h = h0 + G d gives spans in ratio e^G
SHORT = 2.0  # a seam shorter than SHORT knot spans gets seam-sized spans around it
_SAMPLES = 4001  # resolution of the density integral over [0, 1]


@dataclass(frozen=True)
class Grading:
    """Arc-length fractions t (N + 1,) at the integer parameters 0..N of one direction,
    increasing from 0 to 1. At a count n (n - 2 spans, e.g. after knot insertion or an
    adaptive refit) the map is the same curve with the parameter scaled by (n - 2) / N."""

    t: np.ndarray

    @classmethod
    def uniform(cls, spans: int) -> "Grading":
        return cls(np.linspace(0.0, 1.0, spans + 1))

    @property
    def spans(self) -> int:
        return self.t.size - 1

    @property
    def is_uniform(self) -> bool:
        return bool(np.allclose(self.t, np.linspace(0.0, 1.0, self.t.size), rtol=0.0, atol=1e-12))

    def reversed(self) -> "Grading":
        """The same grading seen from the other end (the loop direction of sides 2 and 3)."""
        return Grading(1.0 - self.t[::-1])

    def parameter(self, fraction: np.ndarray, n: int) -> np.ndarray:
        """Parameters in [0, n - 2] of arc-length fractions in [0, 1]."""
        base = np.interp(fraction, self.t, np.arange(self.t.size, dtype=float))
        return base * ((n - 2) / self.spans)

    def fraction(self, u: np.ndarray, n: int) -> np.ndarray:
        """Arc-length fractions of parameters u in [0, n - 2]."""
        base = np.asarray(u, float) * (self.spans / (n - 2))
        return np.interp(base, np.arange(self.t.size, dtype=float), self.t)

    def span(self, u: np.ndarray, n: int, length: float) -> np.ndarray:
        """Span size (metres) at parameters u of an n-point direction whose sides are
        `length` long: length dt/du, linear between span midpoints so MIPS's target has
        no jumps."""
        width = np.diff(self.t)
        base = np.asarray(u, float) * (self.spans / (n - 2))
        mid = np.arange(self.spans) + 0.5
        return length * np.interp(base, mid, width) * (self.spans / (n - 2))


@dataclass(frozen=True)
class Request:
    """A short seam's stretch of one side: side index 0..3 (loop order: v0, u1, v1, u0),
    arc length s0 <= s1 from the side's first corner, and the span wanted there."""

    side: int
    s0: float
    s1: float
    span: float


def density(t: np.ndarray, requests: list[Request], lengths: np.ndarray, direction: int, span: float) -> np.ndarray:
    """Wanted span size as a fraction of the direction's length at fractions t (along u:
    direction 0, sides 0 and 2; along v: direction 1, sides 1 and 3)."""
    along = (0, 2) if direction == 0 else (1, 3)
    L = max(lengths[along[0]], lengths[along[1]])
    mean = 0.5 * (lengths[along[0]] + lengths[along[1]])
    g = np.full_like(t, span / L)
    for r in requests:
        if r.side in along:
            # Along the side; sides 2 and 3 run against the parameter.
            Ls = lengths[r.side]
            s = t * Ls if r.side == along[0] else (1.0 - t) * Ls
            d = np.maximum(np.maximum(r.s0 - s, s - r.s1), 0.0)
            g = np.minimum(g, (r.span + GROWTH * d) / Ls)
        else:
            # Across the side: side 3 (u = 0) or 0 (v = 0) at t = 0, side 1 or 2 at t = 1.
            at_start = r.side == (3 if direction == 0 else 0)
            d = (t if at_start else 1.0 - t) * mean
            g = np.minimum(g, (r.span + GROWTH * d) / mean)
    return g


def grade(requests: list[Request], lengths: np.ndarray, direction: int, span: float, min_spans: int) -> Grading:
    """The grading of one direction: knots equidistributing 1 / density, at least
    min_spans spans; uniform without requests."""
    t = np.linspace(0.0, 1.0, _SAMPLES)
    g = density(t, requests, lengths, direction, span)
    F = np.concatenate([[0.0], np.cumsum(0.5 * (1.0 / g[1:] + 1.0 / g[:-1]) * np.diff(t))])
    N = max(min_spans, int(np.ceil(F[-1] - 1e-9)))
    if not requests:
        return Grading.uniform(N)
    knots = np.interp(np.linspace(0.0, F[-1], N + 1), F, t)
    knots[0], knots[-1] = 0.0, 1.0
    return Grading(knots)
