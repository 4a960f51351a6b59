"""Read GarmentCode sewing patterns (JSON, maria-korosteleva/GarmentCode) as outline panels.

`pattern.panels[name]`: `vertices` (2D, in 1/`properties.units_in_meter` m: cm), `edges`
(a closed loop of `endpoints` [i, j], optional `curvature`: `quadratic` / `cubic` Bezier
with control points relative to the edge - x along it, y along its left normal, both in
edge lengths - or `circle` [radius, large_arc, right] as in SVG), `translation` (3D) and
`rotation` (XYZ Euler angles in degrees, applied as Rz Ry Rx: GarmentCode's convention).
`pattern.stitches`: pairs of {panel, edge}; the two edges are sewn in opposite directions
(both loops run counter-clockwise, so the start of one meets the end of the other), unless
a third entry says "right_wrong": the right side of one panel is sewn to the wrong side of
the other (a collar turned over), so the edges run the same way and start meets start.

Each panel becomes an outline Panel: the edges sampled every `spacing` metres (pattern
vertices kept exactly, as corner hints), its rigid 3D placement, and its exact area
(Green's theorem on the curves), with the area each outline segment misses against its
curve (`segment_bulge`, so pieces of a split panel know their exact areas too).
"""

from __future__ import annotations

import json

import numpy as np

from sim.budget import require_memory
from sim.errors import InputError, printable
from sim.files import input_file
from sim.patches import Panel
from sim.seams.spec import PanelSeam

from ..units import LARGEST_M

_GL_T, _GL_W = np.polynomial.legendre.leggauss(8)


def read_garmentcode(path, spacing: float = 0.003) -> tuple[list[Panel], list[PanelSeam]]:
    """Outline panels (metres) and seams of a GarmentCode pattern file."""
    path = input_file(path)
    try:
        spec = json.loads(path.read_bytes().decode("utf-8"))
        pattern = spec["pattern"]
        panels_spec = pattern["panels"]
        props = spec.get("properties", {})
        units = float(props.get("units_in_meter", 100))
        order = pattern.get("panel_order") or list(panels_spec)
        stitches = pattern.get("stitches", [])
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, AttributeError, ValueError,
            RecursionError) as e:
        raise InputError(f"{path}: not a GarmentCode pattern ({printable(e, 200)})") from None
    for key, value in (("panels", panels_spec), ("panel_order", order), ("stitches", stitches)):
        if not isinstance(value, dict if key == "panels" else list):
            raise InputError(f"{path}: pattern.{key} must be {'an object' if key == 'panels' else 'a list'}")
    if not (np.isfinite(units) and units > 0):  # 0 would divide by zero below
        raise InputError(f"{path}: properties.units_in_meter must be a positive number, got "
                         f"{printable(props.get('units_in_meter'), 40)}")
    scale = 1.0 / units
    if props.get("curvature_coords", "relative") != "relative":
        raise InputError(f"{path}: properties.curvature_coords: only 'relative' is supported")
    panels, curves = [], {}
    samples = 0
    for name in order:
        where = f"{path}: panel {printable(name, 80)}"
        try:
            panel, edge_curves, samples = _panel(name, panels_spec[name], scale, spacing, where, str(path), samples)
        except InputError:
            raise
        except (KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError) as e:
            raise InputError(f"{where}: malformed ({printable(e, 200)})") from None
        panels.append(panel)
        curves[name] = edge_curves
    seams = []
    for s, pair in enumerate(stitches):
        try:
            a, b, *flags = pair
            if len(flags) > 1 or flags and not isinstance(flags[0], str):
                raise ValueError(f"a stitch is two {{panel, edge}} entries and an optional flag, got {len(pair)} entries")
            ca, cb = curves[a["panel"]][int(a["edge"])], curves[b["panel"]][int(b["edge"])]
        except (KeyError, IndexError, TypeError, ValueError, AttributeError, OverflowError) as e:
            raise InputError(f"{path}: pattern.stitches[{s}]: unknown panel or edge ({printable(e, 200)})") from None
        k = max(int(np.ceil(max(ca.length, cb.length) / 0.01)), 2) + 1  # about every cm
        t = np.linspace(0.0, 1.0, k)
        seams.append(PanelSeam(
            name=f"stitch{s}", panel_a=a["panel"], panel_b=b["panel"],
            points_a=ca.at_length_fraction(t),
            points_b=cb.at_length_fraction(t if flags == ["right_wrong"] else 1.0 - t),
        ))
    return panels, seams


# Memory per outline sample while a panel is read (its point, its segment's bulge from 33
# curve points, indices): a knot span typed in metres where millimetres are meant asks
# for hundreds of thousands of samples per panel.
SAMPLE_BYTES = 1000


def _numbers(value, shape: tuple[int, ...], what: str, where: str) -> np.ndarray:
    """`value` as a finite float array of `shape` (-1: any length)."""
    a = np.asarray(value, float)
    if a.ndim != len(shape) or any(n not in (-1, m) for n, m in zip(shape, a.shape)):
        raise InputError(f"{where}: {what} must have shape {shape}, got {a.shape}".replace("-1", "N"))
    if not np.all(np.isfinite(a)):
        raise InputError(f"{where}: {what} holds a non-finite number (NaN or inf)")
    return a


class _Curve:
    """One pattern edge in metres: a line, Bezier or circular arc, p(t) for t in [0, 1]."""

    def __init__(self, kind: str, pts: np.ndarray, arc=None):
        self.kind, self.pts, self.arc = kind, pts, arc
        t = np.linspace(0.0, 1.0, 257)
        d = np.linalg.norm(np.diff(self.at(t), axis=0), axis=1)
        self._t, self._s = t, np.concatenate([[0.0], np.cumsum(d)])
        self.length = float(self._s[-1])

    def at(self, t) -> np.ndarray:
        t = np.asarray(t, float)[:, None]
        p = self.pts
        if self.kind == "circle":
            c, r, a0, da = self.arc
            ang = a0 + da * t[:, 0]
            return c + r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        if len(p) == 2:
            return (1 - t) * p[0] + t * p[1]
        if len(p) == 3:
            return (1 - t) ** 2 * p[0] + 2 * t * (1 - t) * p[1] + t**2 * p[2]
        return (1 - t) ** 3 * p[0] + 3 * t * (1 - t) ** 2 * p[1] + 3 * t**2 * (1 - t) * p[2] + t**3 * p[3]

    def derivative(self, t) -> np.ndarray:
        h = 1e-6
        return (self.at(np.clip(t + h, 0, 1)) - self.at(np.clip(t - h, 0, 1))) / (
            np.clip(t + h, 0, 1) - np.clip(t - h, 0, 1))[:, None]

    def at_length_fraction(self, f) -> np.ndarray:
        return self.at(np.interp(np.asarray(f, float) * self.length, self._s, self._t))

    def bulges(self, f, per_segment: int = 32) -> np.ndarray:
        """Signed areas (m^2) between the curve and its chords from length fraction f[k]
        to f[k + 1], (K - 1,): positive where the curve lies to the right of the chord
        (outwards on a counter-clockwise loop), i.e. what the chord polygon misses."""
        t = np.interp(np.asarray(f, float) * self.length, self._s, self._t)
        sub = t[:-1, None] + (t[1:] - t[:-1])[:, None] * np.linspace(0.0, 1.0, per_segment + 1)[None, :]
        p = self.at(sub.ravel()).reshape(sub.shape[0], per_segment + 1, 2)
        fan = 0.5 * (p[:, :-1, 0] * p[:, 1:, 1] - p[:, 1:, 0] * p[:, :-1, 1]).sum(1)
        chord = 0.5 * (p[:, 0, 0] * p[:, -1, 1] - p[:, -1, 0] * p[:, 0, 1])
        return fan - chord

    def green(self) -> float:
        """Integral of (x dy - y dx) / 2 along the curve (exact for polynomial curves)."""
        t = 0.5 * (_GL_T + 1.0)
        p, dp = self.at(t), self.derivative(t)
        if self.kind == "circle":  # not polynomial: use many points
            t = np.linspace(0.0, 1.0, 2049)
            p = self.at(t)
            return 0.5 * float(np.sum(p[:-1, 0] * p[1:, 1] - p[1:, 0] * p[:-1, 1]))
        return 0.25 * float(np.sum(_GL_W * (p[:, 0] * dp[:, 1] - p[:, 1] * dp[:, 0])))


def _rel_to_abs(a, b, rel):
    e = b - a
    return a + rel[0] * e + rel[1] * np.array([-e[1], e[0]])


def _edge_curve(a, b, curvature, where: str, scale: float) -> _Curve:
    """The edge from a to b (m); a circle's radius is in pattern units, times `scale`."""
    if not curvature:
        return _Curve("line", np.array([a, b]))
    if isinstance(curvature, (list, tuple)):  # old format: one quadratic control point
        curvature = {"type": "quadratic", "params": [curvature]}
    kind, params = curvature["type"], curvature["params"]
    if kind == "quadratic":
        return _Curve(kind, np.array([a, _rel_to_abs(a, b, _numbers(params[0], (2,), "curvature", where)), b]))
    if kind == "cubic":
        c0, c1 = (_numbers(p, (2,), "curvature", where) for p in params[:2])
        return _Curve(kind, np.array([a, _rel_to_abs(a, b, c0), _rel_to_abs(a, b, c1), b]))
    if kind == "circle":
        radius, large, right = float(_numbers(params[0], (), "circle radius", where)) * scale, bool(params[1]), \
            bool(params[2])
        if not radius > 0 or np.allclose(a, b):
            raise InputError(f"{where}: a circle edge needs a positive radius and two distinct ends")
        L = float(np.linalg.norm(b - a))
        h = np.sqrt(max(radius**2 - L**2 / 4.0, 0.0))
        cy = (radius + h if large else radius - h) / L * (-1.0 if right else 1.0)
        mid = _rel_to_abs(a, b, [0.5, cy])
        centre = _circumcentre(a, mid, b)
        a0 = np.arctan2(*(a - centre)[::-1])
        am = np.arctan2(*(mid - centre)[::-1])
        a1 = np.arctan2(*(b - centre)[::-1])
        # Sweep from a through mid to b.
        d1 = (am - a0) % (2 * np.pi)
        d2 = (a1 - a0) % (2 * np.pi)
        da = d2 if d1 <= d2 else d2 - 2 * np.pi
        return _Curve(kind, np.array([a, b]), (centre, radius, a0, da))
    raise InputError(f"{where}: unsupported curvature type {kind!r}")


def _circumcentre(a, b, c):
    d = 2 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    ux = ((a @ a) * (b[1] - c[1]) + (b @ b) * (c[1] - a[1]) + (c @ c) * (a[1] - b[1])) / d
    uy = ((a @ a) * (c[0] - b[0]) + (b @ b) * (a[0] - c[0]) + (c @ c) * (b[0] - a[0])) / d
    return np.array([ux, uy])


def euler_xyz(degrees) -> np.ndarray:
    """GarmentCode's rotation: R = Rz Ry Rx of XYZ Euler angles in degrees."""
    x, y, z = np.deg2rad(np.asarray(degrees, float))
    Rx = np.array([[1, 0, 0], [0, np.cos(x), -np.sin(x)], [0, np.sin(x), np.cos(x)]])
    Ry = np.array([[np.cos(y), 0, np.sin(y)], [0, 1, 0], [-np.sin(y), 0, np.cos(y)]])
    Rz = np.array([[np.cos(z), -np.sin(z), 0], [np.sin(z), np.cos(z), 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _panel(name, spec, scale, spacing, where, source, samples: int) -> tuple[Panel, list[_Curve], int]:
    """The panel, its edge curves and the outline samples read so far (with its own)."""
    V = _numbers(spec["vertices"], (-1, 2), "vertices", where) * scale
    edges = spec["edges"]
    if len(edges) < 2:
        raise InputError(f"{where}: needs at least 2 edges, got {len(edges)}")
    ends = []
    for k, e in enumerate(edges):
        i, j = e["endpoints"]
        if not all(isinstance(x, int) and 0 <= x < len(V) for x in (i, j)):
            raise InputError(f"{where}: edges[{k}].endpoints {printable([i, j], 60)} must be vertex indices "
                             f"0 to {len(V) - 1}")
        ends.append((i, j))
    for k, (i, j) in enumerate(ends):
        if j != ends[(k + 1) % len(ends)][0]:
            raise InputError(f"{where}: edges {k} and {(k + 1) % len(edges)} do not join: the outline is not a loop")
    with np.errstate(all="ignore"):  # a degenerate curve is reported below, not warned about
        curves = [_edge_curve(V[i], V[j], e.get("curvature"), where, scale) for (i, j), e in zip(ends, edges)]
    lengths = np.array([c.length for c in curves])
    if not np.all(np.isfinite(lengths)):
        raise InputError(f"{where}: edge {int(np.flatnonzero(~np.isfinite(lengths))[0])} is degenerate")
    extent = float(np.ptp(np.concatenate([c.at(np.linspace(0.0, 1.0, 33)) for c in curves]), axis=0).max())
    if extent > LARGEST_M:
        raise InputError(f"{where}: the panel is {extent:.3g} m across; check properties.units_in_meter "
                         f"({1.0 / scale:g}: the vertices are in 1/{1.0 / scale:g} m)")
    counts = [max(int(np.ceil(c.length / spacing)), 1 if c.kind == "line" else 4) for c in curves]
    samples += sum(counts)
    require_memory(SAMPLE_BYTES * samples, f"{where}: sampling the outlines every {spacing * 1e3:.3g} mm "
                   f"({samples} points so far)", "raise the knot span (outlines are sampled at a sixth of it)")
    pts, seg_edge, hints, bulge = [], [], [], []
    for k, (c, count) in enumerate(zip(curves, counts)):
        hints.append(sum(len(p) for p in pts))
        pts.append(c.at_length_fraction(np.arange(count) / count))
        seg_edge += [k] * count
        bulge.append(np.zeros(count) if c.kind == "line" else c.bulges(np.arange(count + 1) / count))
    rest = np.concatenate(pts)
    seg_edge = np.asarray(seg_edge)
    bulge = np.concatenate(bulge)
    hints = np.asarray(hints)
    area = sum(c.green() for c in curves)
    if area < 0:  # GarmentCode normalises loops to counter-clockwise; accept the other way
        rest, seg_edge, bulge = rest[::-1], seg_edge[::-1], -bulge[::-1]
        rest = np.roll(rest, 1, axis=0)
        hints = (rest.shape[0] - hints) % rest.shape[0]
        area = -area
    T = np.eye(4)
    T[:3, :3] = euler_xyz(_numbers(spec.get("rotation", [0, 0, 0]), (3,), "rotation", where))
    T[:3, 3] = _numbers(spec.get("translation", [0, 0, 0]), (3,), "translation", where) * scale
    panel = Panel(name=name, source=source, rest=rest, transform=T, corner_hints=np.sort(hints),
                  segment_edges=seg_edge, area=float(area), segment_bulge=bulge)
    return panel, curves, samples
