"""Hessian assembly into a fixed CSC pattern, without triplets (docs/design.md section 5).

The unknowns are the free control points (3 DOFs each). The pattern holds the lower
triangle of the 3n x 3n matrix (CHOLMOD reads only that), grouped in 3x3 blocks: one
block per pair of free control points (I >= J) that share a quadrature point. It is built
once; every Newton iteration writes values straight into `data`:

- `pos[b, r, c]` is the index in `data` of entry (3I + r, 3J + c) of block b (-1 for the
  upper half of diagonal blocks).
- An energy with per-point stencils gets a gather map: for each block the list of
  (point, a, b) stencil pairs that contribute to it, so blocks are summed in parallel
  with no write conflicts and no sorting per iteration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit, prange


@dataclass
class BlockPattern:
    """Lower-triangular block CSC pattern over `n_free` free control points.

    free: (n_cp,) map control point -> free index or -1 if pinned.
    rows, cols: (B,) block coordinates (free indices, rows >= cols), in CSC order.
    pos: (B, 3, 3) data indices; indptr/indices: the scalar CSC structure.
    """

    free: np.ndarray
    n_free: int
    rows: np.ndarray
    cols: np.ndarray
    pos: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray

    @property
    def n_blocks(self) -> int:
        return self.rows.shape[0]

    @property
    def nnz(self) -> int:
        return self.indices.shape[0]

    @property
    def n_dofs(self) -> int:
        return 3 * self.n_free

    def lookup(self, I: np.ndarray, J: np.ndarray) -> np.ndarray:
        """Block index of free pairs (I, J) with I >= J, or -1 where not in the pattern."""
        key = J.astype(np.int64) * self.n_free + I
        ids = np.minimum(np.searchsorted(self._keys, key), self._keys.shape[0] - 1)
        return np.where(self._keys[ids] == key, ids, -1)

    def block_ids(self, I: np.ndarray, J: np.ndarray) -> np.ndarray:
        """Block index of free pairs (I, J) with I >= J; all must be in the pattern."""
        ids = self.lookup(I, J)
        if np.any(ids < 0):
            raise KeyError("control-point pair outside the Hessian pattern")
        return ids

    def matrix(self, data: np.ndarray) -> sp.csc_matrix:
        """A scipy CSC view of the lower triangle holding `data` (no copy)."""
        n = self.n_dofs
        A = sp.csc_matrix((data, self.indices, self.indptr), shape=(n, n))
        return A

    def full(self, data: np.ndarray) -> sp.csc_matrix:
        """The symmetric matrix (both triangles), for products and tests."""
        L = self.matrix(data)
        return (L + L.T - sp.diags(L.diagonal())).tocsc()

    @classmethod
    def from_stencils(cls, free: np.ndarray, stencils: list[np.ndarray]) -> "BlockPattern":
        """Pattern of all free pairs that appear together in a stencil row.

        free: (n_cp,) free index or -1; stencils: arrays (Q, K) of control points
        (padding -1).
        """
        n_free = int(free.max()) + 1 if free.size else 0
        keys = [np.arange(n_free, dtype=np.int64) * n_free + np.arange(n_free)]  # diagonal
        for idx in stencils:
            f = np.where(idx >= 0, free[np.maximum(idx, 0)], -1)
            K = f.shape[1]
            a, b = np.triu_indices(K, 1)
            I, J = f[:, a].ravel(), f[:, b].ravel()
            ok = (I >= 0) & (J >= 0)
            I, J = I[ok], J[ok]
            hi, lo = np.maximum(I, J), np.minimum(I, J)
            keys.append(np.unique(lo.astype(np.int64) * n_free + hi))
        keys = np.unique(np.concatenate(keys))
        cols = keys // n_free
        rows = keys % n_free
        pos, indptr, indices = _scalar_structure(rows, cols, n_free)
        pat = cls(free, n_free, rows, cols, pos, indptr, indices)
        pat._keys = keys
        return pat


def _scalar_structure(rows, cols, n_free):
    """Scalar CSC structure of the lower triangle and the block -> data position map."""
    B = rows.shape[0]
    count = np.bincount(cols, minlength=n_free)  # blocks per block column (sorted by col)
    start = np.concatenate([[0], np.cumsum(count)])
    # Column 3J + c holds rows 3I + r for blocks (I, J) below the diagonal (all r) and the
    # diagonal block's rows r >= c: 3 * count - c entries.
    col_len = (3 * count[:, None] - np.arange(3)[None, :]).ravel()
    indptr = np.concatenate([[0], np.cumsum(col_len)]).astype(np.int64)
    pos = -np.ones((B, 3, 3), np.int64)
    k = np.arange(B) - start[cols]  # rank of the block within its column (diagonal first)
    for c in range(3):
        base = indptr[3 * cols + c]
        for r in range(3):
            diag = rows == cols
            p = np.where(diag, base + r - c, base + 3 * k - c + r)
            valid = ~diag | (r >= c)
            pos[:, r, c] = np.where(valid, p, -1)
    indices = np.empty(indptr[-1], np.int64)
    for r in range(3):
        for c in range(3):
            ok = pos[:, r, c] >= 0
            indices[pos[ok, r, c]] = 3 * rows[ok] + r
    step = np.diff(indices)
    step[indptr[1:-1] - 1] = 1  # column boundaries may repeat a row index
    if np.any(step <= 0):
        raise AssertionError("block pattern rows are not strictly increasing per column")
    return pos, indptr.astype(np.int32), indices.astype(np.int32)


@dataclass
class GatherMap:
    """For each pattern block, the stencil pairs (point, a, b) that contribute to it
    (CSR: ptr (B+1,), point/a/b (P,)). `gptr`/`gpoint`/`ga` do the same per free control
    point for gradients."""

    ptr: np.ndarray
    point: np.ndarray
    a: np.ndarray
    b: np.ndarray
    gptr: np.ndarray
    gpoint: np.ndarray
    ga: np.ndarray


def gather_map(pattern: BlockPattern, idx: np.ndarray, n_cp: int) -> GatherMap:
    """Gather map of stencils idx (Q, K) onto `pattern` (pairs with both points free)."""
    Q, K = idx.shape
    f = np.where(idx >= 0, pattern.free[np.maximum(idx, 0)], -1)
    q, a, b = np.meshgrid(np.arange(Q), np.arange(K), np.arange(K), indexing="ij")
    q, a, b = q.ravel(), a.ravel(), b.ravel()
    I, J = f[q, a], f[q, b]
    keep = (I >= 0) & (J >= 0) & (I >= J)
    q, a, b, I, J = q[keep], a[keep], b[keep], I[keep], J[keep]
    blk = pattern.block_ids(I, J)
    order = np.argsort(blk, kind="stable")
    ptr = np.concatenate([[0], np.cumsum(np.bincount(blk, minlength=pattern.n_blocks))])
    # Gradient gather over all control points (pinned ones too: forces are reported).
    qq, aa = np.meshgrid(np.arange(Q), np.arange(K), indexing="ij")
    qq, aa = qq.ravel(), aa.ravel()
    cp = idx[qq, aa]
    ok = cp >= 0
    qq, aa, cp = qq[ok], aa[ok], cp[ok]
    gorder = np.argsort(cp, kind="stable")
    gptr = np.concatenate([[0], np.cumsum(np.bincount(cp, minlength=n_cp))])
    return GatherMap(
        ptr=ptr.astype(np.int64), point=q[order].astype(np.int64),
        a=a[order].astype(np.int64), b=b[order].astype(np.int64),
        gptr=gptr.astype(np.int64), gpoint=qq[gorder].astype(np.int64), ga=aa[gorder].astype(np.int64),
    )


@njit(parallel=True, cache=True)
def gather_hessian_F(ptr, point, a, b, g, w, HF, pos, data):
    """Add sum_q w_q (g_qa (x) g_qb) : d2Psi/dF2 into each block of `data`.

    HF: (Q, 6, 6) Hessian of the energy density w.r.t. F in column-stacked layout
    [F e1; F e2]; g: (Q, K, 2); pos: (B, 3, 3) data indices.
    """
    B = ptr.shape[0] - 1
    for blk in prange(B):
        acc = np.zeros((3, 3))
        for k in range(ptr[blk], ptr[blk + 1]):
            q = point[k]
            ga0 = g[q, a[k], 0] * w[q]
            ga1 = g[q, a[k], 1] * w[q]
            gb0 = g[q, b[k], 0]
            gb1 = g[q, b[k], 1]
            c00, c01, c10, c11 = ga0 * gb0, ga0 * gb1, ga1 * gb0, ga1 * gb1
            for r in range(3):
                for c in range(3):
                    acc[r, c] += (c00 * HF[q, r, c] + c01 * HF[q, r, 3 + c]
                                  + c10 * HF[q, 3 + r, c] + c11 * HF[q, 3 + r, 3 + c])
        for r in range(3):
            for c in range(3):
                p = pos[blk, r, c]
                if p >= 0:
                    data[p] += acc[r, c]


@njit(parallel=True, cache=True)
def gather_gradient_F(gptr, gpoint, ga, g, w, P, out):
    """out[c] += sum over stencil entries of c: w_q P_q g_qa, with P: (Q, 3, 2)."""
    n = gptr.shape[0] - 1
    for c in prange(n):
        for k in range(gptr[c], gptr[c + 1]):
            q = gpoint[k]
            g0 = g[q, ga[k], 0] * w[q]
            g1 = g[q, ga[k], 1] * w[q]
            for d in range(3):
                out[c, d] += P[q, d, 0] * g0 + P[q, d, 1] * g1


@njit(parallel=True, cache=True)
def deformation_gradients(C, idx, g, F):
    """F_q = sum_a C[idx[q, a]] g[q, a]^T, written into F (Q, 3, 2)."""
    Q, K = idx.shape
    for q in prange(Q):
        for d in range(3):
            F[q, d, 0] = 0.0
            F[q, d, 1] = 0.0
        for a in range(K):
            i = idx[q, a]
            if i < 0:
                continue
            for d in range(3):
                F[q, d, 0] += C[i, d] * g[q, a, 0]
                F[q, d, 1] += C[i, d] * g[q, a, 1]


def add_scalar_matrix(pattern: BlockPattern, K: sp.spmatrix, data: np.ndarray) -> None:
    """Add the 3D matrix K (x) I3 (K: n_cp x n_cp symmetric scalar) into `data`."""
    K = sp.tril(K.tocoo())
    I = pattern.free[K.row]
    J = pattern.free[K.col]
    ok = (I >= 0) & (J >= 0)
    I, J, v = I[ok], J[ok], K.data[ok]
    hi, lo = np.maximum(I, J), np.minimum(I, J)
    blk = pattern.block_ids(hi, lo)
    for r in range(3):
        np.add.at(data, pattern.pos[blk, r, r], v)


def add_diagonal(pattern: BlockPattern, diag: np.ndarray, data: np.ndarray) -> None:
    """Add diag(diag) (x) I3 (diag: (n_cp,)) into `data`."""
    add_scalar_matrix(pattern, sp.diags(diag).tocoo(), data)


def add_dof_matrix(pattern: BlockPattern, H: sp.spmatrix, data: np.ndarray) -> int:
    """Add a symmetric PSD matrix on the free DOFs (3 n_free square) into `data`.

    Entries whose control-point pair lies outside the pattern (distant self-contact)
    are not dropped but moved onto the diagonal as |H_ij| on both rows: H_out is replaced
    by the diagonally dominant D = diag(sum_j |H_out_ij|), and D - H_out is PSD, so the
    result stays PSD (and stiffer) while the pattern, and CHOLMOD's analysis, never
    change. Returns the number of moved entries.
    """
    H = sp.tril(H.tocoo())
    r, c, v = H.row, H.col, H.data
    blk = pattern.lookup(r // 3, c // 3)
    inside = blk >= 0
    pos = np.full(r.shape, -1, np.int64)
    pos[inside] = pattern.pos[blk[inside], r[inside] % 3, c[inside] % 3]
    np.add.at(data, pos[pos >= 0], v[pos >= 0])
    out = ~inside
    if np.any(out):
        diag = pattern.pos[pattern.lookup(np.arange(pattern.n_free), np.arange(pattern.n_free))]
        d = np.zeros(pattern.n_dofs)
        np.add.at(d, r[out], np.abs(v[out]))
        np.add.at(d, c[out], np.abs(v[out]))
        idx = np.arange(pattern.n_dofs)
        np.add.at(data, diag[idx // 3, idx % 3, idx % 3], d)
    return int(out.sum())
