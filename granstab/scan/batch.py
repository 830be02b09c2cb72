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
cluster to `analyze`, as any other non-rigid zero does. With --boundary embedded a negative or zero mode counts only
when it lies mostly in the cluster, which takes its vector: there a cluster keeps its eigenvalues only when they
are all proven positive (the scan's usual case), and the others get eigenvectors and residual bounds. On a GPU (Jacobi, no such a-priori bound) every cluster
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
    resolved_sign,
    value_bounds,
    values_backward_error,
    vector_bounds,
)
from ..mechanics.assembly import dof_index, scatter_columns, stack_blocks
from ..mechanics.attribution import PARTS, contact_work, rim_share
from ..mechanics.branches import BOTH, RIGID, consistency, needs_search, s_limits, sign_patterns
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
from ..mechanics.verdicts import CONSISTENT, tally
from ..model.tolerances import EPS
from ..model.vec import rot_dim
from ..solve.device import backend, eigh_stack, residual_norms
from .clusters import adjacency, boundary_rings, lattice_offset, loaded, members, unwrap
from .uncertain import band_parts, batch_margins

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
    (eigenvalues only: path batched-values), and with options["attribute"] its work_parts (G, 5) and rim_share (NaN
    where not unstable)}, or None when none is batchable. `scene` is best the chunk's own (run.chunk_scene): its
    contact blocks are all built. Clusters are grouped by their count of free particles; each group is one stack of
    all its clusters' branches (split to STACK_BYTES). The boundary (`layout`): `loads`; `fixed`, the ring beyond
    held (its contacts with the cluster count, its dofs dropped: no rigid motion, no projection); `embedded:R`; and
    the controls of options["control"]: "elastic" (every contact elastic) and "rim" (the rim held)."""
    lay = layout(scene, centers, member_lists, options)
    reached, free, inner = lay["reached"], lay["free"], lay["inner"]
    local = np.concatenate(reached)
    sizes = np.array([len(m) for m in reached])
    starts = np.r_[0, np.cumsum(sizes)[:-1]]
    blocks = contact_blocks(scene)
    hg = geometric(blocks.blocks)
    parts = {"elastic": blocks.blocks["Hm"] + hg,                        # H_el per contact, and the row sums of |Hm|,
             "rows_m": np.abs(blocks.blocks["Hm"]).sum(axis=2),         # |Hg| that bound ‖|Hm̃|‖∞, ‖|Hg̃|‖∞ (formation)
             "rows_g": np.abs(hg).sum(axis=2)}
    if options.get("uncertainty"):
        parts["uncertainty"] = band_parts(scene, options["uncertainty"])
    pairs = _cluster_contacts(scene, local, sizes, free)
    pairs["sliding"] = scene.at_yield()[pairs["contact"]]
    if lay["focus"]:               # embedded: only the cluster's own contacts slide; its surroundings' stay elastic
        pairs["sliding"] &= inner[pairs["at_p"]] & inner[pairs["at_q"]]
    if options.get("control") == "elastic":
        pairs["sliding"][:] = False
    n_contacts = np.bincount(pairs["cluster"], minlength=len(centers))
    n_sliding = np.bincount(pairs["cluster"], weights=pairs["sliding"],
                            minlength=len(centers)).astype(int)
    n_free = np.bincount(np.repeat(np.arange(len(sizes)), sizes), weights=free, minlength=len(sizes)).astype(int)
    positions, wraps = _positions(scene, centers, local, sizes, pairs)
    ok = (n_contacts > 0) & (n_sliding <= options["max_sliding"]) & (n_free > 0) & ~wraps
    solved = []
    factor = LENGTH_FACTORS[options["metric"]]
    device = options.get("device", "cpu")
    for n in np.unique(n_free[ok]):
        group = np.flatnonzero(ok & (n_free == n))
        for part in _split(group, n * scene.dof_per_particle, n_sliding, STACK_BYTES[device]):
            solved.append(_solve_group(scene, blocks, parts, pairs, part, positions, starts, int(n), factor, n_sliding,
                                       options, lay))
    return _concatenate(solved)


EMBEDDED_INSIDE = 0.5   # embedded: a negative or zero mode is the cluster's when at least this share of its metric norm
                        # is on the cluster's particles (else its surroundings': left out of the counts)


def layout(scene, centers, member_lists: list, options: dict) -> dict:
    """Per cluster: `reached` (the particles whose contacts with the free ones count, sorted), `free` (flat, per
    entry of reached: its dofs are solved for; the others are held), `inner` (flat: the cluster's own particles),
    `rim` (flat: cluster particles with a contact to a particle outside the cluster) and `focus` (whether a mode
    counts only when mostly inside, EMBEDDED_INSIDE). loads: reached = free = the cluster; fixed: the ring beyond
    held; embedded:R: the next R rings free (their contacts elastic, `solve_chunk`), the ring beyond them held,
    particles the scene holds (scene.fixed) held too; control "rim": the cluster with its rim held."""
    kind, R = boundary_rings(options.get("boundary", "loads"))
    control = options.get("control")
    graph = adjacency(scene)
    rim = rim_flags(scene, centers, member_lists, graph)
    if control == "rim":
        kind, R = "rim", 0
    if kind in ("fixed", "embedded"):
        outer = members(scene, centers, options["rings"] + R + 1, graph)
        if kind == "embedded":
            within = members(scene, centers, options["rings"] + R, graph)
            free_lists = [w if scene.fixed is None else w[~scene.fixed[w]] for w in within]
        else:
            free_lists = member_lists
        reached = outer
    else:
        reached, free_lists = member_lists, member_lists
    free = _flag(reached, free_lists, scene.n_particles)
    inner = _flag(reached, member_lists, scene.n_particles)
    rim_flat = _flag(reached, [m[r] for m, r in zip(member_lists, rim)], scene.n_particles)
    if kind == "rim":
        free = inner & ~rim_flat
    return {"reached": reached, "free": free, "inner": inner, "rim": rim_flat, "focus": kind == "embedded"}


def rim_flags(scene, centers, member_lists: list, graph) -> list[np.ndarray]:
    """Per cluster a bool per member: it has a contact with a particle outside the cluster (`scene` must hold the
    ring beyond the clusters: run.reach), or a load like a contact force (clusters.loaded: a contact cut before)."""
    G, N = len(member_lists), scene.n_particles
    owner = np.repeat(np.arange(G), [len(m) for m in member_lists])
    flat = np.concatenate(member_lists)
    X = sp.csr_matrix((np.ones(len(flat)), (owner, flat)), shape=(G, N))
    inside = np.asarray((X @ graph)[owner, flat]).ravel()                  # neighbours in the cluster, itself too
    degree = np.asarray(graph.sum(axis=1)).ravel()[flat]
    return np.split((inside < degree) | loaded(scene)[flat], np.cumsum([len(m) for m in member_lists])[:-1])


def _flag(reached: list, chosen: list, N: int) -> np.ndarray:
    """Flat over the entries of `reached` (sorted per cluster): whether the particle is in that cluster's `chosen`."""
    keys = np.repeat(np.arange(len(reached)), [len(m) for m in reached]) * N + np.concatenate(reached)
    own = np.repeat(np.arange(len(chosen)), [len(m) for m in chosen]) * N + np.concatenate(
        [np.asarray(c, dtype=np.int64) for c in chosen] + [np.zeros(0, dtype=np.int64)])
    return np.isin(keys, own)


def _concatenate(groups: list[dict]) -> dict | None:
    """The groups' columns joined (the `counts` columns too); None when no cluster is batched."""
    if not groups:
        return None
    out = {key: np.concatenate([g[key] for g in groups]) for key in groups[0] if key != "counts"}
    out["counts"] = {key: np.concatenate([g["counts"][key] for g in groups]) for key in groups[0]["counts"]}
    return out


def _positions(sub, centers: np.ndarray, local: np.ndarray, sizes: np.ndarray, pairs: dict):
    """The particles' positions of every cluster (`local`, the clusters' members one after the other); in a periodic
    chunk each cluster unwrapped from its centre along its contacts (clusters.unwrap, as `subscene` does), so that
    its rigid rotations are those of the extracted cluster. Also which clusters wrap around the cell: they are left
    to `analyze` (whose error names them)."""
    x = sub.x[local]
    if sub.cell is None:
        return x, np.zeros(len(sizes), dtype=bool)
    N = sub.n_particles
    keys = np.repeat(np.arange(len(sizes)), sizes) * N + local
    roots = np.searchsorted(keys, np.arange(len(sizes)) * N + centers)
    shift, loops = unwrap(len(local), pairs["at_p"], pairs["at_q"], sub.image[pairs["contact"]], roots)
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

    at_p, at_q = (np.searchsorted(keys, owner * N + x[contact]) for x in (sub.p, sub.q))
    lp, lq = rank_of[at_p], rank_of[at_q]
    acts = (lp >= 0) | (lq >= 0)                                    # two held particles: no dof of the cluster
    return {"cluster": owner[acts], "contact": contact[acts], "lp": lp[acts], "lq": lq[acts], "at_p": at_p[acts],
            "at_q": at_q[acts]}


def _solve_group(sub, blocks, parts, pairs, part, positions, starts, n, factor, n_sliding, options, lay) -> dict:
    """Row fields of the clusters `part` (all with n free particles): see the module docstring and `_stack`.
    embedded (lay["focus"]): an eigenpair counts only when at least EMBEDDED_INSIDE of its metric norm is on the
    cluster's own particles if it is negative or zero; the others are the surroundings' and are left out like rigid
    ones (code RIGID)."""
    device = options.get("device", "cpu")
    st = _stack(sub, blocks, parts, pairs, part, positions, starts, n, factor, n_sliding, options, lay)
    G, dofs, Ms = len(part), st["base"].shape[1], st["Ms"]
    values_only = (n_sliding[part] == 0) & (device == "cpu")
    solved = _values_first(st, values_only, dofs, lay["focus"])
    vectors = np.flatnonzero(~values_only)
    if vectors.size:
        PA, PS = (np.ascontiguousarray(st[k][vectors][:, :, :Ms]) for k in ("PA", "PS"))   # the branches' columns
        solved.append((vectors, _vectors(st["base"][vectors], PA, PS, st["update"][vectors],
                                         n_sliding[part][vectors], st["formation"][vectors], st["s_tol"][vectors],
                                         st["s_floor"][vectors], dofs, device,
                                         _inside(st, vectors, sub.dof_per_particle) if lay["focus"] else None)))
    owner = np.concatenate([which[got["owner"]] for which, got in solved])
    lam, bounds, codes, hinges, special, error = (np.concatenate([got[key] for _, got in solved])
                                                  for key in ("lam", "bounds", "codes", "hinges", "special", "error"))
    relative = error / np.maximum(np.abs(lam).max(axis=1), 1e-300)
    bad = np.zeros(G, dtype=bool)
    np.logical_or.at(bad, owner, special)
    flat_owner = np.repeat(owner, dofs)
    counts = tally(lam.ravel(), bounds.ravel(), codes.ravel(), hinges.ravel(), flat_owner, G)
    lam_min = np.full(G, np.inf)
    np.minimum.at(lam_min, flat_owner, np.where(codes == RIGID, np.inf, lam).ravel())
    residual = np.zeros(G)
    np.maximum.at(residual, owner, relative)
    g, m = st["g"], st["m"]
    undetermined = np.bincount(g, weights=blocks.rolling_undetermined[m], minlength=G).astype(int)
    keep = ~bad
    out = {"position": part[keep], "counts": {k: v[keep] for k, v in counts.items()},
           "n_branches": np.bincount(owner, minlength=G)[keep],
           "lambda_min": np.where(np.isfinite(lam_min), lam_min, np.nan)[keep], "eigen_residual": residual[keep],
           "rigid_leakage": st["leakage"][keep], "n_undetermined": undetermined[keep],
           "n_contacts": np.bincount(g, minlength=G)[keep], "n_sliding": n_sliding[part][keep],
           "values_only": values_only[keep]}
    if options.get("uncertainty"):                # issue 42: the band factors the bound proves (scan/uncertain.py)
        got = batch_margins(parts["uncertainty"], blocks, st, _modes(st, solved), lam, bounds, owner, G)
        out.update({key: value[keep] for key, value in got.items()})
    if options.get("attribute"):
        work, share, value = _attribution(blocks, st, solved, n)
        scaled = work * (lam_min / value)[:, None]     # |v|² = lambda_min / λ_mode: the parts sum to lambda_min
        out.update(work_parts=scaled[keep], rim_share=share[keep])
    return out


def _stack(sub, blocks, parts, pairs, part, positions, starts, n, factor, n_sliding, options, lay) -> dict:
    """The stacked problem of the clusters `part`: entries g (cluster), m (contact), idx (local dofs; held dofs
    numbered nd, which the scatters drop: assembly.dof_index, stack_blocks), Dp (their metric scale), the sliding
    entries' columns, base (sym(H_el), or sym(Qᵀ H_el Q) off the rigid motions), PA, PS, bounds' inputs, and per
    free particle `inner` and `rim` (G, n). The sliding factors A, S have max_sliding columns whichever clusters
    share the stack, for every per-cluster product and norm: their rounding depended on the column count (numpy and
    BLAS pick kernels by shape; one column is another path), so a row is the same bits however the scan is chunked
    (serially, on any number of workers, resumed; tested). The branches' work takes the stack's most columns only."""
    d, r = sub.dim, rot_dim(sub.dim)
    per = d + r
    nd = n * per
    G = len(part)
    width = options["max_sliding"]
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
    slide = pairs["sliding"][sel]
    gs, ms = g[slide], m[slide]
    col = _rank_within(gs)
    Ms = int(n_sliding[part].max())
    A, S = (scatter_columns(f[ms] * Dp[slide], gs, idx[slide], col, G, nd, width if Ms else 0)   # docstring
            for f in (blocks.slide_left, blocks.slide_right))
    scales = (abs_norm(parts["rows_m"]) + abs_norm(parts["rows_g"])
              + _column_sum(np.linalg.norm(A, axis=1) * np.linalg.norm(S, axis=1)))
    s_tol, s_floor = s_limits(S, sub.tol)                  # branches.Problem.s_tol, s_floor
    lengths = np.diff(np.r_[starts, len(lay["free"])])[part]
    entries = np.repeat(starts[part] - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
    free_entries = entries[lay["free"][entries]]                                      # (G·n,) in cluster order
    out = {"g": g, "m": m, "idx": idx, "Dp": Dp, "slide": slide, "col": col, "Ms": Ms, "L": L, "nd": nd,
           "inner": lay["inner"][free_entries].reshape(G, n), "rim": lay["rim"][free_entries].reshape(G, n),
           "s_tol": s_tol, "s_floor": s_floor, "Q": None}
    if lay["free"][entries].all():  # off the rigid motions: QᵀH Q, QᵀA, QᵀS (_reduced)
        x = positions[free_entries].reshape(G, n, d)
        out["C"] = rotation_columns(x, L)
        out["formation"], out["leakage"], out["Q"], out["base"], out["PA"], out["PS"] = _reduced(H_el, A, S, x, L,
                                                                                                 scales)
        out["formation"] = out["formation"] + curvature
    else:                          # held: no rigid motion, P^nrr = I (eq:Pnrr), formation 8ε of the parts
        out.update(formation=8 * EPS * scales + curvature, leakage=np.zeros(G), base=0.5 * (H_el + np.swapaxes(H_el, 1, 2)),
                   PA=A, PS=S)
    out["update"] = _update_norm(out["PA"], out["PS"])
    return out


def _inside(st: dict, which: np.ndarray, per: int) -> np.ndarray:
    """W (G', n, n) of the clusters `which` of a stack (embedded): vᵀ W v is the squared metric norm of v on the
    cluster's own dofs, W = diag(inner), or QᵀWQ off the rigid motions."""
    mark = np.repeat(st["inner"][which], per, axis=1).astype(float)
    Q = st["Q"]
    return (np.einsum("gij,gi,gik->gjk", Q[which], mark, Q[which]) if Q is not None
            else mark[:, :, None] * np.eye(mark.shape[1])[None])


def _modes(st: dict, solved: list) -> dict:
    """Each cluster's lowest consistent negative mode gathered from the solved parts: `mode` (G,) whether it has one,
    its scaled vector (G, nd), eigenvalue, bound and branch mask (`signs`, (G, Ms)); `U` (P', n) its physical motion
    U = D P (Q y) (loads) or D y (held) over the local dofs of the entries `take` (P,) of clusters with a mode."""
    G = len(st["inner"])
    mode = np.full(G, False)
    vec, value, bound = np.zeros((G, st["base"].shape[1])), np.full(G, np.nan), np.full(G, np.nan)
    signs = np.zeros((G, st["PA"].shape[2]), dtype=np.int8)
    for which, got in solved:
        has = got["mode_has"]
        mode[which[has]] = True
        vec[which[has]] = got["mode_vector"][has]
        value[which[has]] = got["mode_value"][has]
        bound[which[has]] = got["mode_bound"][has]
        signs[which[has], :got["mode_signs"].shape[1]] = got["mode_signs"][has]
    w = vec[:, :, None] if st["Q"] is None else st["Q"] @ vec[:, :, None]          # (G, nd, 1) scaled
    u = w if st["Q"] is None else Projection.from_rotations(st["C"]).apply(w)
    u = np.concatenate([u[:, :, 0], np.zeros((G, 1))], axis=1)                     # the held dof nd: zero
    take = mode[st["g"]]
    U = st["Dp"][take] * u[st["g"][take][:, None], st["idx"][take]]
    return {"mode": mode, "w": w, "value": value, "bound": bound, "signs": signs, "take": take, "U": U}


def _attribution(blocks, st: dict, solved: list, n: int):
    """Work parts (G, 5), rim share (G,) and eigenvalue (G,) of each cluster's lowest consistent negative mode
    (NaN where it has none), by attribution.contact_work on U = D P (Q y) (loads) or D y (held), y unit: the parts
    sum to its eigenvalue."""
    G = len(st["inner"])
    work, share = np.full((G, len(PARTS)), np.nan), np.full(G, np.nan)
    got = _modes(st, solved)
    mode, take, value = got["mode"], got["take"], got["value"]
    if not mode.any():
        return work, share, value
    g, m = st["g"], st["m"]
    sliding = np.zeros(len(g), dtype=bool)
    sliding[np.flatnonzero(st["slide"])] = got["signs"][g[st["slide"]], st["col"]] == 1
    per_entry = contact_work(blocks, m[take], got["U"], sliding[take])
    for j in range(len(PARTS)):
        work[:, j] = np.where(mode, np.bincount(g[take], weights=per_entry[:, j], minlength=G), np.nan)
    weights = (got["w"][:, :, 0] ** 2).reshape(G, n, -1).sum(axis=2)
    share = np.where(mode, rim_share(weights, st["rim"], st["inner"]), np.nan)
    return work, share, value


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
    return formation, leakage, Q, *on_complement(Q, H_el, A, S)


def _values_first(st: dict, values_only: np.ndarray, nd: int, focus: bool) -> list:
    """The clusters `values_only` (no sliding contact, CPU) of a stack solved for eigenvalues only (`_values`), as
    [(their positions, _values)], or []. focus (embedded): a mode is left out when it lies mostly outside the
    cluster, which takes its vector; so only clusters whose eigenvalues are all proven positive (no mode can be
    left out, no search needed) keep the values; the others are taken out of `values_only` (in place) for the
    eigenvectors."""
    values = np.flatnonzero(values_only)
    if not values.size:
        return []
    got = _values(st["base"][values], st["formation"][values], nd)
    if focus:
        kept = (got["lam"][:, 0] > got["bounds"][:, 0]) & ~got["special"]
        values_only[values[~kept]] = False
        values = values[kept]
        got = {key: np.arange(kept.sum()) if key == "owner" else value[kept] for key, value in got.items()}
    return [(values, got)] if values.size else []


def _values(Hsym, formation, nd: int) -> dict:
    """Clusters without sliding contacts (one branch, every eigenpair consistent): eigenvalues only (LAPACK syevd
    without vectors, ~0.45× the cost of eigh at n ≈ 80), each with the a-priori bound of accuracy.value_bounds."""
    with backend("cpu").threads(nd):
        lam = np.linalg.eigvalsh(Hsym)
    scale = abs_norm_inf(Hsym)[:, None]
    bounds = value_bounds(lam, scale, formation[:, None], nd)
    has = lam[:, 0] < -bounds[:, 0]                          # unstable: the lowest mode's vector, for attribution
    vector = np.zeros((len(Hsym), nd))
    if has.any():
        with backend("cpu").threads(nd):
            vector[has] = np.linalg.eigh(Hsym[has])[1][:, :, 0]
    return {"owner": np.arange(len(Hsym)), "lam": lam, "bounds": bounds, "codes": np.full(lam.shape, BOTH, np.int8),
            "hinges": np.zeros(lam.shape, dtype=bool), "special": needs_search(lam, bounds),
            "error": values_backward_error(scale[:, 0], nd), "mode_has": has, "mode_vector": vector,
            "mode_signs": np.zeros((len(Hsym), 0), dtype=np.int8), "mode_value": lam[:, 0],
            "mode_bound": bounds[:, 0]}


def _vectors(base, PA, PS, update, n_sliding, formation, s_tol, s_floor, nd: int, device: str,
             inside: np.ndarray | None = None) -> dict:
    """Every branch (enumerate_masks order) of the clusters `base` (sym(Qᵀ H_el Q), or sym(H_el) held), stacked
    eigh on the backend, residual bounds (accuracy.vector_bounds) and consistency codes (Appendix D) from the S
    values (PSᵀ y = Sᵀ Q y: those of the eigenvector in the cluster's dofs); inside (G, n, n) (embedded): a
    negative or zero eigenpair (λ <= its bound) with less than EMBEDDED_INSIDE of its norm there gets code RIGID (the
    surroundings', not the cluster's; positive ones change no verdict and all count). Also each
    cluster's lowest consistent negative eigenpair (`_lowest`)."""
    Ms = PA.shape[2]
    owner, masks = sign_patterns(n_sliding, Ms)
    Hsym = base[owner]
    loading = np.flatnonzero((masks == 1).any(axis=1))
    if loading.size:                                # + ½(X + Xᵀ), X = a diag(on) sᵀ: exactly symmetric, as `base` is
        X = (PA[owner[loading]] * (masks[loading] == 1)[:, None, :]) @ np.swapaxes(PS[owner[loading]], 1, 2)
        X += np.swapaxes(X, 1, 2)
        Hsym[loading] += 0.5 * X
    got = backend_eigh(Hsym, PS[owner], device, None if inside is None else inside[owner])
    lam = got["lam"]
    scale = (abs_norm_inf(base) + update)[owner]     # >= ‖|Hsym|‖∞ of every branch (update: _update_norm)
    bounds = vector_bounds(lam, got["residual"], scale[:, None], formation[owner, None], nd)
    codes, hinges = consistency(masks[:, :, None].astype(float), got["S"], s_tol[owner, None, None],
                                s_floor[owner, None, None])
    if inside is not None:
        codes = np.where((got["inside"] < EMBEDDED_INSIDE) & (lam <= bounds), RIGID, codes).astype(codes.dtype)
    return {"owner": owner, "lam": lam, "bounds": bounds, "codes": codes, "hinges": hinges,
            "special": needs_search(lam, bounds), "error": got["residual"].max(axis=1),
            **_lowest(lam, bounds, codes, got["V"], owner, masks, len(base))}


def _lowest(lam, bounds, codes, V, owner, masks, G: int) -> dict:
    """Per cluster its lowest consistent negative eigenpair over its branches: mode_has (G,), mode_vector (G, n),
    mode_signs (G, Ms) (the branch's mask)."""
    negative = np.isin(codes, CONSISTENT) & (resolved_sign(lam, bounds) < 0)
    score = np.where(negative, lam, np.inf)
    j = score.argmin(axis=1)
    value = score[np.arange(len(score)), j]
    order = np.lexsort((value, owner))
    first = order[np.r_[True, owner[order][1:] != owner[order][:-1]]]           # per cluster its lowest branch
    has = np.zeros(G, dtype=bool)
    vector, signs = np.zeros((G, V.shape[1])), np.zeros((G, masks.shape[1]), dtype=np.int8)
    has[owner[first]] = np.isfinite(value[first])
    vector[owner[first]] = V[first, :, j[first]]
    signs[owner[first]] = masks[first]
    mode_value, mode_bound = np.full(G, np.nan), np.full(G, np.nan)
    mode_value[owner[first]] = value[first]
    mode_bound[owner[first]] = bounds[first, j[first]]
    return {"mode_has": has, "mode_vector": vector, "mode_signs": signs, "mode_value": mode_value,
            "mode_bound": mode_bound}


def backend_eigh(Hsym: np.ndarray, S: np.ndarray, device: str, inside: np.ndarray | None = None) -> dict:
    """Stacked eigh of sym(𝓗^i) on the device: eigenvalues, eigenvectors, residual norms ‖A v − λ v‖ and the S
    values Sᵀ v (eq:flow) of the eigenvectors, whatever their signs (a row counts consistent modes, PLUS, MINUS or
    BOTH alike); with `inside` (L, n, n), each eigenvector's vᵀ inside v (its squared norm on the cluster)."""
    be = backend(device)

    def keep(xp, A, lam, V, start):
        Sd = be.asarray(S[start:start + A.shape[0]])
        out = {"lam": lam, "V": V, "residual": residual_norms(xp, A, lam, V),
               "S": xp.matmul(xp.swapaxes(Sd, 1, 2), V)}
        if inside is not None:
            out["inside"] = xp.sum(V * xp.matmul(be.asarray(inside[start:start + A.shape[0]]), V), axis=1)
        return out

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
