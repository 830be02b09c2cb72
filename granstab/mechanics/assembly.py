"""Contact blocks → matrices, scikit-fem style: the block kernel (stiffness.contact_blocks) knows nothing of assembly.

One intermediate, the per-contact blocks (eq:piece) with an index map to the dofs they act on (`dof_index`), and
two outputs:

* one scene: `assemble`, CSR over the scene's dofs (analyze; the parts of H, eq:final1), or `Assembly` where
  several block arrays share the scene's contacts (its pattern is found once);
* a stack of G clusters: `stack_blocks`, dense (G, n, n) arrays, each (cluster, contact) entry with its owner and its dofs
  numbered within that cluster (the scan's batch; a held dof of --boundary fixed is numbered n and dropped).

The rank-one sliding factors A, S (eq:ContactF, eq:flow) are scattered the same way, one column per potentially
sliding contact (`scatter_columns`; `sliding_factors` for one scene). Every scatter sums in the order of its entries,
so a cluster's arrays have the same bits whichever clusters share its stack.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def dof_index(p: np.ndarray, q: np.ndarray, per: int, held: int | None = None) -> np.ndarray:
    """The dofs (P, 2·per) of blocks over [particle p, particle q]: p·per + 0, …, per - 1, then q's; with `held`, a
    negative particle number (a held particle) maps all its dofs to `held`."""
    local = np.arange(per)

    def side(x):
        dofs = x[:, None] * per + local
        return dofs if held is None else np.where(x[:, None] >= 0, dofs, held)

    return np.concatenate([side(p), side(q)], axis=1)


class Assembly:
    """The CSR pattern of per-contact (M, 2·per, 2·per) blocks over [particle p, particle q], found once, and the
    scatter of any number of block arrays into it (H, its mechanical part and its error bound share it).

    Built at the level of per×per particle blocks (4M of them instead of (2 per)² M scalars): one stable sort of
    the block keys, then per array one segmented sum in contact order and a gather into CSR order (the BSR → CSR
    map, also found once). (A counting-sort variant that sums only the diagonal blocks was tried: faster below 10⁴
    contacts, slower above, so this one is kept.)
    """

    def __init__(self, p: np.ndarray, q: np.ndarray, per: int, n_dof: int):
        N = n_dof // per
        self.per, self.n_dof, self.M = per, n_dof, len(p)
        if self.M == 0:
            return
        rows = np.stack([p, p, q, q], axis=1).reshape(-1).astype(np.int64)
        cols = np.stack([p, q, p, q], axis=1).reshape(-1).astype(np.int64)
        key = rows * N + cols
        order = np.argsort(key, kind="stable")                      # block 4c + 2a + b: contact c, sides a, b
        self.contact, self.side_row, self.side_col = order // 4, (order // 2) % 2, order % 2
        key = key[order]
        self.starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        brow, bcol = np.divmod(key[self.starts], N)
        indptr = np.r_[0, np.cumsum(np.bincount(brow, minlength=N))]
        n_blocks = len(self.starts)
        label = np.arange(1, n_blocks * per * per + 1, dtype=float).reshape(n_blocks, per, per)   # 1-based: exact
        csr = sp.bsr_matrix((label, bcol, indptr), shape=(n_dof, n_dof)).tocsr()
        self.take = csr.data.astype(np.int64) - 1                     # CSR entry j is BSR entry take[j]
        self.indices, self.indptr = csr.indices, csr.indptr

    def __call__(self, blocks: np.ndarray) -> sp.csr_matrix:
        """Scatter (M, 2·per, 2·per) blocks into CSR, summing duplicates in contact order."""
        if self.M == 0:
            return sp.csr_matrix((self.n_dof, self.n_dof))
        per = self.per
        b = blocks.reshape(self.M, 2, per, 2, per)[self.contact, self.side_row, :, self.side_col, :]   # key order
        data = np.add.reduceat(b, self.starts, axis=0)
        return sp.csr_matrix((data.reshape(-1)[self.take], self.indices.copy(), self.indptr.copy()),
                             shape=(self.n_dof, self.n_dof))


def assemble(blocks: np.ndarray, p: np.ndarray, q: np.ndarray, per: int, n_dof: int) -> sp.csr_matrix:
    """Scatter per-contact (M, 2·per, 2·per) blocks over [particle p, particle q] into CSR, summing duplicates
    (one array; `Assembly` for several over the same contacts)."""
    return Assembly(p, q, per, n_dof)(blocks)


def stack_blocks(values: np.ndarray, owner: np.ndarray, index: np.ndarray, G: int, n: int) -> np.ndarray:
    """Per-entry blocks (P, k, k) summed into G matrices (G, n, n), or per-entry rows (P, k) into G vectors (G, n):
    entry e at the dofs index[e] (k,) of matrix owner[e]; dof n (held) is dropped. Sums in entry order (bincount)."""
    padded = n + 1
    if values.ndim == 3:
        flat = (owner[:, None, None] * padded + index[:, :, None]) * padded + index[:, None, :]
        shape = (G, padded, padded)
    else:
        flat = owner[:, None] * padded + index
        shape = (G, padded)
    out = np.bincount(flat.ravel(), weights=values.ravel(), minlength=int(np.prod(shape))).reshape(shape)
    return np.ascontiguousarray(out[:, :n, :n] if values.ndim == 3 else out[:, :n])


def scatter_columns(values: np.ndarray, owner: np.ndarray, index: np.ndarray, column: np.ndarray, G: int, n: int,
                    width: int) -> np.ndarray:
    """Sliding factors as a stack (G, n, width) (eq:ContactF): the vector values[e] (k,) of sliding contact e at
    rows index[e] (k,) of column column[e] of matrix owner[e]; row n (held) is dropped."""
    out = np.zeros((G, n + 1, width))
    np.add.at(out, (owner[:, None], index, column[:, None]), values)
    return np.ascontiguousarray(out[:, :n])


def sliding_factors(blocks, sliding: np.ndarray):
    """A, S (n_dof, Ms) of one scene from its stiffness.ContactBlocks: a and s of the potentially sliding contacts
    `sliding` (Ms,), one column each (eq:ContactF, eq:flow)."""
    Ms = len(sliding)
    owner, column, index = np.zeros(Ms, dtype=np.intp), np.arange(Ms), blocks.index[sliding]
    return tuple(scatter_columns(f[sliding], owner, index, column, 1, blocks.n_dof, Ms)[0]
                 for f in (blocks.slide_left, blocks.slide_right))
