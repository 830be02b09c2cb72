"""The clusters of a scan chunk solved together: stacked branch matrices and one stacked `eigh` per cluster size.

`analyze` per cluster spends milliseconds on Python around a 21 × 21 eigenproblem. Here the contact blocks are
built once for the chunk (stiffness.py: a cluster's blocks are the packing's, since every term of H is written
per contact, eq:Hg3 included), and every step after that is one array operation over all clusters of a size,
with the kernels `analyze` uses for one cluster (mechanics/), given a leading batch axis:

  scatter the blocks into H̃ = D H D (G, n, n) in the metric L of each cluster (its mean contact radius;
  assembly.stack_blocks, rigid.dof_scale) → rigid motions, C̃⁺, an orthonormal basis Q off them (rigid.py) and the
  formation-error bound (accuracy.py) → every branch H^i = H_el + A diag(on) Sᵀ (eq:ContactF, the masks of
  branches.sign_patterns) of every cluster → sym(Qᵀ 𝓗^i Q), which is sym(Pᵀ H^i P) (eq:newstiffnesses) with its
  d + r rigid zeros taken out exactly (rigid.on_complement) → stacked eigh on the device (solve/device.py: numpy,
  or CuPy with --device gpu) → per-eigenvalue bounds, consistency codes (Appendix D) → counts and verdicts per
  cluster (verdicts.tally, verdict_of).

On the CPU a cluster without sliding contacts (one branch; every eigenpair consistent, so no eigenvector is
needed) is solved for its eigenvalues only (`eigvalsh`, ~0.45× the cost of `eigh` at n ≈ 80), with the wider
a-priori bounds of accuracy.value_bounds instead of residual bounds; its row says `path: batched-values` and its
`eigen_residual` is that a-priori error relative to max |λ|. An eigenvalue those bounds cannot resolve sends the
cluster to `analyze`, as any other non-rigid zero does. On a GPU (Jacobi, no such a-priori bound) every cluster
gets eigenvectors and residuals.

The same numbers as `analyze(subscene, metric=...)` on the dense path, up to round-off, for the stability verdict
and the row's columns. Left out, because no row column uses them: the ℍ^i spectra (uniqueness, Type-2). Handed
back to `analyze` (the caller's per-cluster path), unchanged: clusters whose branches need the eigenspace search
of Appendix D (a repeated eigenvalue or a non-rigid zero), clusters over max_sliding (sampled branches), clusters
without contacts, and metrics other than the L family. With --boundary fixed the held ring's contacts count, its dofs
are dropped (numbered past the cluster's, assembly.dof_index), and there is no rigid motion and no projection.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..mechanics.accuracy import (
    abs_norm_inf,
    centre_error,
    curvature_error,
    gamma,
    value_bounds,
    values_backward_error,
    vector_bounds,
)
from ..mechanics.assembly import dof_index, scatter_columns, stack_blocks
from ..mechanics.branches import BOTH, consistency, needs_search, s_limits, sign_patterns
from ..mechanics.rigid import (
    Projection,
    centred,
    dof_scale,
    on_complement,
    rigid_basis,
    rotation_columns,
    translation_columns,
)
from ..mechanics.stiffness import contact_blocks, geometric
from ..mechanics.verdicts import tally
from ..model.tolerances import EPS
from ..model.vec import rot_dim
from ..solve.device import backend, eigh_stack, residual_norms
from .clusters import lattice_offset, members, unwrap

LENGTH_FACTORS = {"L": 1.0, "L/10": 0.1, "10L": 10.0}
STACK_BYTES = {"cpu": 32 * 2 ** 20,   # the branch matrices of one stacked solve (and their copies) on the host: small
               "gpu": 256 * 2 ** 20}  # enough for glibc to reuse its temporaries (> 32 MB each is a fresh mmap);
                                     # a GPU wants large stacks


def batchable(options: dict) -> bool:
    """Whether the batched path serves these scan options (the L metric family, either boundary)."""
    return options["metric"] in LENGTH_FACTORS


def solve_chunk(scene, centers: np.ndarray, member_lists: list, options: dict) -> dict | None:
    """The row fields of the batchable centres, as columns; the others are left to the caller.

    Returns {"position": index in `centers` of each solved cluster, "counts": its `tally` columns, then its
    n_branches, lambda_min, eigen_residual, rigid_leakage, n_undetermined, n_contacts, n_sliding and values_only
    (eigenvalues only: path batched-values)}, or None when none is batchable. `scene` is best the chunk's own
    (run.chunk_scene): its contact blocks are all built. Clusters are grouped by particle count; each group is one
    stack of all its clusters' branches (split to STACK_BYTES). `--boundary fixed`: the ring beyond each cluster is
    held (clusters.extract): its contacts with the cluster count, its dofs are dropped, and there is no rigid motion
    and no projection."""
    fixed = options.get("boundary", "loads") == "fixed"
    reached = members(scene, centers, options["rings"] + 1) if fixed else member_lists
    local = np.concatenate(reached)
    sizes = np.array([len(m) for m in reached])
    starts = np.r_[0, np.cumsum(sizes)[:-1]]
    free = _free(local, sizes, member_lists, scene.n_particles) if fixed else np.ones(len(local), dtype=bool)
    blocks = contact_blocks(scene)
    hg = geometric(blocks.blocks)
    parts = {"elastic": blocks.blocks["Hm"] + hg,                        # H_el per contact, and the row sums of |Hm|,
             "rows_m": np.abs(blocks.blocks["Hm"]).sum(axis=2),         # |Hg| that bound ‖|Hm̃|‖∞, ‖|Hg̃|‖∞ (formation)
             "rows_g": np.abs(hg).sum(axis=2)}
    pairs = _cluster_contacts(scene, local, sizes, free)
    pairs["sliding"] = scene.at_yield()[pairs["contact"]]
    positions, wraps = ((None, np.zeros(len(centers), dtype=bool)) if fixed
                        else _positions(scene, centers, local, sizes, pairs))
    n_contacts = np.bincount(pairs["cluster"], minlength=len(centers))
    n_sliding = np.bincount(pairs["cluster"], weights=pairs["sliding"],
                            minlength=len(centers)).astype(int)
    ok = (n_contacts > 0) & (n_sliding <= options["max_sliding"]) & ~wraps
    solved = []
    factor = LENGTH_FACTORS[options["metric"]]
    n_free = np.array([len(m) for m in member_lists])
    for n in np.unique(n_free[ok]):
        group = np.flatnonzero(ok & (n_free == n))
        for part in _split(group, n * scene.dof_per_particle, n_sliding, STACK_BYTES[options.get("device", "cpu")]):
            solved.append(_solve_group(scene, blocks, parts, pairs, part, positions, starts, int(n), factor,
                                       n_sliding, options["max_sliding"], options.get("device", "cpu"), fixed))
    return _concatenate(solved)


def _concatenate(groups: list[dict]) -> dict | None:
    """The groups' columns joined (the `counts` columns too); None when no cluster is batched."""
    if not groups:
        return None
    out = {key: np.concatenate([g[key] for g in groups]) for key in groups[0] if key != "counts"}
    out["counts"] = {key: np.concatenate([g["counts"][key] for g in groups]) for key in groups[0]["counts"]}
    return out


def _free(local: np.ndarray, sizes: np.ndarray, member_lists: list, N: int) -> np.ndarray:
    """Which entries of `local` (the particles each cluster's contacts reach, sorted per cluster) are the cluster's
    own (`member_lists`), not the held ring."""
    keys = np.repeat(np.arange(len(sizes)), sizes) * N + local
    own = np.repeat(np.arange(len(member_lists)), [len(m) for m in member_lists]) * N + np.concatenate(member_lists)
    return np.isin(keys, own, assume_unique=True)


def _positions(sub, centers: np.ndarray, local: np.ndarray, sizes: np.ndarray, pairs: dict):
    """The particles' positions of every cluster (`local`, the clusters' members one after the other); in a periodic
    chunk each cluster unwrapped from its centre along its contacts (clusters.unwrap, as `subscene` does), so that
    its rigid rotations are those of the extracted cluster. Also which clusters wrap around the cell: they are left
    to `analyze` (whose error names them)."""
    x = sub.x[local]
    if sub.cell is None:
        return x, np.zeros(len(sizes), dtype=bool)
    N = sub.n_particles
    starts = np.r_[0, np.cumsum(sizes)[:-1]]
    keys = np.repeat(np.arange(len(sizes)), sizes) * N + local
    roots = np.searchsorted(keys, np.arange(len(sizes)) * N + centers)
    start = starts[pairs["cluster"]]
    shift, loops = unwrap(len(local), start + pairs["lp"], start + pairs["lq"], sub.image[pairs["contact"]], roots)
    wraps = np.bincount(pairs["cluster"], weights=loops, minlength=len(sizes)) > 0
    return x + lattice_offset(shift, sub.cell), wraps


def _split(group: np.ndarray, nd: int, n_sliding: np.ndarray, budget: int) -> list[np.ndarray]:
    """Consecutive parts of a group whose branch matrices (8 copies of nd² doubles each) fit `budget` bytes."""
    cost = 2.0 ** n_sliding[group] * 8 * 8 * nd * nd
    cut = np.floor(np.cumsum(cost) / budget).astype(int)
    return [group[cut == c] for c in np.unique(cut)]


def _cluster_contacts(sub, local: np.ndarray, sizes: np.ndarray, free: np.ndarray) -> dict:
    """Every (cluster, contact) with both particles in `local` and one at least `free`, with the particles' ranks
    among the cluster's free particles (-1: held), in cluster order and, within a cluster, in contact order (the
    order `subscene` keeps)."""
    G, N = len(sizes), sub.n_particles
    cluster = np.repeat(np.arange(G), sizes)
    X = sp.csr_matrix((np.ones(len(local)), (local, cluster)), shape=(N, G))
    both = X[sub.p].multiply(X[sub.q]).tocsc()
    both.sort_indices()
    contact = both.indices.astype(np.int64)
    owner = np.repeat(np.arange(G), np.diff(both.indptr))
    keys = cluster * N + local                                      # sorted: members are sorted per cluster
    counted = np.cumsum(free)
    before = (counted - free)[np.r_[0, np.cumsum(sizes)[:-1]]]      # free entries before each cluster's first
    rank_of = np.where(free, counted - 1 - np.repeat(before, sizes), -1)

    def rank(particle):
        return rank_of[np.searchsorted(keys, owner * N + particle)]

    lp, lq = rank(sub.p[contact]), rank(sub.q[contact])
    acts = (lp >= 0) | (lq >= 0)                                    # two held particles: no dof of the cluster
    return {"cluster": owner[acts], "contact": contact[acts], "lp": lp[acts], "lq": lq[acts]}


def _solve_group(sub, blocks, parts, pairs, part, positions, starts, n, factor, n_sliding, width, device,
                 fixed) -> dict:
    """Row fields of the clusters `part` (all with n free particles): see the module docstring. The held ring's
    dofs (fixed) are numbered nd, which the scatters drop (assembly.dof_index, stack_blocks). The sliding
    factors A, S have `width` (max_sliding) columns whichever clusters share the stack, for every per-cluster
    product and norm: their rounding depended on the column count (numpy and BLAS pick kernels by shape; one column
    is another path), so a row is the same bits however the scan is chunked (serially, on any number of workers,
    resumed; tested). The branches' work takes the stack's most columns only."""
    d, r = sub.dim, rot_dim(sub.dim)
    per = d + r
    nd = n * per
    G = len(part)
    slot = np.full(len(n_sliding), -1)
    slot[part] = np.arange(G)
    sel = slot[pairs["cluster"]] >= 0
    g, m = slot[pairs["cluster"][sel]], pairs["contact"][sel]
    idx = dof_index(pairs["lp"][sel], pairs["lq"][sel], per, held=nd)               # (P, 2per) local dofs, nd: held

    # metric: L = mean contact radius of the cluster, D = diag(1, 1/L) per particle: rigid.rotation_length of the
    # cluster, but summed per contact in cluster order, not by numpy's pairwise mean (one summation order for both
    # would move the last bits of one path's rows)
    radii = np.linalg.norm(sub.r_pq[m], axis=1) + np.linalg.norm(sub.r_qp[m], axis=1)
    L = np.bincount(g, weights=radii, minlength=G) / (2 * np.bincount(g, minlength=G))
    L = factor * np.where(L > 0, L, 1.0)
    dscale = np.concatenate([dof_scale(n, d, L), np.ones((G, 1))], axis=1)          # (G, nd + 1): 1 at held dof nd
    Dp = dscale[g[:, None], idx]                                                     # (P, 2per)

    H_el = stack_blocks(parts["elastic"][m] * Dp[:, :, None] * Dp[:, None, :], g, idx, G, nd)   # (G, nd, nd)
    curvature = curvature_error(stack_blocks(blocks.curvature_error[m] * Dp[:, :, None] * Dp[:, None, :],
                                             g, idx, G, nd))      # error from rounding K^p + K^q (accuracy.py)

    def abs_norm(rows):            # ‖|Σ_c X̃_c|‖∞ <= max over rows of Σ_c (row sums of |X̃_c|): per contact, no matrices
        return stack_blocks(rows[m] * Dp * Dp.max(axis=1, keepdims=True), g, idx, G, nd).max(axis=1)

    # sliding factors A, S (G, nd, Ms) in the metric's dofs, the contacts in cluster order (eq:ContactF, eq:flow)
    slide = sel & pairs["sliding"]
    gs, ms = slot[pairs["cluster"][slide]], pairs["contact"][slide]
    col = _rank_within(gs)
    Ms = int(n_sliding[part].max())
    idx_s, Ds = idx[slide[sel]], Dp[slide[sel]]
    A, S = (scatter_columns(f[ms] * Ds, gs, idx_s, col, G, nd, width if Ms else 0)   # max_sliding columns: docstring
            for f in (blocks.slide_left, blocks.slide_right))
    scales = (abs_norm(parts["rows_m"]) + abs_norm(parts["rows_g"])
              + _column_sum(np.linalg.norm(A, axis=1) * np.linalg.norm(S, axis=1)))
    s_tol, s_floor = s_limits(S, sub.tol)                  # branches.Problem.s_tol, s_floor

    if fixed:                      # held by the ring: no rigid motion, P^nrr = I (eq:Pnrr), formation 8ε of the parts
        formation, leakage = 8 * EPS * scales + curvature, np.zeros(G)
        base = 0.5 * (H_el + np.swapaxes(H_el, 1, 2))
        PA, PS = A, S
    else:                          # off the rigid motions: QᵀH Q, QᵀA, QᵀS (_reduced)
        x = positions[np.concatenate([np.arange(starts[c], starts[c] + n) for c in part])].reshape(G, n, d)
        formation, leakage, base, PA, PS = _reduced(H_el, A, S, x, L, scales)
        formation = formation + curvature
    update = _update_norm(PA, PS)
    PA, PS = np.ascontiguousarray(PA[:, :, :Ms]), np.ascontiguousarray(PS[:, :, :Ms])   # the branches' columns
    dofs = base.shape[1]           # the dofs solved for: nd, or nd − (d + r) off the rigid motions
    values_only = (n_sliding[part] == 0) & (device == "cpu")
    values, vectors = np.flatnonzero(values_only), np.flatnonzero(~values_only)
    solved = [(values, _values(base[values], formation[values], dofs))] if values.size else []
    if vectors.size:
        solved.append((vectors, _vectors(base[vectors], PA[vectors], PS[vectors], update[vectors],
                                         n_sliding[part][vectors], formation[vectors],
                                         s_tol[vectors], s_floor[vectors], dofs, device)))
    owner = np.concatenate([which[got["owner"]] for which, got in solved])
    lam, bounds, codes, hinges, special, error = (np.concatenate([got[key] for _, got in solved])
                                                  for key in ("lam", "bounds", "codes", "hinges", "special", "error"))
    relative = error / np.maximum(np.abs(lam).max(axis=1), 1e-300)

    bad = np.zeros(G, dtype=bool)
    np.logical_or.at(bad, owner, special)
    flat_owner = np.repeat(owner, dofs)
    counts = tally(lam.ravel(), bounds.ravel(), codes.ravel(), hinges.ravel(), flat_owner, G)
    lam_min = np.full(G, np.inf)
    np.minimum.at(lam_min, flat_owner, lam.ravel())
    residual = np.zeros(G)
    np.maximum.at(residual, owner, relative)
    undetermined = np.bincount(g, weights=blocks.rolling_undetermined[m], minlength=G).astype(int)
    keep = ~bad
    return {"position": part[keep], "counts": {k: v[keep] for k, v in counts.items()},
            "n_branches": np.bincount(owner, minlength=G)[keep],
            "lambda_min": np.where(np.isfinite(lam_min), lam_min, np.nan)[keep], "eigen_residual": residual[keep],
            "rigid_leakage": leakage[keep], "n_undetermined": undetermined[keep],
            "n_contacts": np.bincount(g, minlength=G)[keep], "n_sliding": n_sliding[part][keep],
            "values_only": values_only[keep]}


def _reduced(H_el, A, S, x, L, scales):
    """The isolated cluster (--boundary loads) on the complement of its rigid motions: the rigid motions about the
    centroid in scaled dofs (eq:dtrigid), an orthonormal basis Q of their complement, and sym(Qᵀ H_el Q), QᵀA, QᵀS
    (rigid.rigid_basis, rigid.on_complement, which lowrank.reduce calls for one cluster's branches): every branch's
    sym(Qᵀ 𝓗^i Q) is sym(Pᵀ H^i P) with its d + r rigid zeros taken out exactly.

    Formation bound: forming Qᵀ H Q (2γ_nd·nd of the parts' scale, Q orthonormal to γ_nd), plus a bound of the
    coupling Qᵀ sym(𝓗^i) R to the rigid motions R that leaving them out neglects, over every branch (zero in exact
    arithmetic: H T = 0, Tᵀ H = 0, Sᵀ T = 0 for translations T, P C = 0; Weyl: it moves no eigenvalue further).
    Also the rigid leakage of H_el (reported as rigid_leakage)."""
    G, n, d = x.shape
    nd = H_el.shape[1]
    C = rotation_columns(x, L)
    R, Q = rigid_basis(np.concatenate([translation_columns(n, d, (G,)), C], axis=2), complement=True)
    PR = Projection.from_rotations(C).apply(R)                                                              # P R (eq:newstiffnesses)
    leak = H_el @ PR
    leakage = np.abs(leak).max(axis=(1, 2)) / np.maximum(np.linalg.norm(H_el, axis=(1, 2)), 1e-300)
    coupling = 0.5 * (np.linalg.norm(leak, axis=(1, 2)) + np.linalg.norm(np.swapaxes(H_el, 1, 2) @ PR, axis=(1, 2))
                      + _column_sum(np.linalg.norm(A, axis=1) * np.linalg.norm(np.swapaxes(S, 1, 2) @ PR, axis=2)
                                    + np.linalg.norm(S, axis=1) * np.linalg.norm(np.swapaxes(A, 1, 2) @ PR, axis=2)))
    formation = (8 * EPS + 2 * gamma(nd) * nd + centre_error(C, centred(x, defect=True)[1])) * scales + coupling
    return formation, leakage, *on_complement(Q, H_el, A, S)


def _values(Hsym, formation, nd: int) -> dict:
    """Clusters without sliding contacts (one branch, every eigenpair consistent): eigenvalues only (LAPACK syevd
    without vectors, ~0.45× the cost of eigh at n ≈ 80), each with the a-priori bound of accuracy.value_bounds."""
    with backend("cpu").threads(nd):
        lam = np.linalg.eigvalsh(Hsym)
    scale = abs_norm_inf(Hsym)[:, None]
    bounds = value_bounds(lam, scale, formation[:, None], nd)
    return {"owner": np.arange(len(Hsym)), "lam": lam, "bounds": bounds, "codes": np.full(lam.shape, BOTH, np.int8),
            "hinges": np.zeros(lam.shape, dtype=bool), "special": needs_search(lam, bounds),
            "error": values_backward_error(scale[:, 0], nd)}


def _vectors(base, PA, PS, update, n_sliding, formation, s_tol, s_floor, nd: int, device: str) -> dict:
    """Every branch (enumerate_masks order) of the clusters `base` (sym(Qᵀ H_el Q), or sym(H_el) held), stacked
    eigh on the backend, residual bounds (accuracy.vector_bounds) and consistency codes (Appendix D) from the S
    values (PSᵀ y = Sᵀ Q y: those of the eigenvector in the cluster's dofs)."""
    Ms = PA.shape[2]
    owner, masks = sign_patterns(n_sliding, Ms)
    Hsym = base[owner]
    loading = np.flatnonzero((masks == 1).any(axis=1))
    if loading.size:                                # + ½(X + Xᵀ), X = a diag(on) sᵀ: exactly symmetric, as `base` is
        X = (PA[owner[loading]] * (masks[loading] == 1)[:, None, :]) @ np.swapaxes(PS[owner[loading]], 1, 2)
        X += np.swapaxes(X, 1, 2)
        Hsym[loading] += 0.5 * X
    got = backend_eigh(Hsym, PS[owner], device)
    lam = got["lam"]
    scale = (abs_norm_inf(base) + update)[owner]     # >= ‖|Hsym|‖∞ of every branch (update: _update_norm)
    bounds = vector_bounds(lam, got["residual"], scale[:, None], formation[owner, None], nd)
    codes, hinges = consistency(masks[:, :, None].astype(float), got["S"], s_tol[owner, None, None],
                                s_floor[owner, None, None])
    return {"owner": owner, "lam": lam, "bounds": bounds, "codes": codes, "hinges": hinges,
            "special": needs_search(lam, bounds), "error": got["residual"].max(axis=1)}


def backend_eigh(Hsym: np.ndarray, S: np.ndarray, device: str) -> dict:
    """Stacked eigh of sym(𝓗^i) on the device: eigenvalues, residual norms ‖A v − λ v‖ and the S values
    Sᵀ v (eq:flow) of the eigenvectors, whatever their signs (a row counts consistent modes, PLUS, MINUS or BOTH
    alike); eigenvectors stay there."""
    be = backend(device)

    def keep(xp, A, lam, V, start):
        Sd = be.asarray(S[start:start + A.shape[0]])
        return {"lam": lam, "residual": residual_norms(xp, A, lam, V), "S": xp.matmul(xp.swapaxes(Sd, 1, 2), V)}

    return eigh_stack(Hsym, device=be.name, keep=keep, symmetric=True)


def _rank_within(groups: np.ndarray) -> np.ndarray:
    """0, 1, 2, ... within each run of equal values of a sorted array."""
    if groups.size == 0:
        return groups
    first = np.r_[0, np.flatnonzero(np.diff(groups)) + 1]
    return np.arange(len(groups)) - np.repeat(first, np.diff(np.r_[first, len(groups)]))


def _update_norm(a: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Per cluster an upper bound of ‖|½(a diag(on) sᵀ + s diag(on) aᵀ)|‖∞ over every on ∈ {0, 1}^Ms:
    ½ Σ_j (‖a_j‖∞ ‖s_j‖₁ + ‖s_j‖∞ ‖a_j‖₁) (a, s: (G, nd, Ms))."""
    a, s = np.abs(a), np.abs(s)
    return 0.5 * _column_sum(a.max(axis=1, initial=0.0) * s.sum(axis=1) + s.max(axis=1, initial=0.0) * a.sum(axis=1))


def _column_sum(values: np.ndarray) -> np.ndarray:
    """Sum over the last axis (a stack's sliding columns), one column after the other: zero columns padded on
    change no bit, whereas numpy's pairwise sum regroups the terms by the column count (from 8 on), so a row would
    depend on which clusters share its stack."""
    total = np.zeros(values.shape[:-1])
    for j in range(values.shape[-1]):
        total = total + values[..., j]
    return total
