"""Quadrature rules in parametric space (docs/design.md section 3).

A rule is three flat arrays (u, v, w): points and parametric weights over the domain
[0, n-2] x [0, m-2] of an n x m control net. Physical weights multiply w by
|det dX/du| at each point (see rest.py).

- `gauss(n, m, k)`: k x k Gauss-Legendre points on every knot span.
- `reduced_membrane(n, m)`: the paper's reduced rule. Boundary-ring spans: 3x3 at the
  corners, 2 along x 3 across on the sides. Interior region [1, n-3] x [1, m-3]: dual
  cells centred on the knots, alternating 1x2 / 2x1 in a checkerboard, the single point
  on the knot line so that it touches only 2 x 3 control points. Half cells on the
  interior region's edge put their single point on the edge knot line, quarter cells on
  the corner knot, with the clipped extent as weight.
- `span_centres(n, m)`: one point at the centre of every span (the bending rule of the
  paper's reference implementation; N'' is continuous there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_GAUSS = {k: np.polynomial.legendre.leggauss(k) for k in (1, 2, 3)}


@dataclass(frozen=True)
class Rule:
    """Quadrature points (u, v) and parametric weights w, all (Q,)."""

    u: np.ndarray
    v: np.ndarray
    w: np.ndarray

    def __len__(self) -> int:
        return self.u.shape[0]


def gauss_1d(a: float, b: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """k-point Gauss-Legendre points and weights on [a, b]."""
    x, w = _GAUSS[k]
    return 0.5 * (a + b) + 0.5 * (b - a) * x, 0.5 * (b - a) * w


def _tensor(pu, wu, pv, wv):
    U, V = np.meshgrid(pu, pv, indexing="ij")
    return U.ravel(), V.ravel(), np.outer(wu, wv).ravel()


def _combine(parts) -> Rule:
    u, v, w = (np.concatenate([p[i] for p in parts]) for i in range(3))
    return Rule(u, v, w)


def gauss(n: int, m: int, k: int) -> Rule:
    """k x k Gauss points on every span of an n x m control net."""
    parts = []
    for s in range(n - 2):
        pu, wu = gauss_1d(s, s + 1, k)
        for t in range(m - 2):
            pv, wv = gauss_1d(t, t + 1, k)
            parts.append(_tensor(pu, wu, pv, wv))
    return _combine(parts)


def span_centres(n: int, m: int) -> Rule:
    return gauss(n, m, 1)


def reduced_membrane(n: int, m: int) -> Rule:
    """The paper's reduced membrane rule; needs n, m >= 5."""
    if n < 5 or m < 5:
        raise ValueError(f"the reduced rule needs at least 5 x 5 control points, got {n} x {m}")
    su, sv = n - 2, m - 2  # spans per direction
    parts = []

    # Boundary ring: a span is in the ring when it touches the patch boundary.
    for s in range(su):
        for t in range(sv):
            ring_u = s in (0, su - 1)
            ring_v = t in (0, sv - 1)
            if not (ring_u or ring_v):
                continue
            ku = 3 if ring_u else 2  # across a left/right side: 3; along a bottom/top side: 2
            kv = 3 if ring_v else 2
            pu, wu = gauss_1d(s, s + 1, ku)
            pv, wv = gauss_1d(t, t + 1, kv)
            parts.append(_tensor(pu, wu, pv, wv))

    # Interior region [1, su-1] x [1, sv-1]: dual cells centred on knots (k, l).
    lo_u, hi_u, lo_v, hi_v = 1.0, su - 1.0, 1.0, sv - 1.0
    for k in range(1, su):
        a_u, b_u = max(k - 0.5, lo_u), min(k + 0.5, hi_u)
        edge_u = k in (1, su - 1)
        for l in range(1, sv):
            a_v, b_v = max(l - 0.5, lo_v), min(l + 0.5, hi_v)
            edge_v = l in (1, sv - 1)
            if edge_u and edge_v:  # quarter cell: one point on the corner knot
                parts.append(([k], [l], [(b_u - a_u) * (b_v - a_v)]))
                continue
            if edge_u:
                single_u = True  # half cell on a left/right edge: point on that knot line
            elif edge_v:
                single_u = False
            else:
                single_u = (k + l) % 2 == 0  # checkerboard of 1x2 / 2x1
            if single_u:
                pv, wv = gauss_1d(a_v, b_v, 2)
                parts.append(_tensor([k], [b_u - a_u], pv, wv))
            else:
                pu, wu = gauss_1d(a_u, b_u, 2)
                parts.append(_tensor(pu, wu, [l], [b_v - a_v]))
    return _combine(parts)


def membrane_rule(name: str, n: int, m: int) -> Rule:
    return {"reduced": lambda: reduced_membrane(n, m), "gauss2": lambda: gauss(n, m, 2),
            "gauss3": lambda: gauss(n, m, 3)}[name]()


def bending_rule(name: str, n: int, m: int) -> Rule:
    return {"reduced": lambda: span_centres(n, m), "gauss2": lambda: gauss(n, m, 2),
            "gauss3": lambda: gauss(n, m, 3)}[name]()

