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
class _Surface:
    """The patches as one triangle mesh: x = W C of each patch, stacked."""

    owner: np.ndarray  # (V,) patch index of each vertex
    faces: np.ndarray  # (F, 3) into the stacked vertices
    W: list  # per patch: (V_k, n_cp_k) interpolation matrix

    @classmethod
    def of(cls, patches, density: float = 2.0) -> "_Surface":
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
              surface: _Surface | None = None) -> dict[tuple[int, int], np.ndarray]:
    """Which parts cross which: {(a, b): crossing points (K, 3)}, a <= b patch indices, the
    body being -1. An edge of one part passing through a triangle of another counts once."""
    surface = surface or _Surface.of(patches)
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


def touching(patches, panels, surface: _Surface | None = None) -> dict[tuple[int, int], np.ndarray]:
    """Pairs of patches that touch without crossing: {(a, b): points (K, 3)}, sampled
    surface points of two patches closer than TOUCH (GarmentCode lays some panels corner
    to corner, e.g. a godet skirt's inserts). Contact would start at zero distance and
    hold them still. Pieces of one split panel (`panels`: each patch's pattern panel)
    meet along their cuts by design: skipped."""
    surface = surface or _Surface.of(patches)
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
    surface = _Surface.of(patches)
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
    group = dict(zip((p.name for p in patches), panels))
    members: dict[str, list[str]] = {}
    for name, panel in group.items():
        members.setdefault(panel, []).append(name)
    lifted: dict[str, float] = {}
    # Asked once for all seams: a lift changes only the seams of the panels it moves,
    # and those are not lifted again.
    through = seams_through_body(patches, seams, body_V, body_F)
    for s in seams:
        if s.name not in through or s.patch_a not in group or s.patch_b not in group:
            continue
        move = set(members[group[s.patch_a]]) | set(members[group[s.patch_b]])
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


def seams_through_cloth(patches, seams, panels=None, surface: _Surface | None = None,
                        moving: set[str] | None = None) -> dict[tuple[str, str], int]:
    """Seams whose closing paths (straight from each sample to its partner) pass through
    the cloth of a panel other than the seam's own two: {(seam name, that panel): how many
    paths}. Pulled shut, such a seam closes round that cloth and pins it (jumpsuit_00's
    sleeve, laid with its underarm between the torso's front and back, caught in the side
    seam). panels: each patch's pattern panel (default its own name). moving: only what a
    move of these panels can change (their seams' paths, and any path through them)."""
    panels = panels or [p.name for p in patches]
    index = {p.name: k for k, p in enumerate(patches)}
    names = sorted(set(panels))
    group = np.array([names.index(g) for g in panels])
    surface = surface or _Surface.of(patches)
    x, face_panel = surface.vertices(patches), group[surface.owner[surface.faces[:, 0]]]
    ends, owner, sides = [], [], {}  # every seam's far paths at once: one broad phase, not one per seam
    for k, s in enumerate(seams):
        if s.patch_a not in index or s.patch_b not in index:
            continue
        ka, kb = index[s.patch_a], index[s.patch_b]
        sides[k] = {group[ka], group[kb]}
        a, b = points_at(patches[ka].world, s.uv_a), points_at(patches[kb].world, s.uv_b)
        far = np.linalg.norm(b - a, axis=1) > CLEARANCE
        ends.append(np.stack([a[far], b[far]], axis=1).reshape(-1, 3))
        owner.append(np.full(int(far.sum()), k))
    if not ends or not sum(map(len, owner)):
        return {}
    ends, owner = np.concatenate(ends), np.concatenate(owner)
    X, faces, paths = np.concatenate([ends, x]), surface.faces + len(ends), np.arange(len(ends)).reshape(-1, 2)
    if moving is None:
        pairs = crossing_pairs(X, paths, faces)
    else:  # the moving panels' seams through any cloth, the others' through the moving cloth
        moved = {names.index(m) for m in moving}
        mine = np.isin(owner, [k for k, g in sides.items() if g & moved])
        theirs = np.flatnonzero(np.isin(face_panel, list(moved)))
        ours, others = crossing_pairs(X, paths[mine], faces), crossing_pairs(X, paths[~mine], faces[theirs])
        ours[:, 0], others[:, 0] = np.flatnonzero(mine)[ours[:, 0]], np.flatnonzero(~mine)[others[:, 0]]
        others[:, 1] = theirs[others[:, 1]]
        pairs = np.concatenate([ours, others])
    path, hit = pairs[:, 0], face_panel[pairs[:, 1]]
    found: dict[tuple[str, str], int] = {}
    for k, g in set(zip(owner[path].tolist(), hit.tolist())):
        if g not in sides[k]:
            found[(seams[k].name, names[g])] = len(np.unique(path[(owner[path] == k) & (hit == g)]))
    return found


OUT_STEP = 0.02  # m, each round moves a panel caught in a seam's path by this
OUT_MOST = 0.3  # m, in all: a sleeve laid half inside the torso needs its width


def _directions() -> list[np.ndarray]:
    """The six axis directions, then the twelve diagonals between two perpendicular ones
    (a sleeve caught at the side moves up and out, across its arm, not along it)."""
    axes = [sign * e for e in np.eye(3) for sign in (1.0, -1.0)]
    return axes + [(a + b) / np.sqrt(2.0) for i, a in enumerate(axes) for b in axes[i + 1:] if abs(a @ b) < 0.5]


DIRECTIONS = _directions()
CAUGHT = 3  # paths: one or two at a seam's end pass a neighbour's corner where panels meet


def out_of_seam_paths(patches, seams, body_V: np.ndarray, body_F: np.ndarray, panels=None) -> dict[str, float]:
    """Move the panels caught in another seam's closing paths (seams_through_cloth, CAUGHT
    paths or more; panels caught by one seam move together) rigidly out of them: along
    the direction (DIRECTIONS, or straight away from the body's vertical axis) that frees
    them with the least move, a multiple of OUT_STEP up to OUT_MOST, and crosses nothing
    new (the body, other panels, other seams' paths). A sleeve laid with its underarm
    between the torso's front and back moves out and up, its cuff with it. Panels round
    the body's axis (a skirt) and panels no move frees stay where they are
    (`Sewing.screened` holds those seams during the ramp); where only what hangs from the
    caught panels is round the axis (a trouser cuff caught in the other cuff's side seam,
    the rest of the garment hanging from it), the caught panels move alone. Returns each
    moved patch's offset (m)."""
    panels = panels or [p.name for p in patches]
    surface = _Surface.of(patches)

    def caught(moving: set[str] | None = None) -> set[tuple[str, str]]:  # (seam, panel caught in its paths)
        return {k for k, n in seams_through_cloth(patches, seams, panels, surface, moving).items() if n >= CAUGHT}

    found = caught()
    if not found:
        return {}
    index = {p.name: p for p in patches}
    members: dict[str, list[str]] = {}
    for p, panel in zip(patches, panels):
        members.setdefault(panel, []).append(p.name)
    group_of = dict(zip((p.name for p in patches), panels))
    links = [(group_of[s.patch_a], group_of[s.patch_b]) for s in seams
             if s.patch_a in group_of and s.patch_b in group_of]
    seam_panels = {s.name: {group_of.get(s.patch_a), group_of.get(s.patch_b)} for s in seams}
    axis = np.asarray(body_V, float)[:, :2].mean(axis=0)

    def control_points(group) -> np.ndarray:  # (K, 3) of every patch of the group's panels
        return np.concatenate([index[n].world.reshape(-1, 3) for panel in sorted(group) for n in members[panel]])

    def round_axis(points) -> bool:
        # Is the body's axis in the middle half of the points' extent (x and y)? A skirt
        # laid round the trunk has it in its middle; a cuff round one ankle reaches it
        # only with its inner edge.
        low, high = points[:, :2].min(axis=0), points[:, :2].max(axis=0)
        return bool(np.all((0.75 * low + 0.25 * high < axis) & (axis < 0.25 * low + 0.75 * high)))

    # Panels caught by a common seam move together, with what hangs from them (not
    # through the panels of the seams that catch them). What hangs from a trouser cuff
    # caught in the other cuff's side seam is the whole garment but that cuff, round the
    # axis: the cuff moves alone, and its seam to the leg closes the gap.
    caught_by = _merged([{panel for s, panel in found if s == seam} for seam in sorted({s for s, _ in found})])
    hanging = [_hanging(g, links, set().union(*(seam_panels[s] for s, panel in found if panel in g)))
               for g in caught_by]
    groups = _merged([g if round_axis(control_points(h)) and not round_axis(control_points(g)) else h
                      for g, h in zip(caught_by, hanging)])
    before = {k: len(v) for k, v in crossings(patches, body_V, body_F, surface).items()}

    def crosses() -> bool:  # the body or a panel, where it did not
        return any(len(v) > before.get(k, 0) for k, v in crossings(patches, body_V, body_F, surface).items())

    moved: dict[str, float] = {}
    for group in groups:
        if moved:  # an earlier group's move may have freed this one (the other cuff)
            found = caught()
            if not any(panel in group for _, panel in found):
                continue
        names = [n for panel in sorted(group) for n in members[panel]]
        start = {n: index[n].world.copy() for n in names}
        points = control_points(group)
        if round_axis(points):
            # Round the body's axis (a skirt whose flared sides reach into the bodice's side
            # seams): its own seams wrap it round the trunk and out of those paths, and no
            # rigid move frees it without taking it off its seams (dress_04's skirt, moved
            # down 24 or 22 cm diagonally, slid off or stayed 3.8 mm open).
            continue
        radial = np.r_[points[:, :2].mean(axis=0) - axis, 0.0]
        length = np.linalg.norm(radial)
        directions = list(DIRECTIONS)
        if length > 1e-6:  # a panel flat in a plane through the axis has none
            directions.append(radial / length)
        best = _least_move(index, start, directions, group, found, lambda: caught(group), crosses)
        turned = None
        if np.linalg.norm(best) > FAR:
            # So far out, the group's seams to the rest open by as much (upper_garment_777_03's
            # fan sleeve, 28 cm straight out, left its armhole 28 cm open): turned in its own
            # plane onto those seams instead, where that frees it with a shorter move.
            turned = _turned_free(index, start, seams, directions, group, found, caught, crosses)
        if turned is not None and np.linalg.norm(turned[1]) < np.linalg.norm(best) - OUT_STEP:
            for n in names:
                index[n].world = turned[0][n] + turned[1]
            moved.update({n: float(np.linalg.norm(index[n].world - start[n], axis=-1).max()) for n in names})
            continue
        for n in names:
            index[n].world = start[n] + best
        if best.any():
            moved.update({n: float(np.linalg.norm(best)) for n in names})
    return moved


# m, a rigid move beyond which a caught group is turned onto its seams instead, if that
# frees it. The plain moves of the designs that dress are 2-8 cm (sleeves 6-8 cm out of
# the side seams); dress_777_04's sleeves, 20 cm out with their cuffs round the hands,
# held both arms raised in 3 of 5 runs (cuffs round the grown hands).
FAR = 0.1


def _turned_free(index, start, seams, directions, group, found, caught, crosses):
    """(turned control points {name: world}, the least move after the turn) that frees the
    group (nothing of it caught, nothing new caught or crossed), or None. The patches are
    left at `start`."""
    turned = _turned_onto_seams(start, seams, index)
    if turned is None:
        return None
    names = list(start)

    def at(move) -> bool:  # is the group free, turned and moved by `move`?
        for n in names:
            index[n].world = turned[n] + move
        now = caught(group)
        return not (any(panel in group for _, panel in now) or now - found or crosses())

    then = np.zeros(3) if at(np.zeros(3)) else _least_move(index, turned, directions, group, found,
                                                         lambda: caught(group), crosses)
    free = at(then)
    for n in names:
        index[n].world = start[n]
    return (turned, then) if free else None


def _turned_onto_seams(start: dict[str, np.ndarray], seams, index) -> dict[str, np.ndarray] | None:
    """The control points of the patches in `start` (name: world), turned about the normal
    of their common plane and moved in it to fit their seams to the other patches (index:
    name: patch) best (least squares, Kabsch in 2D); None when they share no plane or no
    such seam."""
    normals = [np.linalg.svd(X - X.mean(axis=0), full_matrices=False)[2] for X in
               (w.reshape(-1, 3) for w in start.values())]
    normal = normals[0][2]
    # One plane's normal for all: each patch flat and parallel to the first (a sleeve's front and back).
    flat = all(abs(vt[2] @ normal) > PARALLEL for vt in normals)
    mine, theirs = [], []
    for s in seams:
        if (s.patch_a in start) == (s.patch_b in start) or s.patch_a not in index or s.patch_b not in index:
            continue
        (p, uv_p), (q, uv_q) = ((s.patch_a, s.uv_a), (s.patch_b, s.uv_b))[:: 1 if s.patch_a in start else -1]
        mine.append(points_at(start[p], uv_p))
        theirs.append(points_at(index[q].world, uv_q))
    if not flat or not mine:
        return None
    e1 = normals[0][0]
    e2 = np.cross(normal, e1)

    def plane(X):  # (K, 3) -> (K, 2) in-plane coordinates
        return np.c_[X @ e1, X @ e2]

    P, Q = plane(np.concatenate(mine)), plane(np.concatenate(theirs))
    pc, qc = P.mean(axis=0), Q.mean(axis=0)
    x, y = P - pc, Q - qc
    angle = np.arctan2(np.sum(x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0]), np.sum(x * y))
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    out = {}
    for n, w in start.items():
        X = w.reshape(-1, 3)
        uv = (plane(X) - pc) @ R.T + qc
        out[n] = np.ascontiguousarray((np.outer(X @ normal, normal) + np.outer(uv[:, 0], e1)
                                       + np.outer(uv[:, 1], e2)).reshape(w.shape))
    return out


PARALLEL = 0.99  # |cos| between the normals of panels turned together


def _merged(sets: list[set[str]]) -> list[set[str]]:
    """The sets, those that share a member joined."""
    out: list[set[str]] = []
    for g in sets:
        g = set(g)
        for other in [h for h in out if h & g]:
            out.remove(other)
            g |= other
        out.append(g)
    return out


def _hanging(panels: set[str], links: list[tuple[str, str]], holding: set[str]) -> set[str]:
    """`panels` and every panel sewn to them, through any chain of seams (links: pairs of
    panels) that does not pass through the `holding` panels: a sleeve with its cuff."""
    out, grew = set(panels), True
    while grew:
        grew = False
        for a, b in links:
            for x, y in ((a, b), (b, a)):
                if x in out and y not in out and y not in holding:
                    out.add(y)
                    grew = True
    return out


def _least_move(index, start, directions, group, found, caught, crosses) -> np.ndarray:
    """Of the moves k OUT_STEP d (d in directions, up to OUT_MOST) after which nothing is
    caught that was not (`found`, `caught()`) and `crosses()` is False, the shortest of
    those that leave the fewest seams catching a panel of `group`; zero when no move
    frees any."""
    def catching(now) -> int:
        return len({seam for seam, panel in now if panel in group})

    best, fewest = np.zeros(3), catching(found)
    for k in range(1, int(round(OUT_MOST / OUT_STEP)) + 1):
        for d in directions:
            for n, w in start.items():
                index[n].world = w + k * OUT_STEP * d
            now = caught()
            if catching(now) < fewest and not now - found and not crosses():
                best, fewest = k * OUT_STEP * d, catching(now)
                if fewest == 0:
                    return best
    return best


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
