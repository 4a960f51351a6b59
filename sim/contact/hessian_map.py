"""Contact Hessian mapped from contact-mesh vertices to control points, in parallel
(docs/design.md section 5, the paper's Algorithm 1).

The barrier Hessian H lives on vertex pairs (u, v) of the embedded mesh, x = W C, so the
control-point Hessian is W^T H W: block (I, J) += W[u, i] W[v, j] H_uv. We accumulate it
straight into the fixed lower-triangular block pattern (sim/assembly.py), with no triplets
and no sorting:

- Vertices with the same support (the control points of one knot span) form a spatial
  block; blocks are coloured so that two blocks of one colour share no control point.
- The vertex Hessian is regrouped per call by one "owner" vertex of each pair; a
  colour's blocks then run in parallel, each writing only pattern blocks whose row (or
  column) control point it owns: no write conflicts, no atomics.
- Control-point pairs outside the pattern (distant self-contact) are summed and moved to
  the diagonal as |H_ij| on both rows, exactly as assembly.add_dof_matrix does.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit, prange

from ..assembly import BlockPattern


class ContactHessianMap:
    """Maps vertex-level contact Hessians onto `pattern` through the constant W.

    W: (Vc, n_cp) cloth interpolation (x_cloth = W C); pattern: the solver's BlockPattern
    (its `free` map says which control points are unknowns). Built once per pattern.
    """

    def __init__(self, W: sp.spmatrix, pattern: BlockPattern):
        W = sp.csr_matrix(W, copy=True)
        W.eliminate_zeros()
        W.sort_indices()
        self.pattern = pattern
        self.n_cloth = W.shape[0]
        counts = np.diff(W.indptr)
        K = max(int(counts.max()) if counts.size else 1, 1)
        rows = np.repeat(np.arange(self.n_cloth), counts)
        slot = np.arange(W.indices.size) - W.indptr[rows]
        sup = -np.ones((self.n_cloth, K), np.int64)
        sup[rows, slot] = W.indices
        self.sup_w = np.zeros((self.n_cloth, K))
        self.sup_w[rows, slot] = W.data
        # Free index of each support entry; -1 for pinned points and padding.
        self.sup_free = np.where(sup >= 0, pattern.free[np.maximum(sup, 0)], -1).astype(np.int64)
        # Spatial blocks: vertices with identical support sets.
        _, group = np.unique(sup, axis=0, return_inverse=True)
        group = group.ravel()
        n_groups = int(group.max()) + 1 if group.size else 0
        self.gverts = np.argsort(group, kind="stable").astype(np.int64)
        self.gptr = np.concatenate([[0], np.cumsum(np.bincount(group, minlength=n_groups))]).astype(np.int64)
        gsup = sup[self.gverts[self.gptr[:-1]]] if n_groups else sup[:0]
        color = _greedy_colors(gsup, W.shape[1])
        n_colors = int(color.max()) + 1 if color.size else 0
        self.n_colors = n_colors
        self.color_groups = np.argsort(color, kind="stable").astype(np.int64)
        self.color_ptr = np.concatenate([[0], np.cumsum(np.bincount(color, minlength=n_colors))]).astype(np.int64)
        self.n_groups = n_groups
        # Pattern lookup: the blocks of column J are colstart[J]:colstart[J+1], rows sorted.
        self.colstart = np.searchsorted(pattern.cols, np.arange(pattern.n_free + 1)).astype(np.int64)
        self.rows = pattern.rows.astype(np.int64)
        self.pos = pattern.pos.astype(np.int64)
        n = pattern.n_free
        dblk = pattern.lookup(np.arange(n), np.arange(n))
        idx = np.arange(3 * n)
        self.diag_pos = pattern.pos[dblk[idx // 3], idx % 3, idx % 3].astype(np.int64)
        self.moved_entries = 0

    def add(self, H: sp.spmatrix, data: np.ndarray) -> int:
        """Add W^T H W (free control points, lower triangle) into pattern `data`.

        H: symmetric (3V, 3V) vertex Hessian, both triangles stored (ipctk's CSC output
        as is); rows/columns of vertices >= Vc (obstacles) are ignored. Returns the number
        of off-pattern entries moved to the diagonal (as add_dof_matrix counts them).
        """
        if H.format not in ("csc", "csr"):
            H = H.tocsc()
        if not H.has_sorted_indices:
            H = H.sorted_indices()
        outer_is_row = H.format == "csr"
        ptr, inner, blocks = _vertex_blocks(H.indptr.astype(np.int64), H.indices.astype(np.int64),
                                            H.data.astype(np.float64), self.n_cloth, outer_is_row)
        return self._map(ptr, inner, blocks, outer_is_row, data)

    def add_local(self, hess: np.ndarray, vertex_ids: np.ndarray, data: np.ndarray) -> int:
        """Same as `add` for per-collision local Hessians.

        hess: (N, 3m, 3m) symmetric local Hessians over stencils vertex_ids (N, m);
        ids < 0 or >= Vc (padding, obstacles) are skipped.
        """
        ptr, inner, blocks = _local_blocks(np.ascontiguousarray(hess, np.float64),
                                           np.ascontiguousarray(vertex_ids, np.int64), self.n_cloth)
        return self._map(ptr, inner, blocks, True, data)

    def _map(self, ptr, inner, blocks, outer_is_row, data) -> int:
        off = np.zeros(self.n_groups, np.int64)
        args = (self.gptr, self.gverts, ptr, inner, blocks, outer_is_row,
                self.sup_free, self.sup_w, self.colstart, self.rows)
        _map_blocks(self.color_ptr, self.color_groups, *args, self.pos, data, off)
        self.moved_entries = 0
        self.off_pattern = None
        self.shift = None
        total = int(off.sum())
        if total:
            groups = np.flatnonzero(off).astype(np.int64)
            r, c, val = _collect_off(groups, *args, 9 * total)
            self.moved_entries = self._move_to_diagonal(r, c, val, data)
        return self.moved_entries

    def _move_to_diagonal(self, r, c, val, data) -> int:
        """Sum off-pattern contributions per scalar entry (r, c) and add |sum| to the
        diagonal on both rows; returns the number of nonzero moved entries. The moved
        entries (`off_pattern`, one triangle) and the diagonal added (`shift`) are kept, so
        a solver can still apply the exact Hessian (partial factorization, sim/newton.py)."""
        n3 = 3 * self.pattern.n_free
        # On the dress every iteration moves millions of contributions: np.unique's argsort
        # took a fifth of the time, scipy's CSR conversion (which sorts every row to sum
        # duplicates) 7 %.
        indptr, cols, signed = _sum_entries(r, c, val, n3)
        rows = np.repeat(np.arange(n3), np.diff(indptr))
        s = np.abs(signed)
        d = np.bincount(rows, s, minlength=n3) + np.bincount(cols, s, minlength=n3)
        data[self.diag_pos] += d
        self.off_pattern = (rows, cols, signed)
        self.shift = d
        return int(np.count_nonzero(s))


@njit(cache=True)
def _sum_entries(r, c, val, n):
    """Triplets (r, c, val) summed per entry, as CSR (indptr, indices, data) with n rows:
    a counting sort by row, then one pass per row with a marker per column (columns stay
    in first-seen order; nothing is sorted)."""
    m = r.size
    start = np.zeros(n + 1, np.int64)
    for k in range(m):
        start[r[k] + 1] += 1
    for i in range(n):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    bc = np.empty(m, np.int64)
    bv = np.empty(m)
    for k in range(m):
        p = fill[r[k]]
        bc[p], bv[p] = c[k], val[k]
        fill[r[k]] = p + 1
    at = np.full(n, -1, np.int64)  # output position of column j, if in the current row
    indptr = np.zeros(n + 1, np.int64)
    cols = np.empty(m, np.int64)
    vals = np.empty(m)
    q = 0
    for i in range(n):
        first = q
        for p in range(start[i], start[i + 1]):
            j = bc[p]
            if at[j] >= first:
                vals[at[j]] += bv[p]
            else:
                at[j], cols[q], vals[q] = q, j, bv[p]
                q += 1
        indptr[i + 1] = q
    return indptr, cols[:q], vals[:q]


@njit(cache=True)
def _greedy_colors(gsup, n_cp):
    """Colour groups so that groups sharing a control point differ (greedy, first fit)."""
    G, K = gsup.shape
    count = np.zeros(n_cp + 1, np.int64)
    for g in range(G):
        for k in range(K):
            if gsup[g, k] >= 0:
                count[gsup[g, k] + 1] += 1
    ptr = np.cumsum(count)
    fill = ptr[:-1].copy()
    members = np.empty(ptr[-1], np.int64)
    for g in range(G):
        for k in range(K):
            i = gsup[g, k]
            if i >= 0:
                members[fill[i]] = g
                fill[i] += 1
    color = -np.ones(G, np.int64)
    mark = -np.ones(G + 1, np.int64)  # mark[c] == g: colour c is taken by a neighbour of g
    for g in range(G):
        for k in range(K):
            i = gsup[g, k]
            if i < 0:
                continue
            for t in range(ptr[i], ptr[i + 1]):
                h = members[t]
                if color[h] >= 0:
                    mark[color[h]] = g
        c = 0
        while mark[c] == g:
            c += 1
        color[g] = c
    return color


@njit(cache=True, inline="always")
def _row_cursors(indptr, o):
    """Start and end of the three scalar rows (or columns) of vertex o."""
    p = np.empty(3, np.int64)
    e = np.empty(3, np.int64)
    for k in range(3):
        p[k] = indptr[3 * o + k]
        e[k] = indptr[3 * o + k + 1]
    return p, e


@njit(cache=True, inline="always")
def _next_vertex(p, e, indices, limit):
    """Smallest cloth vertex still ahead of the three cursors, or -1 when done."""
    v = -1
    for k in range(3):
        if p[k] < e[k] and indices[p[k]] < limit:
            w = indices[p[k]] // 3
            if v < 0 or w < v:
                v = w
    return v


@njit(parallel=True, cache=True)
def _vertex_blocks(indptr, indices, vals, n_cloth, outer_is_row):
    """3x3 vertex blocks of a scalar CSR/CSC matrix (sorted indices), cloth part only.

    Returns ptr (Vc+1,), inner (nb,) vertex, blocks (nb, 3, 3) stored as H_uv (rows of u,
    columns of v) where the outer vertex is u if outer_is_row else v. Two passes: count
    the blocks of each outer vertex, then fill them.
    """
    limit = 3 * n_cloth
    count = np.zeros(n_cloth + 1, np.int64)
    for o in prange(n_cloth):
        p, e = _row_cursors(indptr, o)
        n = 0
        v = _next_vertex(p, e, indices, limit)
        while v >= 0:
            for k in range(3):
                while p[k] < e[k] and indices[p[k]] // 3 == v:
                    p[k] += 1
            n += 1
            v = _next_vertex(p, e, indices, limit)
        count[o + 1] = n
    ptr = np.cumsum(count)
    inner = np.empty(ptr[-1], np.int64)
    blocks = np.zeros((ptr[-1], 3, 3))
    for o in prange(n_cloth):
        p, e = _row_cursors(indptr, o)
        b = ptr[o]
        v = _next_vertex(p, e, indices, limit)
        while v >= 0:
            inner[b] = v
            for k in range(3):
                while p[k] < e[k] and indices[p[k]] // 3 == v:
                    j = indices[p[k]] % 3
                    if outer_is_row:
                        blocks[b, k, j] = vals[p[k]]
                    else:
                        blocks[b, j, k] = vals[p[k]]
                    p[k] += 1
            b += 1
            v = _next_vertex(p, e, indices, limit)
    return ptr, inner, blocks


@njit(cache=True)
def _local_blocks(hess, ids, n_cloth):
    """Per-collision local Hessians regrouped by row vertex (a counting sort)."""
    N, m = ids.shape
    count = np.zeros(n_cloth + 1, np.int64)
    for k in range(N):
        for a in range(m):
            u = ids[k, a]
            if u < 0 or u >= n_cloth:
                continue
            for b in range(m):
                v = ids[k, b]
                if v >= 0 and v < n_cloth:
                    count[u + 1] += 1
    ptr = np.cumsum(count)
    fill = ptr[:-1].copy()
    inner = np.empty(ptr[-1], np.int64)
    blocks = np.empty((ptr[-1], 3, 3))
    for k in range(N):
        for a in range(m):
            u = ids[k, a]
            if u < 0 or u >= n_cloth:
                continue
            for b in range(m):
                v = ids[k, b]
                if v >= 0 and v < n_cloth:
                    t = fill[u]
                    inner[t] = v
                    for r in range(3):
                        for c in range(3):
                            blocks[t, r, c] = hess[k, 3 * a + r, 3 * b + c]
                    fill[u] += 1
    return ptr, inner, blocks


@njit(cache=True, inline="always")
def _find(colstart, rows, I, J):
    """Block index of (I, J), I >= J, or -1 (binary search in column J)."""
    lo = colstart[J]
    hi = colstart[J + 1]
    while lo < hi:
        mid = (lo + hi) >> 1
        if rows[mid] < I:
            lo = mid + 1
        else:
            hi = mid
    if lo < colstart[J + 1] and rows[lo] == I:
        return lo
    return -1


@njit(parallel=True, cache=True)
def _map_blocks(color_ptr, color_groups, gptr, gverts, ptr, inner, blocks, outer_is_row,
                sup_free, sup_w, colstart, rows, pos, data, off):
    """data += lower(W^T H W) on the pattern; off[g] counts block contributions of group g
    that fell outside it. Groups of one colour share no control point and each writes only
    blocks whose row (outer_is_row) or column control point is in its support."""
    K = sup_free.shape[1]
    for col in range(color_ptr.shape[0] - 1):
        for k in prange(color_ptr[col], color_ptr[col + 1]):
            g = color_groups[k]
            n_off = 0
            for t in range(gptr[g], gptr[g + 1]):
                o = gverts[t]
                for e in range(ptr[o], ptr[o + 1]):
                    n = inner[e]
                    for a in range(K):
                        A = sup_free[o, a]
                        if A < 0:
                            continue
                        wa = sup_w[o, a]
                        for b in range(K):
                            B = sup_free[n, b]
                            if B < 0:
                                continue
                            I, J = (A, B) if outer_is_row else (B, A)
                            if I < J:
                                continue  # the transposed pair (v, u) supplies it
                            blk = _find(colstart, rows, I, J)
                            if blk < 0:
                                n_off += 1
                                continue
                            w = wa * sup_w[n, b]
                            for r in range(3):
                                for c in range(3):
                                    p = pos[blk, r, c]
                                    if p >= 0:
                                        data[p] += w * blocks[e, r, c]
            off[g] = n_off


@njit(cache=True)
def _collect_off(groups, gptr, gverts, ptr, inner, blocks, outer_is_row,
                 sup_free, sup_w, colstart, rows, size):
    """Scalar (row, col, value) of every off-pattern contribution of `groups` (rare)."""
    R = np.empty(size, np.int64)
    Cc = np.empty(size, np.int64)
    V = np.empty(size)
    K = sup_free.shape[1]
    m = 0
    for g in groups:
        for t in range(gptr[g], gptr[g + 1]):
            o = gverts[t]
            for e in range(ptr[o], ptr[o + 1]):
                n = inner[e]
                for a in range(K):
                    A = sup_free[o, a]
                    if A < 0:
                        continue
                    for b in range(K):
                        B = sup_free[n, b]
                        if B < 0:
                            continue
                        I, J = (A, B) if outer_is_row else (B, A)
                        if I < J or _find(colstart, rows, I, J) >= 0:
                            continue
                        w = sup_w[o, a] * sup_w[n, b]
                        for r in range(3):
                            for c in range(3):
                                R[m] = 3 * I + r
                                Cc[m] = 3 * J + c
                                V[m] = w * blocks[e, r, c]
                                m += 1
    return R[:m], Cc[:m], V[:m]
