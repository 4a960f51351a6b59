"""Seams in the contact mesh: matched seam vertices that merge as the seams close.

A sewn piece's mesh carries the matched points of its seams (sim/seams/mesh.py). Each
matched pair that comes within d_hat becomes one contact vertex at the mean of both sides,
pair by pair, as a zipper: the stitched panels then share their seam line, so stitched
neighbours never make a barrier (ipctk never pairs primitives that share a vertex) while
everything else near the seam keeps its barrier.

Contact is never switched off around a seam, so a seam that cannot close without cloth
passing through cloth stays open instead: a nearly closed open pair that could not be
sewn shut right now without cloth passing through cloth or body (a pleat's layer folded
between or against the two sides, a dart's folded neighbours within d_hat / 2) is BLOCKED
until it could (`update_blocked`, every step). The seam energy pulls a blocked pair only
weakly (SewingOptions.held_fraction, sim/seams/sewing.py) where cloth lies between its two
sides, or once they are within HOLD_BELOW of the block reach (`to_hold`): pulling harder
would only press the layers together without bound (dress_knife's knife pleats: contacts
at 40 nm, Newton at its cap down to dt / 16). With nothing between them it pulls fully:
such a merge crosses because the jump to the midpoint sweeps the pair's triangles through
cloth folded nearby (a dart's tip), and the pull closes what the jump could not.
A refused merge is not final either: kept apart for good, a pair refused once while a
layer slid past stayed open after it had gone (dress_knife: seam47 5.4 mm).
"""

from __future__ import annotations

from typing import Callable

import ipctk
import numpy as np
import scipy.sparse as sp

from ..contact.mesh import ContactMesh, cloth_crossings_at, crossing_pairs, crossings_at
from ..intersect import Triangles
from .mesh import mean_rows, merged_faces, merged_labels

OPEN, SEWN, BLOCKED = 0, 1, 3  # states of a matched pair
# Of the block reach: a blocked pair with nothing between its sides is pulled at full
# strength until it is this close, then held weakly (to_hold).
HOLD_BELOW = 0.05
APART = 2  # in checkpoints before refused merges were retried (kept apart for good): read as BLOCKED


class SeamContact:
    """The cloth part of the contact mesh and its seams.

    pieces: sim.simulator.Piece (own W and faces); pairs (P, 2): matched seam vertices
    (global cloth-vertex indices); excluded: cloth vertex pairs (i < j) that never collide
    (seams with no matched vertices, contact.seams = "band"); keep_crossings: exclude the
    cloth crossings of every mesh built from contact (Simulator.keep_crossings)."""

    def __init__(self, pieces, pairs: np.ndarray, excluded: set, obstacles, self_contact: bool,
                 keep_crossings: bool = False):
        self.W_own = sp.vstack([p.W for p in pieces]).tocsr()  # each piece on its own surface
        self.n = self.W_own.shape[0]
        starts = np.cumsum([0] + [p.W.shape[0] for p in pieces])
        self.faces = np.concatenate([p.topology.faces + s for p, s in zip(pieces, starts)])
        self.ids = np.repeat(np.arange(len(pieces)), np.diff(starts))
        self.pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
        self.state = np.zeros(len(self.pairs), np.int8)
        self.labels = np.arange(self.n)  # contact vertex of each cloth vertex
        self.excluded = set(excluded)
        self.obstacles = list(obstacles)
        self.self_contact = self_contact
        self.keep_crossings = keep_crossings

    def gaps(self, C: np.ndarray) -> np.ndarray:
        """(P,) distance between the two sides of every matched pair."""
        x = self.W_own @ C
        return np.linalg.norm(x[self.pairs[:, 0]] - x[self.pairs[:, 1]], axis=1)

    def update_blocked(self, C: np.ndarray, mesh: ContactMesh, reach: float) -> np.ndarray:
        """Block the open pairs less than `reach` apart whose two vertices, moved to their
        midpoint as a merge would, take an edge or triangle through cloth in `mesh` (the
        current one); free the blocked ones for which that no longer holds, however far
        apart they have drifted since. Only nearly closed pairs start a block: a seam
        pulled shut from afar wraps around whatever lies between its sides on the way.
        Returns the (P,) BLOCKED pairs."""
        test = np.flatnonzero(((self.state == OPEN) & (self.gaps(C) < reach)) | (self.state == BLOCKED))
        if len(test):
            x = mesh.vertices(C)
            a, b = self.labels[self.pairs[test]].T
            x[a] = x[b] = 0.5 * (x[a] + x[b])
            same = np.arange(len(x))
            same[b] = a  # as if merged: the two sides' own triangles touch along the seam
            hit = cloth_crossings_at(mesh, x, np.r_[a, b], same)
            self.state[test] = np.where(np.isin(a, hit) | np.isin(b, hit), BLOCKED, OPEN)
        return self.held_open()

    def to_hold(self, C: np.ndarray, mesh: ContactMesh, reach: float) -> np.ndarray:
        """(P,) the BLOCKED pairs the seam pulls only weakly: those with cloth between their
        sides (`_layered`: pulled harder, the seam would press the layer between them
        without bound), and those already within HOLD_BELOW x reach. The others are pulled
        at full strength: their merge crosses because a midpoint jump of a few millimetres
        sweeps their triangles through cloth folded nearby (a dart's own folded tip), and
        nothing stops them closing (dress_knife's seam47 stayed 3.5 mm open, held)."""
        return (self.state == BLOCKED) & (self._layered(C, mesh) | (self.gaps(C) < HOLD_BELOW * reach))

    def _layered(self, C: np.ndarray, mesh: ContactMesh) -> np.ndarray:
        """(P,) blocked pairs whose two sides have cloth between them: the straight segment
        from one side's vertex to the other's passes through a cloth triangle not on
        either vertex (a pleat's layer folded between a tuck's sides)."""
        out = np.zeros(len(self.pairs), bool)
        blocked = np.flatnonzero(self.state == BLOCKED)
        if len(blocked) == 0:
            return out
        x = mesh.vertices(C)
        a, b = self.labels[self.pairs[blocked]].T
        faces = mesh.cloth_faces
        hits = Triangles(x[:mesh.n_cloth], faces).crossed(x[a], x[b])
        if len(hits):
            own = (faces[hits[:, 1]] == a[hits[:, 0], None]).any(axis=1) | \
                  (faces[hits[:, 1]] == b[hits[:, 0], None]).any(axis=1)
            out[blocked[hits[~own, 0]]] = True
        # A layer's edge lying along the segment (a seam's end pair at a pleat's corner)
        # is not a crossing: a pair whose neighbour along the seam (the next or previous
        # pair, its vertices joined to this pair's by mesh edges) is layered is too.
        free = blocked[~out[blocked]]
        pair = np.concatenate([free, free])
        next_to = np.concatenate([free - 1, free + 1])
        keep = (next_to >= 0) & (next_to < len(out))
        pair, next_to = pair[keep], next_to[keep]
        keep = out[next_to]
        pair, next_to = pair[keep], next_to[keep]
        if len(pair) == 0:
            return out
        n = mesh.n_cloth  # edge keys lo * n + hi over the cloth edges (labels are cloth vertices)
        E = mesh.mesh.edges
        E = np.sort(E[(E < n).all(axis=1)], axis=1).astype(np.int64)
        keys = E[:, 0] * n + E[:, 1]
        L = self.labels[self.pairs].astype(np.int64)
        joined = np.ones(len(pair), bool)
        for side in (0, 1):
            u, v = L[pair, side], L[next_to, side]
            joined &= np.isin(np.minimum(u, v) * n + np.maximum(u, v), keys)
        spread = out.copy()
        spread[pair[joined]] = True
        return spread

    def held_open(self) -> np.ndarray:
        """(P,) pairs held open, not merged: BLOCKED (the seam pulls only those in
        `to_hold` weakly)."""
        return self.state == BLOCKED

    def rows(self, mesh: ContactMesh) -> sp.csr_matrix:
        """(n, n_cp) interpolation of every cloth vertex as in `mesh` (built for the current
        state): merged ones at the mean of their class, so the exported meshes share merged
        seam vertices bit for bit."""
        return mesh.W[self.labels]

    def mesh(self, C: np.ndarray, state: np.ndarray, like: ContactMesh | None = None):
        """The contact mesh with the pairs in `state` merged (SEWN); bodies where they are
        in `like`. Returns the mesh and the merge labels."""
        excluded = set(self.excluded)
        labels = merged_labels(self.n, self.pairs[state == SEWN])
        W, faces, ids = self.W_own, self.faces, self.ids
        if (state == SEWN).any():
            W = (mean_rows(labels) @ W).tocsr()
            first = np.full(W.shape[0], -1)
            first[labels[::-1]] = np.arange(self.n)[::-1]
            faces, ids = merged_faces(labels[faces]), ids[first]
            excluded = {(min(i, j), max(i, j)) for i, j in ((labels[a], labels[b]) for a, b in excluded) if i != j}

        def build(excluded) -> ContactMesh:
            mesh = ContactMesh(W, faces, W @ C, self.obstacles, ids, self.self_contact, excluded,
                               body_ids=None if like is None else like.body_ids)
            if like is not None:  # cached contact data expire
                mesh.move_obstacles(like.obstacle_vertices.copy())
                mesh.version = like.version + 1
            return mesh

        mesh = build(excluded)
        x = mesh.vertices(C)
        if self.keep_crossings and ipctk.has_intersections(mesh.mesh, x):
            # A state handed over from a coarser run (garment bench garment --refine): its
            # finer mesh may cross where the coarse one nearly touched; leave those be.
            mesh = build(excluded | crossing_pairs(mesh.mesh, x, mesh.n_cloth))
        return mesh, labels

    def sew(self, C: np.ndarray, barrier, use: Callable[[ContactMesh], None],
            restore: np.ndarray | None = None) -> int:
        """Merge every open pair within d_hat of the barrier (or put back the state
        `restore`, from a checkpoint), installing the new mesh with `use`. Pairs whose
        merge crosses cloth or body are BLOCKED. Returns the pairs newly sewn."""
        old = barrier.contact
        if restore is not None:
            state = restore.astype(np.int8)
            state[state == APART] = BLOCKED
            fresh = (state == SEWN) != (self.state == SEWN)
            if fresh.any():
                mesh, self.labels = self.mesh(C, state, like=old)
                use(mesh)
            self.state = state
            return int(fresh.sum())
        state = self.state.copy()
        state[(state == OPEN) & (self.gaps(C) < barrier.dhat)] = SEWN
        fresh = state != self.state
        if not fresh.any():
            return 0
        for _ in range(3):
            mesh, labels = self.mesh(C, state, like=old)
            x = mesh.vertices(C)
            if ipctk.has_intersections(mesh.mesh, x):
                # Some merged vertex moved through cloth or body: those pairs stay apart.
                first = labels[self.pairs[:, 0]]
                crossing = crossings_at(mesh.mesh, x, mesh.n_cloth, first[fresh & (state == SEWN)])
                bad = fresh & (state == SEWN) & np.isin(first, crossing)
                if bad.any():
                    state[bad] = BLOCKED
                    continue
                if not self.keep_crossings:
                    return 0
                # A handed-over state's own crossings, none at a merged vertex. Refusing
                # the merge for them refused it again on every later step, with two
                # whole-mesh crossing searches each time (bench garment --refine: 4-6 s
                # a step at 16 mm, 14 % of the run, and its seams never merged).
            use(mesh)
            if barrier.min_distance(C) > 0.0:
                break
            use(old)
            return 0
        else:
            return 0
        self.state, self.labels = state, labels
        return int((fresh & (state == SEWN)).sum())  # not the pairs just BLOCKED
