"""Verdicts of Sec. 3: stability (eq:stab, eq:neutral, eq:instab), Type-1 and Type-2 non-uniqueness (Sec. 3.1),
and the second-order work of a given motion (eq:newinner, softening).

The conditions are the paper's sufficient ones: a consistent negative eigenvalue of some sym(𝓗^i) proves
instability, a consistent non-rigid zero proves neutral stability, and all branches positive definite off the
rigid modes proves stability. A negative eigenvalue whose eigenvector is not consistent proves nothing (Sec. 3.2);
the summary then says that stability is not proven instead of claiming it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from .accuracy import resolved_sign
from .branches import BOTH, MINUS, PLUS, RIGID, branch_matrices, test_codes
from .stiffness import stiffness

CONSISTENT = (PLUS, MINUS, BOTH)
COUNTS = ("consistent_positive", "consistent_negative", "consistent_zero")
TOTALS, LOWER = "totals", "lower bounds"


@dataclass(frozen=True)
class MetricVerdict:
    """One metric's line of a family verdict (issue 11): `Verdict.metrics`."""

    metric: str
    rotation_length: float | None
    verdict: str
    sufficient: bool
    consistent_positive: int
    consistent_negative: int

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Verdict:
    """The verdict of one cluster (eq:stab, eq:neutral, eq:instab) with its reason and whether it is a proof.

    `sufficient` is True exactly when `insufficient_because` is empty. `counts_are` says per count of COUNTS whether
    it is a total or a lower bound; `suggest_k` is set where the sparse path's spectrum is partial. `metrics` and
    `metric_robust` are the metric family's (empty and None for one metric). `to_dict()` is the `summary` object of
    `granstab analyze --json`. A frozen record: the steps that refine it (`finalize`, `mark_partial`,
    `flag_undetermined`) return new ones."""

    verdict: str
    reason: str
    insufficient_because: tuple[str, ...]
    consistent_positive: int
    consistent_negative: int
    consistent_zero: int
    counts_are: tuple[tuple[str, str], ...]
    type2_nonuniqueness: bool
    hinges_on_tolerance: bool
    n_branches: int
    zero_margin: float | None
    suggest_k: int | None = None
    metrics: tuple[MetricVerdict, ...] = ()
    metric_robust: bool | str | None = None
    counts_robust: bool | None = None
    metric_flips: tuple = ()
    branches: str = "all"
    branches_kept: int | None = None
    free_spins: int = 0

    @property
    def sufficient(self) -> bool:
        return not self.insufficient_because

    def weaker(self, because: tuple[str, ...] = (), reason: str = "", **changes) -> Verdict:
        """This verdict with more reasons why it is not a proof and `reason` appended to its reason."""
        return replace(self, insufficient_because=self.insufficient_because + tuple(because),
                       reason=self.reason + reason, **changes)

    def to_dict(self) -> dict:
        """The JSON summary (`granstab analyze --json`): lists for tuples, `suggest_k` only where it is set."""
        out = {"verdict": self.verdict, "sufficient": self.sufficient,
               "insufficient_because": list(self.insufficient_because), "reason": self.reason,
               **{key: getattr(self, key) for key in COUNTS}, "counts_are": dict(self.counts_are),
               "type2_nonuniqueness": self.type2_nonuniqueness, "hinges_on_tolerance": self.hinges_on_tolerance,
               "n_branches": self.n_branches, "zero_margin": self.zero_margin}
        if self.suggest_k is not None:
            out["suggest_k"] = self.suggest_k
        return {**out, "metrics": [e.to_dict() for e in self.metrics], "metric_robust": self.metric_robust,
                "counts_robust": self.counts_robust, "metric_flips": list(self.metric_flips),
                "branches": self.branches, "branches_kept": self.branches_kept, "free_spins": self.free_spins}


@dataclass(frozen=True)
class ModeWork:
    """One consistent negative eigenpair's second-order work split by part (attribution.PARTS; they sum to
    `eigenvalue`, the eigenvector unit in the verdict's metric) and its share on the rim (attribution.rim_share)."""

    branch: int
    index: int
    eigenvalue: float
    work_parts: tuple[float, ...]
    rim_share: float

    def to_dict(self) -> dict:
        return {**asdict(self), "work_parts": list(self.work_parts)}


@dataclass(frozen=True)
class Attribution:
    """Why an unstable cluster is unstable (issue 25, attribution.py): its `mechanism` label, the work parts and rim
    share of its lowest consistent negative mode, the verdicts of the two controls (every contact elastic; the rim
    held fixed) and every consistent negative mode's parts (`modes`)."""

    mechanism: str
    work_parts: tuple[float, ...]
    rim_share: float
    elastic_control: str
    fixed_control: str
    modes: tuple[ModeWork, ...]

    def to_dict(self) -> dict:
        from .attribution import PARTS
        return {"mechanism": self.mechanism, "work_parts": dict(zip(PARTS, self.work_parts)),
                "rim_share": self.rim_share, "elastic_control": self.elastic_control,
                "fixed_control": self.fixed_control, "modes": [m.to_dict() for m in self.modes]}

    def line(self) -> str:
        """One line for a verdict panel or a report."""
        from .attribution import PARTS
        parts = ", ".join(f"{n} {v:+.2e}" for n, v in zip(PARTS, self.work_parts))
        return (f"mechanism: {self.mechanism} — work of the lowest negative mode: {parts}; rim share "
                f"{self.rim_share:.0%}; all elastic: {self.elastic_control}, rim held: {self.fixed_control}")


def frequencies_and_growth(lam: np.ndarray, accuracy) -> tuple[np.ndarray, np.ndarray]:
    """In the inertia metric (λ = ω²): the frequencies √λ of the eigenvalues resolved positive (λ > accuracy) and
    the growth rates √(−λ) of those resolved negative (λ < −accuracy), each in the eigenvalues' order."""
    return np.sqrt(lam[lam > accuracy]), np.sqrt(-lam[lam < -accuracy])


def summarize(branches, notes: dict | None = None) -> Verdict:
    """Counts of consistent eigenvalues over all branches and the verdict with its reason (`tally`, `verdict_of`).

    `notes` from the backend: complete = False when negative eigenvalues may lie beyond the computed ones (sparse
    path), suggest_k; tally and n_branches when the backend kept only some branches (counts over all of them).
    """
    notes = notes or {}
    counts = notes.get("tally") or branch_tally(branches)
    return verdict_of(counts, notes, n_branches=notes.get("n_branches", len(branches)),
                      type2=any(b.type2 for b in branches))


def branch_tally(branches) -> dict:
    """`tally` of a list of Branch objects, as one group (scalars)."""
    parts = [(b.stability_eigenvalues, b.accuracy, b.codes, b.hinges) for b in branches]
    lam, acc, codes, hinges = (np.concatenate([p[i] for p in parts]) if parts else np.empty(0) for i in range(4))
    return {key: value[0] for key, value in tally(lam, acc, codes, hinges.astype(bool),
                                                  np.zeros(len(lam), dtype=np.int64), 1).items()}


def merge_tallies(a: dict | None, b: dict) -> dict:
    """Two one-group tallies as one (counts add, flags or, the margin is the smaller)."""
    if a is None:
        return dict(b)
    return {key: (min(a[key], b[key]) if key == "margin" else a[key] + b[key] if key in COUNTED else
                  bool(a[key] or b[key])) for key in a}


COUNTED = ("pos", "neg", "zero", "proven_zero")


def tally(lam, acc, codes, hinges, owner, n_groups: int) -> dict:
    """Per group (e.g. the branches of one cluster) the counts the verdict rests on, from flat per-eigenvalue arrays
    (`owner`: the group of each eigenvalue), vectorised over any number of groups.

    Signs come from each eigenvalue's accuracy bound (accuracy.py): |λ| > δ counts with its sign; |λ| <= δ is a zero
    within accuracy whose sign is not determined (an exact zero only when λ = δ = 0). margin = the smallest |λ|/δ
    over every non-rigid eigenvalue, zeros included (< 1: some sign is not resolved).
    """
    def count(flags):
        if n_groups == 1:                                               # one cluster (summarize): a plain sum
            return np.array([np.count_nonzero(flags)], dtype=np.int64)
        return np.bincount(owner, weights=flags, minlength=n_groups).astype(np.int64)

    def any_(flags):
        return count(flags) > 0

    sign = resolved_sign(lam, acc)
    exact = (lam == 0) & (acc == 0)
    nonrigid = codes != RIGID
    ok = np.isin(codes, CONSISTENT)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(acc > 0, np.abs(lam) / acc, np.where(exact, np.inf, np.nan))
    ratio = np.where(nonrigid & ~np.isnan(ratio), ratio, np.inf)
    margin = np.full(n_groups, np.inf)
    np.minimum.at(margin, owner, ratio)
    return {"pos": count(ok & (sign > 0)), "neg": count(ok & (sign < 0)), "zero": count(ok & (sign == 0)),
            "proven_zero": count(ok & exact), "hinge": any_(hinges & ok & (sign <= 0)),
            "inconsistent_negative": any_(~ok & nonrigid & (sign < 0)),
            "unresolved_other": any_(~ok & nonrigid & (sign == 0) & ~exact),
            "non_finite": any_(~(np.isfinite(lam) & np.isfinite(acc))), "margin": margin}


def verdict_of(counts: dict, notes: dict | None, n_branches: int, type2: bool = False) -> Verdict:
    """The verdict of one cluster from its `tally` counts: verdict (eq:stab, eq:neutral, eq:instab), reason,
    whether it is a proof (`insufficient_because`) and the counts."""
    notes = notes or {"complete": True}
    neg, zero, proven_zero = int(counts["neg"]), int(counts["zero"]), int(counts["proven_zero"])
    because = []
    complete = notes.get("complete", True)
    if neg:
        verdict = "unstable"
        reason = (f"{neg} consistent negative eigenvalue(s) of sym(𝓗^i), each below minus its accuracy bound: "
                  "negative second-order work (eq:instab)")
    elif zero:
        verdict = "neutral"
        reason = f"{zero} consistent non-rigid zero eigenvalue(s): zero second-order work (eq:neutral)"
        if proven_zero < zero:
            because.append("unresolved_sign")
            reason += (f"; NOT DETERMINED: {zero - proven_zero} of them zero only within their accuracy bound — "
                       "their sign is not resolved in double precision")
    elif not complete:
        verdict = "not determined"
        because.append("partial_spectrum")
        reason = ("no consistent negative or zero eigenpair among the computed ones, but negative eigenvalues beyond "
                  "them are not excluded; " + notes.get("partial_because", f"rerun with k >= {notes.get('suggest_k', '?')}"))
    else:
        verdict = "stable"
        reason = "every branch positive definite off the rigid modes (eq:stab)"
        if counts["inconsistent_negative"]:
            because.append("inconsistent_negative")
        if counts["unresolved_other"]:
            because.append("unresolved_sign")
        if because:
            reason = ("no consistent negative or zero eigenmode, but some eigenvalues are negative or zero (within "
                      "accuracy) with inconsistent eigenvectors: the sufficient condition of eq:stab is not met "
                      "(Sec. 3.2)")
    if counts["non_finite"]:
        because.append("non_finite")
    margin = float(counts["margin"])
    totals = (notes.get("full", complete), complete, complete)
    return Verdict(verdict=verdict, reason=reason, insufficient_because=tuple(because),
                   consistent_positive=int(counts["pos"]), consistent_negative=neg, consistent_zero=zero,
                   counts_are=tuple((key, TOTALS if total else LOWER) for key, total in zip(COUNTS, totals)),
                   type2_nonuniqueness=bool(type2), hinges_on_tolerance=bool(counts["hinge"]),
                   n_branches=n_branches, zero_margin=None if not np.isfinite(margin) else margin,
                   suggest_k=None if complete else notes.get("suggest_k"))


# the tally counts a row's verdict, reason and proof flags depend on (verdict_of, finalize), besides n_branches,
# the errors' finiteness and undetermined rolling
KEYED = ("neg", "zero", "proven_zero", "inconsistent_negative", "unresolved_other", "non_finite")


def verdict_columns(counts: dict, n_branches: np.ndarray, errors_finite: np.ndarray,
                    n_undetermined: np.ndarray) -> dict:
    """`verdict_of` then `finalize` (one metric) of many clusters, from their `tally` columns: evaluated once per
    distinct input (verdict, reason and flags depend only on these), then spread over the clusters; the counts that
    vary freely (consistent_positive, the zero margin) are each cluster's own."""
    key = np.column_stack([np.asarray(counts[k], dtype=np.int64) for k in KEYED]
                          + [n_branches, errors_finite, n_undetermined]).astype(np.int64)
    distinct, inverse = np.unique(key, axis=0, return_inverse=True)
    fields = ("verdict", "sufficient", "insufficient_because", "reason")
    table = {field: [] for field in fields}
    for row in distinct:
        v = verdict_of({**dict(zip(KEYED, row)), "pos": 0, "hinge": False, "margin": np.inf}, None,
                       n_branches=int(row[-3]))
        v = finalize(v, {"errors": 0.0 if row[-2] else np.nan}, int(row[-1]), None)
        for field in fields:
            value = getattr(v, field)
            table[field].append(",".join(value) if field == "insufficient_because" else value)
    spread = {field: np.array(values, dtype=bool if field == "sufficient" else object)[inverse.reshape(-1)]
              for field, values in table.items()}
    margin = np.asarray(counts["margin"], dtype=float)
    return {**spread, "consistent_negative": np.asarray(counts["neg"], dtype=np.int64),
            "consistent_positive": np.asarray(counts["pos"], dtype=np.int64),
            "zero_margin": np.where(np.isfinite(margin), margin, np.nan)}


def family_entry(metric, verdict: Verdict) -> MetricVerdict:
    """One metric's line of a family verdict (issue 11)."""
    return MetricVerdict(metric=metric.name, rotation_length=metric.rotation_length, verdict=verdict.verdict,
                         sufficient=verdict.sufficient, consistent_positive=verdict.consistent_positive,
                         consistent_negative=verdict.consistent_negative)


def finalize(verdict: Verdict, errors: dict, n_undetermined: int, entries: list | None, robustness=None,
             masses: bool = False) -> Verdict:
    """The verdict's last word on sufficiency: non-finite error estimates, undetermined rolling (flag_undetermined)
    and, over the metric family `entries` (MetricVerdict), `counts_robust` (every metric's verdict and counts equal)
    and `metric_robust`, the proven answer of robustness.metric_robustness (True, False or "undetermined"; without
    it False where two metrics prove different verdicts, else "undetermined")."""
    if not all(np.isfinite(v) for v in errors.values()) and "non_finite" not in verdict.insufficient_because:
        verdict = verdict.weaker(("non_finite",))
    verdict = flag_undetermined(verdict, n_undetermined)
    if entries is not None:
        key = ("verdict", "consistent_positive", "consistent_negative")
        counts = all(tuple(getattr(e, k) for k in key) == tuple(getattr(entries[0], k) for k in key)
                     for e in entries)
        proven = {e.verdict for e in entries if e.sufficient}
        robust = robustness.robust if robustness is not None else False if len(proven) > 1 else "undetermined"
        flips = robustness.flips if robustness is not None else ()
        # a contradiction: another metric PROVES a different verdict (one that only leaves the sign unresolved,
        # e.g. an eigenvalue scaled below its accuracy bound, is listed but contradicts nothing)
        contradicted = any(e.verdict != verdict.verdict and e.sufficient for e in entries) or bool(flips)
        depends = len({e.verdict for e in entries}) > 1
        reason = ("; the verdict depends on the projection metric: "
                  + ", ".join(f"{e.metric} {e.verdict}" for e in entries) if depends else "")
        if flips:
            reason += ("; proven to change with the rotation length at L = "
                       + ", ".join(f"{v:.4g}" for v in flips))
        if robust is not True:
            reason += ("; the inertia metric (kinetic energy) is the physical answer" if masses else
                       "; give masses for the physical answer (the inertia metric)")
        verdict = verdict.weaker(("metric_dependent",) if contradicted else (), reason, metrics=tuple(entries),
                                 metric_robust=robust, counts_robust=counts, metric_flips=tuple(flips))
    if "non_finite" in verdict.insufficient_because:
        verdict = verdict.weaker(reason="; NOT DETERMINED: some computed numbers are not finite (overflow)")
    return verdict


def mark_partial(verdict: Verdict, examined: int, Ms: int) -> Verdict:
    """A sample of the 2^Ms branches was examined: a proven instability stands (one consistent negative eigenvalue
    suffices, eq:instab); any other verdict could change on an unexamined branch."""
    proven = verdict.verdict == "unstable" and verdict.sufficient
    return verdict.weaker(() if proven else ("unexamined_branches",),
                          f"; {examined} of the 2^{Ms} branches examined (a sample)",
                          counts_are=tuple((key, LOWER) for key, _ in verdict.counts_are), branches="partial")


def flag_undetermined(verdict: Verdict, n_bad: int) -> Verdict:
    """Where a loaded contact's rolling is undetermined (K^p + K^q singular: the pseudo-inverse cut-off decides),
    the verdict is not a proof: insufficient because of it, hinges_on_tolerance = True, and the reason says why."""
    if not n_bad:
        return verdict
    return verdict.weaker(("rolling_undetermined",),
                          f"; NOT DETERMINED: {n_bad} loaded contact(s) with K^p + K^q singular (flat-on-flat or "
                          "exact hand-in-glove) — their rolling is undetermined and the verdict rests on the "
                          "pseudo-inverse cut-off (pinv_rtol)", hinges_on_tolerance=True)


def _require_no_supports(analysis) -> None:
    if analysis.problem.free is not None:
        raise ValueError(f"{analysis.scene.source}: load responses and second-order work are not implemented for "
                         "scenes with fixed particles yet (the verdicts are)")


def load_response(analysis, load_increment, rtol: float = 1e-8) -> dict:
    """Solve ℍ^i dU = d𝕓 on every branch of `analysis` (eq:problem) and test each solution's consistency (Sec. 3.1).

    Parameters
    ----------
    analysis : Analysis
        An analysis of a scene without fixed particles (its branches and metric are used).
    load_increment : array_like, (n_dof,)
        Objective load increments [d𝕓, d𝕨] particle by particle, in the order of ``scene.dofs()``.
    rtol : float
        A branch's least-squares solution counts only if its relative residual is at most rtol.

    Returns
    -------
    dict
        ``solutions``: per branch ``mask`` (M,), ``residual``, ``consistent``, ``hinges``, ``motion`` (n_dof,)
        (physical, rigid part removed) and ``scaled`` (n_dof,); ``n_consistent``; ``type1_nonuniqueness``: two
        consistent solutions on different branches that differ by more than a rigid motion.
    """
    _require_no_supports(analysis)
    problem = analysis.problem
    metric = analysis.metric
    rhs = metric.physical(np.asarray(load_increment, dtype=float))   # D d𝕓: ℍ̃ Ũ = D H D Ũ
    masks = np.array([b.mask for b in analysis.branches])
    _, HH, _ = branch_matrices(problem, masks)
    solutions = []
    for mask, A in zip(masks, HH):
        x, *_ = np.linalg.lstsq(A, rhs, rcond=None)
        residual = float(np.linalg.norm(A @ x - rhs) / max(np.linalg.norm(rhs), 1e-300))
        x = x - problem.rigid @ (problem.rigid.T @ x)
        code, hinge = (int(c[0, 0]) for c in test_codes(problem, mask[None], x[None, :, None]))
        ok = residual <= rtol and code in (PLUS, BOTH)
        solutions.append({"mask": mask.tolist(), "residual": residual, "consistent": ok, "hinges": bool(hinge),
                          "motion": metric.physical(x), "scaled": x})
    good = [s for s in solutions if s["consistent"]]
    distinct = any(np.linalg.norm(a["scaled"] - b["scaled"]) > 1e-6 * max(np.linalg.norm(a["scaled"]), 1e-300)
                   for i, a in enumerate(good) for b in good[i + 1:])
    return {"solutions": solutions, "n_consistent": len(good), "type1_nonuniqueness": bool(distinct)}


def second_order_work(analysis, motion) -> dict:
    """Second-order work dUᵀ 𝓗^i dU of a motion on the branch its own S signs select (eq:newinner, eq:flow).

    Parameters
    ----------
    analysis : Analysis
        An analysis of a scene without fixed particles.
    motion : array_like, (n_dof,)
        A physical motion [du, dθ] particle by particle (e.g. ``analysis.motion(vector)``); its rigid rotation is
        projected out (eq:Pnrr).

    Returns
    -------
    dict
        ``mask`` (M,) the branch, ``work`` = ``geometric`` (Hg1 + Hg2 + Hg3) + ``mechanical`` (Hm); negative work
        means softening along the motion (Sec. 3.2).
    """
    _require_no_supports(analysis)
    problem, scene = analysis.problem, analysis.scene
    metric = analysis.metric
    u = metric.scaled(np.asarray(motion, dtype=float))
    S = problem.S.T @ u
    mask = np.zeros(scene.n_contacts, dtype=int)
    mask[problem.sliding] = np.where(S > problem.s_tol, 1, -1)
    K = stiffness(scene, mask)
    v = metric.physical(problem.projection.apply(u))                              # physical motion, rigid rotation removed
    geometric = float(v @ (K.Hg1 + K.Hg2 + K.Hg3) @ v)
    mechanical = float(v @ K.Hm @ v)
    return {"mask": mask.tolist(), "work": geometric + mechanical, "geometric": geometric, "mechanical": mechanical}
