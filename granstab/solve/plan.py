"""`plan(scene, **options) -> Plan`: what an analysis will do, decided once (issue 40), and what it will cost
(issue 38): the method (dense or sparse), the branch path (full, low-rank, sparse), the branches per metric and the
metrics, what the run leaves out, and the estimated seconds on this machine's free cores.

`analysis.analyze` follows the plan (its method and path come from here, nothing re-derives them); the CLI's
refusal before work (`Plan.refuse`), `granstab analyze --plan`, `export --modes` and `track --whole` read it.

The estimate is the sum of its parts (`Plan.parts`), each from a cost measured on this machine (budget.py: a timed
probe of the dense kernels in CPU time) or from the sparse path's calibration (budget.sparse_parts: by step and
metric, the Ritz updates of a metric that fall back to ARPACK counted as such):

* branches: every branch in every metric on its path; a low-rank branch that cannot be resolved there (a non-rigid
  zero or repeated eigenvalue: a floppy particle, `floppy`) goes to the full path, and is counted there;
* robustness: the family's proof over every rotation length (dense, every branch: an eigh a branch and a few
  at each crossing, ROBUST_EIGH);
* attribution: an unstable dense result's elastic control (one more branch, one metric), counted whatever the
  verdict (the verdict is not known before the run: on the safe side);
* the parts shared by cores: the low-rank branches run on every FREE core (threads.free_cores), and every part
  takes longer by threads.slowdown() where more processes want a core than there are: a busy machine's estimate
  follows its load, as the measured time does.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..mechanics.metric import family
from ..mechanics.robustness import MAX_WORK as ROBUST_MAX_WORK
from ..model.scene import Scene
from . import budget

MEASURED = ("estimated_s", "estimate_parts", "workers")   # keys of `cost` that depend on the machine and its load
ROBUST_EIGH = 8.0        # the robustness proof: eigh-sized solves a branch (the branch's S, the crossings' bordered
                         # matrices, a complete QR and two products at each interval; measured: a stable 1,200-dof
                         # packing 0.94 s for 2 branches, 1.2 eigh's worth; the unstable annulus frame 0.6-1.4 s for 1
                         # branch of 429 dofs, 10-25 eigh's worth: the intervals cannot be known before the run)
ATTRIBUTION_BRANCHES = 1  # the elastic control: one branch in one metric
OVERHEAD_S = 0.01        # a metric's work outside the kernels (blocks, projections, verdicts; measured 0.02-0.1 s in
OVERHEAD_BRANCH_S = 5e-4  # all on the corpus's small scenes, where the kernels' estimate was 0.005-0.05 s) and a
                          # branch's (its Branch, codes and consistency search in Python: 1,024 3D branches, 3 metrics)


@dataclass(frozen=True)
class Plan:
    """What `analyze` will do with a scene, and its estimated cost (module docstring)."""

    source: str
    method: str                    # "dense" | "sparse"
    path: str                      # "full" | "low_rank" | "sparse"
    n_dof: int                     # the dofs solved (free ones where particles are held)
    n_sliding: int
    n_branches: int                # per metric
    metrics: tuple                 # names, the primary first
    sampled: bool                  # more sliding contacts than max_sliding: a sample of the branches
    refusal: str | None            # why the run cannot start (too many branches, none sampled)
    lowrank: bool
    uniqueness: bool
    attribution: bool
    robustness: bool
    floppy: bool                   # a particle or the packing with fewer constraints than dofs (full-path branches)
    left_out: tuple
    estimated_s: float | None      # None: not estimated (a GPU device)
    parts: dict = field(default_factory=dict)
    workers: int = 1
    one_metric_s: float | None = None   # the primary metric alone (the refusal's alternative to the family)
    deficit: int = 0               # non-rigid modes surely at zero (`deficit`): the sparse path's ARPACK pairs
    fitted: dict | None = None     # the default plan fitted to budget.ASK_SECONDS (`fit`): what that left out
    memory: dict | None = None     # the sparse path's peak memory estimate against what is available (memory.py)
    below: dict = field(default_factory=dict)   # `probe`: per metric, ν of a sample of the branches (sparse path)
    dim: int = 2

    def to_dict(self) -> dict:
        """The `cost` object of `granstab analyze --json --plan` (and the planned part of every run's `cost`)."""
        return {"method": self.method, "path": self.path, "n_dof": self.n_dof, "n_sliding": self.n_sliding,
                "branches_per_metric": self.n_branches, "metrics": len(self.metrics),
                "metric_names": list(self.metrics), "sampled": self.sampled,
                "uniqueness": self.uniqueness, "robustness": self.robustness, "attribution": self.attribution,
                "floppy": self.floppy, "left_out": list(self.left_out), "workers": self.workers,
                "estimated_s": self.estimated_s, "estimate_parts": dict(self.parts), "refusal": self.refusal,
                "fitted": self.fitted, "memory": self.memory,
                "probed_below": {m: [int(v) for v in nu] for m, nu in self.below.items()}}

    def lines(self) -> list[str]:
        """`granstab analyze --plan`: the plan in a few lines, then the estimate."""
        out = [f"{self.source}: plan, nothing run",
               f"method {self.method}, {self.path.replace('_', '-')} path, {self.n_dof} dofs, {self.n_sliding} "
               f"potentially sliding contact(s)",
               f"branches: {self.n_branches} per metric ({'a sample' if self.sampled else 'all'}) × "
               f"{len(self.metrics)} metric(s): {', '.join(self.metrics)}"]
        out += [f"left out: {what}" for what in self.left_out] or ["left out: nothing"]
        if self.refusal:
            out.append(f"refused: {self.refusal}")
        out += fit_lines(self)
        if self.estimated_s is None:
            out.append("estimate: none on a GPU device (the probe times this machine's CPU)")
        else:
            shown = ", ".join(f"{k} {v:.3g} s" for k, v in self.parts.items() if v > 0)
            out.append(f"estimate: {self.estimated_s:.3g} s on {self.workers} free core(s)"
                       + (f" ({shown})" if shown else ""))
        return out

    def refuse(self, seconds_left: float | None) -> None:
        """Raise budget.OverBudget (one line, what to do) when the run cannot start or its estimate exceeds the
        time left (None: budget.ASK_SECONDS, which --timeout lifts); a fitted plan fits it at rest (`fit`)."""
        if self.refusal:
            raise budget.OverBudget(self.refusal)
        if self.estimated_s is None or self.fitted:
            return
        one = (f"--metric L alone (about {self.one_metric_s:.3g} s), " if len(self.metrics) > 1
               else "")
        other = "--method sparse with a small --k, " if self.method == "dense" else ""
        path = self.path.replace("_", "-")
        budget.refuse_over(self.source, self.estimated_s, seconds_left,
                           f"{self.n_branches} branches × {len(self.metrics)} metric(s) of {self.n_dof} dofs "
                           f"({path} path)", one + other)


def floppy(scene: Scene) -> bool:
    """Whether some branch surely has a non-rigid zero eigenvalue, so that the low-rank path hands it to the full
    one (lowrank._special): `deficit` > 0."""
    return deficit(scene) > 0


def deficit(scene: Scene) -> int:
    """Non-rigid modes of the elastic branch surely at zero before the prestress moves them: the dofs of each particle
    beyond its contact constraints (d a frictional contact, the sliding ones counted as 1), summed, or the packing's
    dofs beyond its constraints in all (Maxwell's count, rigid modes off) where that is more."""
    d, per = scene.dim, scene.dof_per_particle
    weight = np.where(scene.at_yield(), 1, d)
    constraints = np.bincount(np.concatenate([scene.p, scene.q]), np.concatenate([weight, weight]),
                              minlength=scene.n_particles)
    held = np.zeros(scene.n_particles, bool) if scene.fixed is None else scene.fixed
    rigid = 0 if held.any() else d + (1 if d == 2 else 3)
    particles = int(np.maximum(per - constraints, 0)[~held].sum())
    return max(particles, per * int(np.sum(~held)) - rigid - int(weight.sum()))


def plan(scene: Scene, *, metric: str = "family", rotation_length: float | None = None, max_sliding: int = 16,
         sample_branches: int | None = None, method: str = "auto", k: int = 6, device: str = "cpu",
         lowrank: bool | None = None, uniqueness: bool = True, attribution: bool = True,
         estimate: bool = True, rest: bool = False, seed: int = 0) -> Plan:
    """The plan of `analyze(scene, **options)` (same options; module docstring); estimate=False skips the estimate
    (and its probes); rest=True estimates for this machine at rest (every core free: `fit`'s choice, which must not
    depend on the load of the moment); seed: the sampled branches' (`probe`)."""
    from .lowrank import use_lowrank
    from .sparse import DENSE_MAX_DOF
    n_sliding = int(np.sum(scene.at_yield()))
    sampled = n_sliding > max_sliding
    refusal = None
    if sampled and sample_branches is None:
        refusal = (f"{scene.source}: {n_sliding} potentially sliding contacts give 2^{n_sliding} branches, more than "
                   f"--max-sliding {max_sliding} allows: examine a sample (--sample-branches N), raise "
                   "--max-sliding (with --timeout to bound the time), set state = \"elastic\" for contacts known "
                   "to stick, or scan local clusters (granstab scan)")
    n_branches = min(sample_branches + 2, 2 ** n_sliding) if sampled and sample_branches is not None \
        else 2 ** min(n_sliding, 62)
    sparse = method == "sparse" or (method == "auto" and scene.n_dof > DENSE_MAX_DOF)
    n = scene.n_dof if scene.free_dofs is None else len(scene.free_dofs)
    names = tuple(m.name for m in family(scene, rotation_length)) if metric == "family" else (metric,)
    names = tuple(sorted(names, key=lambda x: x != "L"))
    gpu = device != "cpu"
    if not sparse and lowrank is None:
        from .device import backend
        lowrank = use_lowrank(n_branches, n, uniqueness) or backend(device).name == "gpu"
    lowrank = bool(lowrank) and not sparse
    path = "sparse" if sparse else "low_rank" if lowrank else "full"
    fam = metric == "family"
    p = Plan(source=scene.source, method="sparse" if sparse else "dense", path=path, n_dof=n, n_sliding=n_sliding,
             n_branches=n_branches, metrics=names, sampled=sampled, refusal=refusal, lowrank=lowrank,
             uniqueness=uniqueness and not sparse, attribution=attribution and not sparse,
             robustness=fam and not sparse and not sampled and scene.fixed is None
             and n_branches * float(n) ** 3 <= ROBUST_MAX_WORK, floppy=lowrank and floppy(scene),
             left_out=(), estimated_s=None, deficit=deficit(scene) if sparse else 0, dim=scene.dim)
    if sparse:
        p = _with_memory(p, scene, device)
    p = _with_left_out(p, k, fam)
    if not estimate or gpu or p.refusal:
        return p
    return _estimated(replace(p, below=probe(scene, p, rotation_length, k, sample_branches, seed)), k, rest)


def _with_memory(p: Plan, scene: Scene, device: str) -> Plan:
    """The sparse plan with its peak memory estimate, refused (one line) where it exceeds what is available."""
    from .device import backend
    from .memory import refusal
    from .sparse import LU_MAX_DOF_3D
    factor = (scene.dim == 2 or p.n_dof <= LU_MAX_DOF_3D) and backend(device).name == "cpu"
    solver = "shift-invert" if factor else "lobpcg"
    info, refused = refusal(scene.source, p.n_dof, scene.n_contacts, scene.dim, solver)
    return replace(p, memory=info, refusal=p.refusal or refused)


def _with_left_out(p: Plan, k: int, fam: bool) -> Plan:
    out = []
    if p.sampled:
        skipped = f"{2 ** p.n_sliding - p.n_branches}" if p.n_sliding <= 40 else f"all but {p.n_branches}"
        out.append(f"{skipped} of the 2^{p.n_sliding} branches (a sample: a proof only of instability)")
    if p.path == "sparse":
        out += [f"eigenpairs above the lowest {k} of each branch", "ℍ^i spectra and Type-2 (uniqueness)"]
        if fam:
            out.append("the robustness proof over every rotation length (dense path only)")
        out.append("the attribution of an unstable result (dense path only)")
    elif p.path == "low_rank":
        out.append("ℍ^i spectra of the low-rank branches (their nullity is proven)")
    if p.method == "dense" and not p.uniqueness:
        out.append("ℍ^i (uniqueness eigenvalues, Type-2)")
    if fam and p.sampled and p.method == "dense":
        out.append("the robustness proof over every rotation length (sampled branches)")
    return replace(p, left_out=tuple(out))


def _estimated(p: Plan, k: int, rest: bool = False) -> Plan:
    """The plan with its estimate (seconds per part; module docstring); rest: on every core, none busy."""
    from .threads import cores, free_cores, runnable, slowdown
    n, L, metrics = p.n_dof, p.n_branches, len(p.metrics)
    if not rest:
        runnable(fresh=True)                   # the load now, not the BLAS policy's last read (up to 2 s old)
    workers = cores() if rest else free_cores()
    parts = {}
    if p.path == "sparse":                     # by step, summed over the metrics (budget.sparse_parts)
        for name in p.metrics:
            for step, seconds in budget.sparse_parts(n, L, name, p.n_sliding, k, p.deficit,
                                                     p.below.get(name), p.dim).items():
                parts[step] = parts.get(step, 0.0) + seconds * budget.speed()
        one = budget.sparse_estimate(n, L, p.metrics[:1], p.n_sliding, k, p.deficit, p.below, p.dim)
    else:
        full = (budget.branch_seconds(n, min(budget.MEASURE_STACK, L), lowrank=not p.uniqueness)   # no ℍ^i: eigh
                if not p.lowrank or p.floppy else 0.0)
        if p.lowrank and not p.floppy:
            per = budget.branch_seconds(n, min(budget.MEASURE_STACK, L), lowrank=True)
            parts["branches"] = metrics * per * (L / workers + budget.SETUP_BRANCHES)
        else:                       # every branch on the full path (a floppy packing: the low-rank path hands it on)
            parts["branches"] = metrics * L * full / (workers if p.lowrank else 1)
        one = parts["branches"] / metrics
        eigh = budget.branch_seconds(n, 1, lowrank=True) if p.robustness or p.attribution else 0.0
        if p.robustness:
            parts["robustness"] = ROBUST_EIGH * L * eigh
        if p.attribution:
            parts["attribution"] = ATTRIBUTION_BRANCHES * (full if full else eigh * (1 + budget.SETUP_BRANCHES))
    parts["overhead"] = metrics * (OVERHEAD_S + OVERHEAD_BRANCH_S * L)
    slow = 1.0 if rest else slowdown()
    parts = {key: float(v) * slow for key, v in parts.items()}
    one *= slow
    return replace(p, estimated_s=sum(parts.values()), parts=parts, workers=workers,
                    one_metric_s=float(one + parts.get("attribution", 0.0)))


PROBE_BRANCHES = 32   # `probe`: at most this many of the run's branches (the sampled ones, or a sample of all)
_PROBED: dict = {}    # `probe`'s counts of the last scene: {(metric, rotation length, mask): ν}


def probe(scene: Scene, p: Plan, rotation_length: float | None, k: int, sample_branches: int | None,
          seed: int) -> dict:
    """ν, the eigenvalues below the run's shift σ, of up to PROBE_BRANCHES of the branches the run will solve, per
    metric (ritz.below_counts: one factorisation and a block solve a metric, each branch's inertia from its
    Woodbury update; no eigen-solve): where the sparse path solves several branches of kk = k + 1 or more sliding
    contacts, the branches with ν >= kk skip the Ritz updates (ritz.py) and ν sets their cost and that of the
    refinements (budget.sparse_parts); elsewhere, or where the factor gives no count, {} (ν = 0 assumed). The masks
    are the run's (analysis.analyze: sample_masks with the same seed), or a seeded sample of all 2^Ms; the counts
    are exact and independent of the machine, kept for the last scene (`fit` plans it several times)."""
    from ..mechanics.branches import sample_masks
    from ..mechanics.metric import resolve
    from .assembled import sparse_parts, sparse_problem
    from .ritz import below_counts
    from .threads import blas_threads
    if p.path != "sparse" or p.n_branches < 2 or p.n_sliding < k + 1:
        return {}
    sliding = np.flatnonzero(scene.at_yield())
    n_sample = min(sample_branches if p.sampled else PROBE_BRANCHES, PROBE_BRANCHES - 2)
    masks = sample_masks(sliding, scene.n_contacts, n_sample, seed)
    metrics = family(scene, rotation_length) if len(p.metrics) > 1 else [resolve(scene, p.metrics[0],
                                                                                  rotation_length)]
    key = _fingerprint(scene)
    if _PROBED.get("scene") != key:
        _PROBED.clear()
        _PROBED["scene"] = key
    out, parts = {}, None
    for m in (m for m in metrics if m.name in p.metrics):
        keys = [(m.name, rotation_length, mask.tobytes()) for mask in masks]
        if any(kk not in _PROBED for kk in keys):
            parts = parts or sparse_parts(scene)
            with blas_threads(1):                   # thin products and small dense steps (as SparseMethod.solve)
                counts = below_counts(sparse_problem(scene, metric=m, parts=parts), masks)
            _PROBED.update(zip(keys, [None] * len(keys) if counts is None else counts.tolist()))
        nu = [_PROBED[kk] for kk in keys]
        if None not in nu:
            out[m.name] = tuple(nu)
    return out


def _fingerprint(scene: Scene) -> str:
    """A digest of what the scene's stiffness is made of (positions, contacts, forces, laws, states)."""
    import hashlib
    h = hashlib.blake2b(digest_size=16)
    for name in ("x", "p", "q", "point", "normal", "force", "moment", "k", "alpha", "mu", "curvature_p",
                 "curvature_q", "cell"):
        value = getattr(scene, name, None)
        h.update(b"-" if value is None else np.ascontiguousarray(value).tobytes())
    h.update(scene.at_yield().tobytes())
    return h.hexdigest()


FIT_SAMPLES = (62, 14, 4)  # random branches tried by `fit` (with the all-loading and all-unloading ones: 64, 16, 6)
FIT_SHARE = 0.5            # `fit` takes a plan estimated within this share of budget.ASK_SECONDS: the run stays
                           # within it where it takes up to twice its estimate


def fit(scene: Scene, full: Plan, options: dict) -> Plan:
    """The default plan fitted to budget.ASK_SECONDS (issues 36-38): where `full` (the plan of `options`, none of
    them given by the user) is refused or estimated longer, the first of `_reductions` whose estimate fits, with
    what it leaves out first in `left_out` and `fitted` saying how to run the full analysis (--timeout with its
    estimate). Where none fits, the cheapest of them all (`full` included) when estimated within
    budget.RUN_UNASKED_SECONDS at rest and at the load now (nothing cheaper is left to run: it runs,
    `fitted["unasked"]`, with a line up front and a heartbeat every budget.UNASKED_HEARTBEAT s in the CLI); else
    `full` (refused as before, as it is refused over 10 s at the load now). The choice is made on this machine at
    rest (plan(rest=True)): the plan, and so the verdict, do not depend on the load of the moment (a loaded machine
    takes longer, and says so); the plan returned carries the estimate at the load now. A
    reduced plan must fit FIT_SHARE of the budget. A reduced verdict claims no more than it proves: sampled
    branches prove only instability (verdicts.mark_partial), one metric is not the family's robustness."""
    if full.estimated_s is None:
        return full
    cheapest = (None, options) if full.refusal else (plan(scene, **options, rest=True), options)
    if cheapest[0] is not None and cheapest[0].estimated_s <= budget.ASK_SECONDS:
        return full
    for reduced in _reductions(full, options):
        at_rest = plan(scene, **reduced, rest=True)
        if at_rest.refusal:
            continue
        if at_rest.estimated_s <= FIT_SHARE * budget.ASK_SECONDS:
            return _fitted(scene, full, options, reduced)
        if cheapest[0] is None or at_rest.estimated_s < cheapest[0].estimated_s:
            cheapest = (at_rest, reduced)
    if cheapest[0] is None or cheapest[0].estimated_s > budget.RUN_UNASKED_SECONDS:
        return full
    unasked = _fitted(scene, full, options, cheapest[1], unasked=True)
    return unasked if unasked.estimated_s <= budget.RUN_UNASKED_SECONDS else full     # and at the load now


def _fitted(scene: Scene, full: Plan, options: dict, reduced: dict, unasked: bool = False) -> Plan:
    """The plan of `reduced` (`full` itself where it is `options`), with what it leaves out of `full` first and
    `fitted` (`_full_run`; unasked: it runs over budget.ASK_SECONDS, `fit`)."""
    p = full if reduced is options else plan(scene, **reduced)
    dropped = tuple(f"the metric(s) {', '.join(full.metrics[1:])} of the family (the verdict in L alone: its "
                    "metric-robustness not evaluated)" for _ in [0] if len(p.metrics) < len(full.metrics))
    return replace(p, left_out=dropped + p.left_out,
                   fitted={**_full_run(scene, full, options, reduced), "unasked": unasked})


def _reductions(full: Plan, options: dict):
    """Cheaper options, in order: the primary metric L alone, then a sample of the branches (a proof only of
    instability), then the sparse method (the lowest k eigenpairs a branch), each keeping the ones before."""
    one = {**options, "metric": "L"}
    Ms = full.n_sliding
    samples = [None] + [n for n in FIT_SAMPLES if Ms > 0 and n + 2 < 2 ** min(Ms, 62)]
    for method in ((options["method"],) if full.method == "sparse" else (options["method"], "sparse")):
        for n in samples:
            if n is None and full.refusal:
                continue                                    # every branch is what was refused
            sample = {} if n is None else {"max_sliding": min(options["max_sliding"], Ms - 1), "sample_branches": n}
            reduced = {**one, "method": method, **sample}
            if reduced != options:
                yield reduced


def _full_run(scene: Scene, full: Plan, options: dict, reduced: dict) -> dict:
    """`Plan.fitted`: the budget fitted to, the options run, and the full analysis's estimate and options (none
    where the run is the full analysis)."""
    whole = full if not full.refusal or full.n_sliding > 30 else plan(scene, **{**options,
                                                                                "max_sliding": full.n_sliding})
    seconds = None if whole.refusal else whole.estimated_s
    flags = ([] if whole is full else [f"--max-sliding {full.n_sliding}"]) + \
        ([f"--timeout {int(np.ceil(1.2 * seconds))}"] if seconds else [])
    return {"budget_s": budget.ASK_SECONDS, "options": reduced, "full_estimated_s": seconds,
            "full_options": " ".join(flags) if seconds and reduced is not options else None,
            "runs_full": reduced is options}


def fit_lines(p: Plan, listed: bool = False) -> list[str]:
    """A fitted plan in words: what it left out to fit the budget (listed: here, else on the plan's own lines), and
    the command of the full analysis."""
    if not p.fitted:
        return []
    f = p.fitted
    what = "; ".join(p.left_out) if listed else "what it leaves out is listed above"
    full = (f"the full analysis needs about {f['full_estimated_s']:.3g} s: run it with {f['full_options']}"
            if f["full_options"] else "this is the full analysis" if f.get("runs_full") else
            "the full analysis cannot be estimated (too many branches to enumerate)")
    if f.get("unasked"):
        return [f"plan: nothing cheaper fits the {f['budget_s']:.3g} s a run takes without --timeout; the cheapest, "
                f"estimated within {budget.RUN_UNASKED_SECONDS:.3g} s at rest, runs, leaving out: {what or 'nothing'}"
                f"; {full}"]
    return [f"plan fitted to the {f['budget_s']:.3g} s a run takes without --timeout, leaving out: {what}; {full}"]


def unasked_line(p: Plan) -> str | None:
    """What the CLI says on stderr, as a heartbeat line (io.progress.Heartbeat.note), before a run over
    budget.ASK_SECONDS without --timeout (`fit`'s unasked plan): its estimate and how to cap it; None for any other
    plan."""
    if not (p.fitted and p.fitted.get("unasked")):
        return None
    return (f"estimated {p.estimated_s:.3g} s on this machine now, over the {budget.ASK_SECONDS:.3g} s a run takes "
            f"without --timeout, and nothing cheaper is left to run: it runs (a line every "
            f"{budget.UNASKED_HEARTBEAT:.3g} s); give --timeout S to cap it")
