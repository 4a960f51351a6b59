"""A valid starting layout: panels that cross each other or the (shrunk) body are moved
apart before sewing, rigidly, along their outward normals.

Pattern layouts place flat panels around the body (GarmentCode's `translation` and
`rotation`), and nothing keeps them from crossing: front halves overlap at the centre
line, a waistband sits inside the skirt's top, a hip panel dips into the body. The
simulator refuses such a start (IPC needs an intersection-free state), so crossings are
removed first, the way a tailor lays the pieces out: a panel that crosses the body moves
out along its normal, and of two panels that cross, the outer one moves out. Each move is
a few millimetres; the seams close the extra distance while sewing. What rigid moves cannot
fix (a panel folded through itself, a pair still crossing after the largest allowed move)
is a PlacementError that names the panels and where they cross.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import ipctk
import numpy as np
from scipy.spatial import cKDTree

from sim.embedding import default_resolution, grid_faces, interpolation_matrix, points_at, sample_grid
from sim.errors import InputError
from sim.intersect import Triangles, crossing_pairs
from sim.seams.routes import through

from ..io.arms import find_arms, raised
from .groups import panel_names

STEP = 0.004  # m, a panel's first push along its normal; each further push is one STEP longer
MOST = 0.15  # m, a panel is never moved further than this in all
CLEARANCE = 0.002  # m, panels end at least this far from the body and from each other


class PlacementError(InputError):
    """The pattern's layout cannot be made valid by moving panels (status "placement")."""

    category = "placement"


@dataclass
class Layout:
    """What separate() did: each moved patch's total offset (m), and the rounds it took."""

    moved: dict[str, float] = field(default_factory=dict)
    rounds: int = 0
    lifted: dict[str, float] = field(default_factory=dict)  # lift_over_body, m
    raise_arms: float = 0.0  # arms_out_of_the_way, degrees
    out_of_paths: dict[str, float] = field(default_factory=dict)  # out_of_seam_paths, m
    bent: dict[str, float] = field(default_factory=dict)  # halves.into_own_half, m
    below_resolution: list[str] = field(default_factory=list)  # seams conform dropped (conform/pipeline.py)


@dataclass
class Surface:
    """The patches as one triangle mesh: x = W C of each patch, stacked."""

    owner: np.ndarray  # (V,) patch index of each vertex
    faces: np.ndarray  # (F, 3) into the stacked vertices
    W: list  # per patch: (V_k, n_cp_k) interpolation matrix

    @classmethod
    def of(cls, patches, density: float = 2.0) -> "Surface":
        owner, faces, Ws, offset = [], [], [], 0
        for k, p in enumerate(patches):
            n, m = p.shape
            res = default_resolution(n, m, density)
            u, v = sample_grid(n, m, res)
            Ws.append(interpolation_matrix(u, v, n, m, 0, n * m))
            faces.append(grid_faces(*res) + offset)
            owner.append(np.full(len(u), k))
            offset += len(u)
        return cls(np.concatenate(owner), np.concatenate(faces).astype(np.int32), Ws)

    def vertices(self, patches) -> np.ndarray:
        return np.concatenate([W @ p.world.reshape(-1, 3) for W, p in zip(self.W, patches)])


def crossings(patches, body_V: np.ndarray | None = None, body_F: np.ndarray | None = None,
              surface: Surface | None = None) -> dict[tuple[int, int], np.ndarray]:
    """Which parts cross which: {(a, b): crossing points (K, 3)}, a <= b patch indices, the
    body being -1. An edge of one part passing through a triangle of another counts once."""
    surface = surface or Surface.of(patches)
    x = surface.vertices(patches)
    part = surface.owner
    edges = ipctk.edges(surface.faces)
    # Cloth edges through any triangle, then body edges through cloth triangles: the
    # body's own edge-triangle pairs are never tested.
    E, F = [edges], [surface.faces]
    if body_V is not None:
        body_F = np.asarray(body_F) + len(x)
        part = np.concatenate([part, np.full(len(body_V), -1)])
        x = np.concatenate([x, body_V])
        E, F = [edges, ipctk.edges(body_F)], [np.concatenate([surface.faces, body_F]), surface.faces]
    found: dict[tuple[int, int], list] = {}
    for segments, triangles in zip(E, F):
        pairs = crossing_pairs(x, segments, triangles)
        e, f = segments[pairs[:, 0]], triangles[pairs[:, 1]]
        a, b = part[e[:, 0]], part[f[:, 0]]
        for i, j, middle in zip(np.minimum(a, b), np.maximum(a, b), 0.5 * (x[e[:, 0]] + x[e[:, 1]])):
            found.setdefault((int(i), int(j)), []).append(middle)
    return {k: np.array(v) for k, v in found.items()}


TOUCH = 1e-3  # m: panels closer than this start inside each other's contact barrier


def touching(patches, panels, surface: Surface | None = None) -> dict[tuple[int, int], np.ndarray]:
    """Pairs of patches that touch without crossing: {(a, b): points (K, 3)}, sampled
    surface points of two patches closer than TOUCH (GarmentCode lays some panels corner
    to corner, e.g. a godet skirt's inserts). Contact would start at zero distance and
    hold them still. Pieces of one split panel (`panels`: each patch's pattern panel)
    meet along their cuts by design: skipped."""
    surface = surface or Surface.of(patches)
    x = surface.vertices(patches)
    pairs = cKDTree(x).query_pairs(TOUCH, output_type="ndarray")
    if not len(pairs):
        return {}
    root = np.array(panels)
    a, b = surface.owner[pairs[:, 0]], surface.owner[pairs[:, 1]]
    keep = (a != b) & (root[a] != root[b])
    out: dict[tuple[int, int], list] = {}
    for i, j, (p, q) in zip(a[keep], b[keep], pairs[keep]):
        out.setdefault((int(min(i, j)), int(max(i, j))), []).append(0.5 * (x[p] + x[q]))
    return {k: np.array(v) for k, v in out.items()}


def _middles(patches) -> np.ndarray:
    """(P, 3) the point of each patch's control net at its middle."""
    return np.array([p.world[p.shape[0] // 2, p.shape[1] // 2] for p in patches])


class _Body:
    """Which side of the body's surface points are on. Inside is the generalized winding
    number (Jacobson et al. 2013: the solid angle the surface subtends, over 4 pi), which
    holds for body meshes with holes and for points far from the surface; the normals of
    the nearest triangles do not there (a point 17 cm in front of the knee was behind all
    8 of its nearest triangles on a shrunk leg a few centimetres thick)."""

    def __init__(self, V: np.ndarray, F: np.ndarray):
        T = V[F]
        n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
        # Faces wound clockwise (a negative signed volume) have normals pointing in.
        self.orientation = 1.0 if np.einsum("fd,fd->", T[:, 0], n) >= 0 else -1.0
        self.normals = n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None] * self.orientation
        self.triangles = T
        self.centres = T.mean(1)
        self.tree = cKDTree(self.centres)

    def winding(self, points: np.ndarray) -> np.ndarray:
        """(P,) generalized winding numbers: about 1 inside the body, 0 outside."""
        out = np.empty(len(points))
        for i, p in enumerate(points):
            a, b, c = (self.triangles[:, j] - p for j in range(3))
            la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
            det = np.einsum("fd,fd->f", a, np.cross(b, c))
            div = la * lb * lc + np.einsum("fd,fd->f", a, b) * lc + np.einsum("fd,fd->f", b, c) * la \
                + np.einsum("fd,fd->f", c, a) * lb
            out[i] = self.orientation * np.arctan2(det, div).sum() / (2.0 * np.pi)
        return out

    def inside(self, points: np.ndarray) -> np.ndarray:
        """(P,) points inside the body."""
        return self.winding(points) > 0.5

    def side(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(outward unit normals of the nearest body triangles (P, 3), signed distances
        along them (P,): negative behind them)."""
        idx = self.tree.query(points)[1]
        n = self.normals[idx]
        return n, np.einsum("pd,pd->p", points - self.centres[idx], n)


def outward_normals(patches, body: "_Body | None") -> np.ndarray:
    """(P, 3) unit normal of each patch at its middle, turned to agree with the body's
    outward normal at the closest point (sleeves face away from the arm, a panel sunk into
    the body still faces out)."""
    mids = _middles(patches)
    if body is not None:
        away, _ = body.side(mids)
    else:
        away = mids - mids.mean(0)
    out = np.zeros((len(patches), 3))
    for k, p in enumerate(patches):
        C = p.world
        n, m = p.shape
        nrm = np.cross(C[-1, m // 2] - C[0, m // 2], C[n // 2, -1] - C[n // 2, 0])
        if np.linalg.norm(nrm) < 1e-12:
            nrm = away[k]
        nrm = nrm / max(np.linalg.norm(nrm), 1e-12)
        out[k] = nrm if nrm @ away[k] >= 0 else -nrm
    return out


def _distance_to_body(patches, tree: cKDTree) -> np.ndarray:
    """(P,) mean distance of each patch's control points to the nearest body vertex."""
    return np.array([tree.query(p.world.reshape(-1, 3))[0].mean() for p in patches])


def separate(patches, body_V: np.ndarray | None, body_F: np.ndarray | None, names=None, panels=None) -> Layout:
    """Move patches (their world control points, in place) until none crosses the body or
    another; raise PlacementError naming what still crosses. names: for messages; panels:
    the pattern panel each patch was cut from (default: its own name)."""
    names = names or [p.name for p in patches]
    panels = panels or names
    layout = Layout()
    surface = Surface.of(patches)
    ref = body_V if body_V is not None else np.concatenate([p.world.reshape(-1, 3) for p in patches]).mean(0)[None]
    body = _Body(body_V, body_F) if body_V is not None else None
    normals = outward_normals(patches, body)
    tree = cKDTree(ref)
    offset = np.zeros(len(patches))
    pushes = np.zeros(len(patches), int)
    decided = np.zeros(len(patches), bool)
    body_tree = cKDTree(body_V) if body_V is not None else None
    for layout.rounds in range(int(MOST / STEP) + 1):
        hits = crossings(patches, body_V, body_F, surface)
        for pair, points in touching(patches, panels, surface).items():
            hits.setdefault(pair, points)
        self_hits = {k: v for k, v in hits.items() if k[0] == k[1]}
        if self_hits:
            (k, _), pts = next(iter(self_hits.items()))
            raise PlacementError(f"panel {names[k]} folds through itself ({len(pts)} crossings near "
                                 f"{_where(pts)}): its conformed surface is not a valid start; try another knot span")
        push = np.zeros(len(patches), bool)
        if body is not None:  # a panel wholly inside the body crosses nothing, yet must come out
            inside = body.inside(_middles(patches))
            push |= inside
            hits.update({(-1, int(k)): _middles(patches)[k][None] for k in np.flatnonzero(inside)})
        if not hits and not push.any():
            break
        far = _distance_to_body(patches, tree)
        for (a, b), points in hits.items():
            if a == -1:
                push[b] = True
                if not decided[b]:  # which way is out, judged where it crosses
                    normals[b] = _away_from_body(patches[b], normals[b], points, body_V, body_tree)
                    decided[b] = True
            else:  # the outer of the two layers moves out
                push[a if far[a] > far[b] else b] = True
        stuck = push & (offset >= MOST)
        if stuck.any():
            raise PlacementError(_stuck_message(hits, names, offset))
        for k in np.flatnonzero(push):
            pushes[k] += 1
            d = min(STEP * pushes[k], MOST - offset[k])
            patches[k].world += d * normals[k]
            offset[k] += d
    else:
        raise PlacementError(_stuck_message(crossings(patches, body_V, body_F, surface), names, offset))
    if layout.rounds:  # a clearance beyond the last push, so contact starts apart
        for k in np.flatnonzero(offset):
            patches[k].world += CLEARANCE * normals[k]
            offset[k] += CLEARANCE
    layout.moved = {names[k]: float(offset[k]) for k in np.flatnonzero(offset)}
    return layout


LIFT_STEP = 0.02  # m, each round lifts the panels of a seam whose path crosses the body by this
LIFT_MOST = 0.1  # m, in all: a strap needs a few centimetres to clear a shoulder


def seams_through_body(patches, seams, body_V: np.ndarray, body_F: np.ndarray) -> dict[str, np.ndarray]:
    """Seams whose closing paths (straight from each sample to its partner) pass through
    the body: {seam name: the crossing paths' midpoints (K, 3)}. Pulled shut, such a seam
    presses its panels into the body (a shoulder strap laid in front of the shoulder and
    its back partner behind it)."""
    index = {p.name: p for p in patches}
    body = Triangles(body_V, body_F)
    found: dict[str, np.ndarray] = {}
    for s in seams:
        if s.patch_a not in index or s.patch_b not in index:
            continue
        a, b = points_at(index[s.patch_a].world, s.uv_a), points_at(index[s.patch_b].world, s.uv_b)
        far = np.linalg.norm(b - a, axis=1) > CLEARANCE
        hit = through(a[far], b[far], body)
        if hit.any():
            found[s.name] = np.unique(0.5 * (a[far][hit] + b[far][hit]), axis=0)
    return found


def lift_over_body(patches, seams, body_V: np.ndarray, body_F: np.ndarray, panels=None,
                   up=(0.0, 0.0, 1.0)) -> dict[str, float]:
    """Lift (rigidly, along `up`) the panels of each seam whose closing paths pass through
    the body, by the least multiple of LIFT_STEP (at most LIFT_MOST) that takes every path
    over it: straps pulled shut over a shoulder, not into it. A seam that no lift clears
    (an inner leg seam round a thigh) is left as it is. A panel moves with all its pieces
    (`panels`: each patch's pattern panel; default its own name): a piece slid up its own
    plane would overlap the piece below it. The panels' other seams open by the lift and
    close again straight down. Returns each lifted patch's lift (m)."""
    up = np.asarray(up, float)
    panels = panels or [p.name for p in patches]
    index = {p.name: p for p in patches}
    group, names_of = panel_names(patches, panels)
    lifted: dict[str, float] = {}
    # Asked once for all seams: a lift changes only the seams of the panels it moves,
    # and those are not lifted again.
    through = seams_through_body(patches, seams, body_V, body_F)
    for s in seams:
        if s.name not in through or s.patch_a not in group or s.patch_b not in group:
            continue
        move = set(names_of[group[s.patch_a]]) | set(names_of[group[s.patch_b]])
        if move & set(lifted):
            continue  # lifted already for another seam
        start = {n: index[n].world.copy() for n in move}
        for k in range(1, int(round(LIFT_MOST / LIFT_STEP)) + 1):
            for n in move:
                index[n].world = start[n] + k * LIFT_STEP * up
            if not seams_through_body(patches, [s], body_V, body_F):
                lifted.update({n: k * LIFT_STEP for n in move})
                break
        else:
            for n in move:
                index[n].world = start[n]
    return lifted


ARM_ANGLES = (20.0, 40.0, 60.0, 80.0)  # degrees, tried in turn


def arms_out_of_the_way(patches, seams, body_V: np.ndarray, body_F: np.ndarray) -> tuple[float, list]:
    """(angle, arms): the least of ARM_ANGLES (degrees) by which the body's arms, raised
    (garment/io/arms.py), are off every seam's closing path, and those arms (for
    ObstacleGeometry.arms: found once); (0, []) when no path passes through an arm (or
    the body has none found, or no angle clears them). A skirt laid round an A-pose
    body's hips covers the hands, and its side seams close over them."""
    hits = seams_through_body(patches, seams, body_V, body_F)
    arms = find_arms(body_V, body_F) if hits else []
    if not arms:
        return 0.0, []
    on_arm = np.zeros(len(body_V), bool)
    for a in arms:
        on_arm[a.vertices[a.weights > 0.0]] = True

    def on_arms(V, hits) -> bool:  # is the body vertex nearest some crossing an arm's?
        return bool(hits) and bool(on_arm[cKDTree(V).query(np.concatenate(list(hits.values())))[1]].any())

    if not on_arms(body_V, hits):
        return 0.0, []
    for angle in ARM_ANGLES:
        V = raised(body_V, arms, np.radians(angle))
        if not on_arms(V, seams_through_body(patches, seams, V, body_F)):
            return angle, arms
    return 0.0, []


def _away_from_body(patch, normal: np.ndarray, points: np.ndarray, body_V: np.ndarray, tree: cKDTree,
                    reach: float = 0.2) -> np.ndarray:
    """The normal of a panel crossing the body, turned away from the body's bulk near the
    crossings: a flat sleeve panel cutting through an arm leaves on the side where less
    of the arm is (the nearest triangle to its middle may well be the torso's)."""
    sample = points[:: max(1, len(points) // 64)]
    near = np.unique(np.concatenate([np.asarray(i, int) for i in tree.query_ball_point(sample, reach)]))
    if len(near) == 0:
        return normal
    middle = patch.world[patch.shape[0] // 2, patch.shape[1] // 2]
    side = float(np.mean((body_V[near] - middle) @ normal))
    return -normal if side > 0 else normal


def _where(points: np.ndarray) -> str:
    lo, hi = points.min(0), points.max(0)
    return f"({', '.join(f'{a * 100:.0f}..{b * 100:.0f}' for a, b in zip(lo, hi))}) cm"


def _stuck_message(hits, names, offset) -> str:
    def name(k):
        return "the body" if k == -1 else f"panel {names[k]}"

    pairs = sorted(hits.items(), key=lambda kv: -len(kv[1]))[:4]
    where = "; ".join(f"{name(a)} and {name(b)}: {len(p)} crossings at {_where(p)}" for (a, b), p in pairs)
    return (f"the layout stays invalid after moving panels up to {MOST * 100:.0f} cm apart: {where}. Fix the "
            "panels' placement (translation, rotation) in the pattern, or check the body's scale and up axis")
