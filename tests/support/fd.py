"""Finite differences for the derivative tests: one checker for every energy.

An energy is an object with the interface of sim/energies/base.py (`value(C)`,
`add_gradient(C, out)`, and for the analytic Hessian `stencils`, `bind`, `add_hessian`);
a plain function is passed as a callable instead: `x -> value` where a value is
differenced, `x -> gradient` where a gradient is. Every difference is central,

    (f(x + h dx) - f(x - h dx)) / 2h,

so a unit direction dx moves one coordinate (or one coordinate of every point at once,
`unit(x, np.s_[:, k])`) by exactly h. The tests compare with `relerr` or their own
tolerances; this module asserts nothing.

    fd_gradient(e, C, eps)             value -> gradient, coordinate by coordinate
    fd_hessian(e, C, eps)              gradient -> Hessian, column by column
    fd_directional(e, C, d, eps)       both along one direction d: (dE, dg) ~ (g . d, H d)
    central(f, x, dx, h), second_central(f, x, dx, h)   the stencils themselves
"""

from __future__ import annotations

import numpy as np

from sim.assembly import BlockPattern


# ------------------------------------------------------------------ the analytic side


def bound(e, free) -> BlockPattern:
    """Bind the energy to the block pattern of its stencils over `free` (the index map of
    sim/assembly.py: -1 for pinned points), or over all of `free` points when it is a count."""
    free = np.arange(free) if np.isscalar(free) else free
    pattern = BlockPattern.from_stencils(free, e.stencils())
    e.bind(pattern)
    return pattern


def gradient(e, C: np.ndarray) -> np.ndarray:
    """The energy's gradient at C, shaped like C."""
    g = np.zeros_like(C)
    e.add_gradient(C, g)
    return g


def hessian(e, pattern: BlockPattern, C: np.ndarray, project=False) -> np.ndarray:
    """The energy's Hessian at C assembled into `pattern` (free DOFs), as a dense matrix."""
    data = np.zeros(pattern.nnz)
    e.add_hessian(C, data, project=project)
    return pattern.full(data).toarray()


def relerr(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / max |b|: the error of a relative to the reference b."""
    return np.abs(a - b).max() / np.abs(b).max()


def dofs(points, k: int = 3) -> np.ndarray:
    """The DOF indices (k per point, point-major) of `points`."""
    return (k * np.asarray(points)[:, None] + np.arange(k)).ravel()


# ------------------------------------------------------------------ differences


def central(f, x: np.ndarray, dx: np.ndarray, h: float):
    """(f(x + h dx) - f(x - h dx)) / 2h: the derivative of f at x along dx (f's value a
    number or an array)."""
    return (f(x + h * dx) - f(x - h * dx)) / (2 * h)


def second_central(f, x: np.ndarray, dx: np.ndarray, h: float):
    """(f(x + h dx) - 2 f(x) + f(x - h dx)) / h^2: the second derivative of f along dx."""
    return (f(x + h * dx) - 2 * f(x) + f(x - h * dx)) / h**2


def unit(x: np.ndarray, index) -> np.ndarray:
    """A direction shaped like x: 1 at `index` (an entry, or a slice such as
    np.s_[:, k] for component k of every point), 0 elsewhere."""
    d = np.zeros_like(x, dtype=float)
    d[index] = 1.0
    return d


def value_of(f):
    """x -> value: the energy's `value`, or f itself when it is a plain callable."""
    return f.value if hasattr(f, "value") else f


def gradient_of(f):
    """x -> gradient shaped like x: the energy's `add_gradient` into zeros, or f itself
    when it is a plain callable."""
    if hasattr(f, "add_gradient"):
        return lambda C: gradient(f, C)
    return f


def _points(C: np.ndarray, points):
    return range(C.shape[0]) if points is None else points


def fd_gradient(e, C: np.ndarray, eps: float = 1e-6, points=None) -> np.ndarray:
    """Central differences of the value (energy or callable `e`) at C, coordinate by
    coordinate: shaped like C. With `points`, only those rows: (len(points), C.shape[1]),
    to compare with g[points]."""
    value = value_of(e)
    rows = _points(C, points)
    g = np.zeros((len(rows), C.shape[1]))
    for r, i in enumerate(rows):
        for d in range(C.shape[1]):
            g[r, d] = central(value, C, unit(C, (i, d)), eps)
    return g


def fd_hessian(e, C: np.ndarray, eps: float = 1e-6, points=None) -> np.ndarray:
    """Central differences of the gradient (energy, or a callable C -> gradient) at C:
    (C.size, C.size), column k C.shape[1] i + d the gradient's derivative along C[i, d].
    With `points`, only those points' columns: (C.size, k len(points)), to compare with
    H[:, dofs(points)]."""
    grad = gradient_of(e)
    rows = _points(C, points)
    k = C.shape[1]
    H = np.zeros((C.size, k * len(rows)))
    for r, i in enumerate(rows):
        for d in range(k):
            H[:, k * r + d] = central(grad, C, unit(C, (i, d)), eps).ravel()
    return H


def fd_directional(e, C: np.ndarray, d: np.ndarray, eps: float):
    """Central differences along the direction d: (dE, dg), the value's derivative (to
    compare with g . d) and the gradient's, shaped like C (to compare with H d)."""
    return central(value_of(e), C, d, eps), central(gradient_of(e), C, d, eps)
