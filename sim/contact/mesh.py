"""The collision mesh: every cloth's embedded triangle mesh plus obstacles.

Cloth vertices come first (x = W C with the constant interpolation matrix W of all
pieces stacked), obstacle vertices after them; ipctk's static-obstacle filter keeps
obstacles from colliding with each other. Obstacle positions are state: animated bodies
move them (`obstacle_vertices`, see sim/contact/drive.py).
"""

from __future__ import annotations

import ipctk
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree


class ContactMesh:
    """W: (Vc, n_cp) cloth interpolation; cloth_faces (Fc, 3) on cloth vertices; rest
    (Vc, 3) initial cloth vertices; obstacles: list of garment.io.obstacles.ObstacleGeometry.

    Only the obstacle triangles near the cloth take part (`focus`, once per time step): a
    body of 50K triangles under a garment of 5K made every broad phase (collision sets,
    CCD) cost 0.2 s, 70 % of a dressing step, for contacts that can only happen within
    reach of the cloth. `body_ids` are the obstacle vertices in the ipctk mesh (None: all);
    obstacle positions are kept whole (`obstacle_vertices`)."""

    def __init__(self, W: sp.csr_matrix, cloth_faces: np.ndarray, rest: np.ndarray, obstacles=(),
                 piece_ids: np.ndarray | None = None, self_contact: bool = True, excluded=(),
                 body_ids: np.ndarray | None = None):
        """piece_ids: (Vc,) cloth piece of each vertex, needed when self_contact is off;
        excluded: cloth vertex pairs (i < j) that never collide (stitched neighbours);
        body_ids: the obstacle vertices taking part (another mesh's focus; None: all)."""
        self.W = W.tocsr()
        self.n_cloth = W.shape[0]
        self.piece_ids = piece_ids
        self.self_contact, self.excluded = self_contact, excluded
        self.obstacles = list(obstacles)
        self.obstacle_vertices = (np.concatenate([o.at(0.0) for o in self.obstacles])
                                  if self.obstacles else np.zeros((0, 3)))
        self._rest = np.asarray(rest, float)
        # The obstacles' rest shape, for ipctk's rest areas (the barrier's area weights):
        # fixed, so a mesh rebuilt by focus() weighs contacts the same whenever it is
        # rebuilt (a resumed run rebuilds at another moment than the straight one).
        self._obstacle_rest = (np.concatenate([np.asarray(o.vertices, float) for o in self.obstacles])
                               if self.obstacles else np.zeros((0, 3)))
        self.cloth_faces = np.ascontiguousarray(cloth_faces, dtype=np.int32)
        body, offset = [], 0
        for o in self.obstacles:
            body.append(o.faces + offset)
            offset += o.vertices.shape[0]
        self.body_faces = np.concatenate(body).astype(np.int32) if body else np.zeros((0, 3), np.int32)
        self.body_ids = None
        self._spheres = None  # the obstacle triangles' bounding spheres (_triangle_spheres)
        self._build(body_ids)
        self.version = 0  # bumped whenever obstacles move or the mesh changes: cached contact data expire
        # dx_cloth = W3 dC: 3x3-block expansion of W, for mapping gradients and Hessians.
        self.W3 = sp.kron(self.W, sp.identity(3), format="csr")

    def _build(self, body_ids: np.ndarray | None) -> None:
        """The ipctk mesh of the cloth and the obstacle triangles on `body_ids` (None: all)."""
        faces, ids = self.body_faces, None
        if body_ids is not None:
            use = np.zeros(len(self.obstacle_vertices), bool)
            use[body_ids] = True
            faces = faces[use[faces].all(axis=1)]
            ids = np.asarray(body_ids, np.int64)
            local = np.full(len(self.obstacle_vertices), -1, np.int64)
            local[ids] = np.arange(len(ids))
            faces = local[faces]
        self.body_ids = ids
        self.faces = np.ascontiguousarray(np.concatenate([self.cloth_faces, faces + self.n_cloth]), dtype=np.int32)
        edges = ipctk.edges(self.faces)
        V = np.concatenate([self._rest, self.active(self._obstacle_rest)])
        self.mesh = ipctk.CollisionMesh(np.asfortranarray(V), edges, self.faces)
        filters = []
        n_obstacle = V.shape[0] - self.n_cloth
        if not self.self_contact:
            # Pieces collide with each other and with obstacles, never with themselves;
            # obstacles share one label so they never collide with each other.
            labels = np.concatenate([self.piece_ids, np.full(n_obstacle, -1)]).astype(np.int32)
            filters.append(ipctk.make_vertex_patches_filter(labels))
        elif self.obstacles:
            filters.append(ipctk.make_static_obstacle_filter(self.n_cloth))
        if self.excluded:
            filters.append(ipctk.make_sparse_filter({pair: False for pair in self.excluded}, True))
        if filters:
            f = filters[0]
            for other in filters[1:]:
                f = f & other
            self.mesh.can_collide = f

    def focus(self, C: np.ndarray, B1: np.ndarray, reach: float) -> bool:
        """Keep the obstacle triangles that can come within `reach` of the cloth at C while
        the obstacles move from where they are to B1: those whose centroid is within reach
        + the obstacles' largest motion + the cloth's longest edge + the triangle's own
        circumradius of a cloth vertex. Every contact within reach then keeps its whole
        neighbourhood (a body vertex that close has all its triangles kept), so the
        barrier, its area weights and CCD are those of the whole mesh. Returns whether
        the mesh changed."""
        if not len(self.body_faces):
            return False
        B0 = self.obstacle_vertices
        motion = float(np.sqrt(((B1 - B0) ** 2).sum(axis=1).max(initial=0.0)))
        x = self.W @ C
        X = x[self.cloth_faces]
        cloth_edge = float(np.sqrt(((X - np.roll(X, 1, axis=1)) ** 2).sum(axis=2).max(initial=0.0)))
        centre, radius = self._triangle_spheres()
        bound = reach + motion + cloth_edge + radius
        d, _ = cKDTree(x).query(centre, distance_upper_bound=float(bound.max()) * (1 + 1e-9))
        ids = np.unique(self.body_faces[d <= bound])
        if self.body_ids is not None and np.array_equal(ids, self.body_ids):
            return False
        self._build(ids)
        self.version += 1
        return True

    def _triangle_spheres(self) -> tuple[np.ndarray, np.ndarray]:
        """Centroid (Fo, 3) and circumradius bound (Fo,) of every obstacle triangle where
        the obstacles are; computed again only after they moved (a still body: once, not
        every step: 37 ms a step on the 47.5K triangles of the corpus bodies)."""
        if self._spheres is None:
            T = self.obstacle_vertices[self.body_faces]
            centre = T.mean(axis=1)
            self._spheres = centre, np.sqrt(((T - centre[:, None]) ** 2).sum(axis=2)).max(axis=1)
        return self._spheres

    def move_obstacles(self, B: np.ndarray) -> None:
        """Set the obstacle vertices (Vo, 3), all of them. Where they already are (a still
        body, moved onto its target every step), nothing changes and cached contact data
        stay valid."""
        B = np.ascontiguousarray(B, dtype=float)
        if B.shape == self.obstacle_vertices.shape and np.array_equal(B, self.obstacle_vertices):
            return
        self.obstacle_vertices = B
        self._spheres = None
        self.version += 1

    def active(self, B: np.ndarray) -> np.ndarray:
        """Rows of an (all obstacle vertices, ...) array for the obstacle vertices in the mesh."""
        return B if self.body_ids is None else B[self.body_ids]

    @property
    def n_obstacle(self) -> int:
        """Obstacle vertices in the ipctk mesh."""
        return self.mesh.num_vertices - self.n_cloth

    def vertices(self, C: np.ndarray, B: np.ndarray | None = None) -> np.ndarray:
        """(V, 3) Fortran-ordered collision-mesh vertices for control points C (n_cp, 3) and
        obstacle vertices B (all of them; the current ones when None)."""
        B = self.obstacle_vertices if B is None else B
        return np.asfortranarray(np.concatenate([self.W @ C, self.active(B)]))

    def cloth_part(self, v: np.ndarray) -> np.ndarray:
        """Rows of a per-DOF vector (3 V,) that belong to cloth vertices."""
        return v[: 3 * self.n_cloth]

    def obstacle_part(self, v: np.ndarray) -> np.ndarray:
        """(Vo, 3) obstacle-vertex rows of a per-DOF vector (3 V,) (those in the mesh)."""
        return v[3 * self.n_cloth:].reshape(-1, 3)


def _edge_face_crossings(x: np.ndarray, edges: np.ndarray, faces: np.ndarray, skip=None):
    """(edge vertices, triangle vertices) of every edge of `edges` that passes through a
    triangle of `faces` at positions x (V, 3) and shares no vertex with it; skip(E, F)
    -> (n,) bool leaves out more of the broad phase's candidates (E (n, 2), F (n, 3)).
    The candidates are filtered as arrays: per candidate in Python, the filter was half of
    a jumpsuit's sewing step (1M candidates, 3-4 s a step, jumpsuit_00)."""
    if len(edges) == 0 or len(faces) == 0:
        return
    broad = ipctk.LBVH()
    broad.build(np.asfortranarray(x), np.asfortranarray(edges, dtype=np.int32),
                np.asfortranarray(faces, dtype=np.int32), 0.0)
    ids = np.array([(c.edge_id, c.face_id) for c in broad.detect_edge_face_candidates()], np.int64).reshape(-1, 2)
    E, F = edges[ids[:, 0]], faces[ids[:, 1]]
    keep = ~(E[:, :, None] == F[:, None, :]).any(axis=(1, 2))
    if skip is not None:
        keep &= ~skip(E, F)
    for e, f in zip(E[keep], F[keep]):
        if ipctk.is_edge_intersecting_triangle(x[e[0]], x[e[1]], x[f[0]], x[f[1]], x[f[2]]):
            yield e, f


def _crossings(mesh: ipctk.CollisionMesh, x: np.ndarray, n_cloth: int, vertices: np.ndarray | None = None):
    """(edge vertices, triangle vertices) of every edge that passes through a triangle it
    shares no vertex with, at positions x (V, 3), cloth involved (bodies may cross
    themselves); with `vertices`, only those whose edge or triangle has one of them."""
    edges, faces = mesh.edges, mesh.faces

    def bodies(E, F):
        return np.minimum(E.min(axis=1), F.min(axis=1)) >= n_cloth

    if vertices is None:
        yield from _edge_face_crossings(x, edges, faces, bodies)
        return
    mine = np.zeros(len(x), bool)
    mine[vertices] = True
    at_edge = mine[edges].any(axis=1)
    # Edges with one of them against every triangle, then the other edges against the
    # triangles with one: each crossing once, and a broad phase over a few elements.
    yield from _edge_face_crossings(x, edges[at_edge], faces, bodies)
    yield from _edge_face_crossings(x, edges[~at_edge], faces[mine[faces].any(axis=1)], bodies)


def crossing_pairs(mesh: ipctk.CollisionMesh, x: np.ndarray, n_cloth: int) -> set[tuple[int, int]]:
    """Cloth vertex pairs (i < j) of every cloth edge that passes through a cloth triangle
    at positions x (V, 3): the edge's two vertices against the triangle's three."""
    pairs: set[tuple[int, int]] = set()
    for e, f in _crossings(mesh, x, n_cloth):
        if e.max() < n_cloth and f.max() < n_cloth:
            pairs.update((min(a, b), max(a, b)) for a in e.tolist() for b in f.tolist())
    return pairs


def _parts(mesh: ContactMesh) -> np.ndarray:
    """The part of every ipctk mesh vertex: cloth pieces 0, 1, ... (mesh.piece_ids) and
    obstacles -1, -2, ... (in mesh.obstacles' order)."""
    sizes = [o.vertices.shape[0] for o in mesh.obstacles]
    body = mesh.active(np.repeat(-1 - np.arange(len(sizes)), sizes))
    return np.concatenate([np.asarray(mesh.piece_ids), body]).astype(int)


def crossing_parts(mesh: ContactMesh, x: np.ndarray) -> dict[tuple[int, int], int]:
    """Which parts (`_parts`) cross which at positions x (V, 3), and with how many
    edge-triangle crossings. Keys are sorted pairs; a piece crossing itself is (k, k)."""
    part = _parts(mesh)
    counts: dict[tuple[int, int], int] = {}
    for e, f in _crossings(mesh.mesh, x, mesh.n_cloth):
        a, b = sorted((int(part[e[0]]), int(part[f[0]])))
        counts[a, b] = counts.get((a, b), 0) + 1
    return counts


def _touching(mesh: ContactMesh, x: np.ndarray, dhat: float, limit: float):
    """(vertex ids, distance) of every contact closer than `limit` (m) at positions x.
    ipctk hands out its collisions by reference into the set; a wrapper that outlives the
    set is matched by pybind11 to whatever is built later at that address (a segfault),
    so each is read as plain numbers and dropped at once."""
    collisions = ipctk.NormalCollisions()
    collisions.build(mesh.mesh, x, dhat)
    for k in range(len(collisions)):
        c = collisions[k]
        v = [int(i) for i in c.vertex_ids(mesh.mesh.edges, mesh.mesh.faces) if i >= 0]
        d = float(np.sqrt(c.compute_distance(c.dof(x, mesh.mesh.edges, mesh.mesh.faces))))
        del c
        if d < limit:
            yield v, d


def touching_parts(mesh: ContactMesh, x: np.ndarray, dhat: float, limit: float
                   ) -> dict[tuple[int, int], tuple[int, float, np.ndarray]]:
    """Which parts (as in crossing_parts) come closer than `limit` (m) at positions x:
    {(a, b): (contacts, closest distance, where (3,))}."""
    part = _parts(mesh)
    found: dict[tuple[int, int], tuple[int, float, np.ndarray]] = {}
    for v, d in _touching(mesh, x, dhat, limit):
        key = tuple(sorted((int(part[v[0]]), int(part[v[-1]]))))
        n, best, where = found.get(key, (0, np.inf, None))
        found[key] = (n + 1, min(best, d), x[v].mean(axis=0) if d < best else where)
    return found


def touching_vertices(mesh: ContactMesh, x: np.ndarray, dhat: float, limit: float) -> np.ndarray:
    """The contact vertices of every contact closer than `limit` (m) at positions x."""
    return np.unique([i for v, _ in _touching(mesh, x, dhat, limit) for i in v]).astype(np.int64)


def crossings_at(mesh: ipctk.CollisionMesh, x: np.ndarray, n_cloth: int, vertices: np.ndarray) -> np.ndarray:
    """Those of `vertices` on an edge or triangle that crosses another (cloth or body)."""
    hit = set()
    mine = set(np.asarray(vertices).tolist())
    for e, f in _crossings(mesh, x, n_cloth, np.asarray(vertices, np.int64)):
        hit.update(mine.intersection(e.tolist() + f.tolist()))
    return np.array(sorted(hit), np.int64)


def cloth_crossings_at(mesh: ContactMesh, x: np.ndarray, vertices: np.ndarray, same: np.ndarray) -> np.ndarray:
    """Those of `vertices` (moved) on a cloth edge or triangle that crosses a cloth element
    of unmoved vertices at positions x (V, 3), elements whose vertices share a label in
    `same` (V,) not counted (as if those vertices were merged). Moved elements are not
    tested against each other: they stand for alternatives, not one motion (two seams
    closing over each other cross only halfway). Cheap where few vertices moved."""
    moved = np.zeros(len(x), bool)
    moved[vertices] = True
    edges = mesh.mesh.edges[(mesh.mesh.edges < mesh.n_cloth).all(axis=1)]
    faces = mesh.cloth_faces
    edge_moved, face_moved = moved[edges].any(axis=1), moved[faces].any(axis=1)
    hit = set()

    def merged(E, F):  # elements that would share a vertex once the pairs are merged
        return (same[E][:, :, None] == same[F][:, None, :]).any(axis=(1, 2))

    for E, F in ((edges[edge_moved], faces[~face_moved]), (edges[~edge_moved], faces[face_moved])):
        for e, f in _edge_face_crossings(x, E, F, merged):
            hit.update(int(v) for v in (*e, *f) if moved[v])
    return np.array(sorted(hit), np.int64)
