"""Panels laid inside another seam's closing paths, moved or turned out of them.

Pulled shut, a seam whose straight closing paths pass through a third panel closes round
that cloth and pins it: a sleeve laid with its underarm between the torso's front and
back is sewn into the side seam. Such panels (with what hangs from them) move rigidly out
of the paths by the least move that frees them; one only a far move frees is first turned
in its plane onto its own seams, as a sleeve onto its armhole.
"""

from __future__ import annotations

import numpy as np

from sim.embedding import points_at
from sim.intersect import crossing_pairs

from .groups import hanging, merged, panel_names
from .layout import CLEARANCE, Surface, crossings


def seams_through_cloth(patches, seams, panels=None, surface: Surface | None = None,
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
    surface = surface or Surface.of(patches)
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
    surface = Surface.of(patches)

    def caught(moving: set[str] | None = None) -> set[tuple[str, str]]:  # (seam, panel caught in its paths)
        return {k for k, n in seams_through_cloth(patches, seams, panels, surface, moving).items() if n >= CAUGHT}

    found = caught()
    if not found:
        return {}
    index = {p.name: p for p in patches}
    group_of, names_of = panel_names(patches, panels)
    links = [(group_of[s.patch_a], group_of[s.patch_b]) for s in seams
             if s.patch_a in group_of and s.patch_b in group_of]
    seam_panels = {s.name: {group_of.get(s.patch_a), group_of.get(s.patch_b)} for s in seams}
    axis = np.asarray(body_V, float)[:, :2].mean(axis=0)

    def control_points(group) -> np.ndarray:  # (K, 3) of every patch of the group's panels
        return np.concatenate([index[n].world.reshape(-1, 3) for panel in sorted(group) for n in names_of[panel]])

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
    caught_by = merged([{panel for s, panel in found if s == seam} for seam in sorted({s for s, _ in found})])
    hang = [hanging(g, links, set().union(*(seam_panels[s] for s, panel in found if panel in g)))
            for g in caught_by]
    groups = merged([g if round_axis(control_points(h)) and not round_axis(control_points(g)) else h
                    for g, h in zip(caught_by, hang)])
    before = {k: len(v) for k, v in crossings(patches, body_V, body_F, surface).items()}

    def crosses() -> bool:  # the body or a panel, where it did not
        return any(len(v) > before.get(k, 0) for k, v in crossings(patches, body_V, body_F, surface).items())

    moved: dict[str, float] = {}
    for group in groups:
        if moved:  # an earlier group's move may have freed this one (the other cuff)
            found = caught()
            if not any(panel in group for _, panel in found):
                continue
        names = [n for panel in sorted(group) for n in names_of[panel]]
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
