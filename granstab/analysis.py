"""`analyze(scene)`: every branch's spectra, consistent modes and verdicts, with error estimates and timings.

One pipeline for every size and metric: scene → contact blocks (stiffness.py) → assembled problem → projection in
a metric (metric.py: L-scaled or inertia) → all 2^Ms branches (an eigen method, solve/methods.py: dense LAPACK or
sparse shift-invert/LOBPCG) → verdicts (verdicts.py) → result. The branch loop, the verdicts and the error
reporting are written once; the methods differ only in the eigen step and say what they leave out. By default
the verdict is evaluated in the metric family L/10, L, 10L (and inertia where masses are known) and the summary
says whether it is metric-robust; the spectra shown are those of the primary metric ("L", or the one asked for).
"""
from __future__ import annotations

import warnings as _warnings
from dataclasses import dataclass, field, replace

import numpy as np

from .mechanics.accuracy import resolved_sign
from .mechanics.attribution import contact_work, mechanism, rim_share
from .mechanics.branches import BOTH, MINUS, PLUS, RIGID, Problem, enumerate_masks, sample_masks
from .mechanics.metric import CHOICES, Metric, family, has_masses, resolve
from .mechanics.robustness import metric_robustness
from .mechanics.stiffness import ContactBlocks, contact_blocks, curvature_warnings
from .mechanics.verdicts import (
    Attribution,
    ModeWork,
    Verdict,
    family_entry,
    finalize,
    frequencies_and_growth,
    mark_partial,
    summarize,
)
from .model.scene import Scene, SceneError
from .solve.budget import OverBudget
from .solve.methods import METHODS, Timer, choose_method
from .solve.plan import Plan, plan

__all__ = ["Analysis", "METHODS", "Plan", "analyze", "attribute", "build_problem", "plan"]

KEEP = ("auto", "all", "verdict")
KEEP_ALL = 4096     # keep="auto": every branch up to 2^12; above, memory would grow with 2^Ms (3.4 kB a branch)


@dataclass(eq=False)
class Analysis:
    """Result of `analyze`: branches, verdict (a `Verdict`; `summary` is its dict), errors (relative,
    dimensionless), timings (s), in the primary metric `metric` (metric.py); `cost`: the plan it followed
    (solve/plan.py: method, path, metrics, what it left out, `estimated_s`) and how many branches each path solved
    over all of them ("paths": "low_rank", "full", "sparse")."""

    scene: Scene
    problem: Problem
    metric: Metric
    branches: list
    verdict: Verdict
    errors: dict
    timings: dict
    warnings: list = field(default_factory=list)
    backend: str = "dense"
    attribution: Attribution | None = None
    cost: dict = field(default_factory=dict)

    @property
    def summary(self) -> dict:
        """The verdict as the `summary` object of `granstab analyze --json` (Verdict.to_dict)."""
        return self.verdict.to_dict()

    @property
    def length(self) -> float | None:
        """L of the scaled dofs [du, L dθ] (None for the inertia metric)."""
        return self.metric.rotation_length

    @property
    def scale(self) -> np.ndarray:
        """diag(D), U = D Ũ (only for diagonal metrics; `metric.physical` works for all)."""
        d = self.metric.diagonal
        if d is None:
            raise ValueError("the metric is not diagonal (3D inertia tensors): use analysis.metric.physical")
        return d

    def motion(self, vector: np.ndarray) -> np.ndarray:
        """Physical motion U = D Ũ of a scaled eigenvector (n,) or of each column of a block (n, K) over every dof of
        the scene (fixed particles: zero), normalised to unit length."""
        vector = np.asarray(vector, dtype=float)
        if self.problem.free is not None:
            full = np.zeros((self.scene.n_dof,) + vector.shape[1:])
            full[self.problem.free] = vector
            vector = full
        u = self.metric.physical(vector)
        return u / (np.linalg.norm(u, axis=0) if u.ndim > 1 else np.linalg.norm(u))

    def to_dict(self) -> dict:
        """The `granstab analyze --json` object."""
        s = self.scene
        inertia = self.metric.rotation_length is None
        return {
            "dim": s.dim,
            "title": s.title,
            "n_particles": s.n_particles,
            "n_contacts": s.n_contacts,
            "n_dof": s.n_dof,
            "n_sliding": int(np.sum(s.at_yield())),
            "metric": self.metric.name,
            "rotation_length": self.length,
            "eigenvalue_units": self.metric.units,
            "backend": self.backend,
            "branches": [_branch_dict(b, inertia) for b in self.branches],
            "summary": self.summary,
            "errors": self.errors,
            "timings": self.timings,
            "cost": self.cost,
            "warnings": self.warnings,
            "attribution": None if self.attribution is None else self.attribution.to_dict(),
        }


def _branch_dict(b, inertia: bool) -> dict:
    out = {
        "mask": [int(v) for v in b.mask],
        "stability_eigenvalues": [float(v) for v in b.stability_eigenvalues],
        "accuracy": [float(v) for v in b.accuracy],
        "n_zero": b.n_zero,
        "zero_tolerance": b.zero_tol,
        "consistent": [{k: c[k] for k in ("eigenvalue", "vector_sign", "hinges_on_tolerance")} for c in b.consistent()],
        "uniqueness_eigenvalues": [[float(v.real), float(v.imag)] for v in b.uniqueness_eigenvalues],
        "uniqueness_n_zero": b.uniqueness_n_zero,
        "type2": [{"vector_sign": t["vector_sign"], "dimension": t["dimension"]} for t in b.type2],
    }
    if b.negative_count is not None:
        out["negative_count"] = b.negative_count
    if inertia:                                                       # λ = ω²: frequencies and growth rates
        frequencies, growth = frequencies_and_growth(b.stability_eigenvalues, b.accuracy)
        out["frequencies"], out["growth_rates"] = frequencies.tolist(), growth.tolist()
    return out


def _spin_warning(problem) -> list[str]:
    spins = getattr(problem, "free_spins", 0)
    return [f"{spins} free spin(s): rotation dofs no contact feels (frictionless round particles), set aside like "
            "the rigid motions: zero modes, neither neutral nor unstable"] if spins else []


def build_problem(scene: Scene, blocks: ContactBlocks, metric):
    """The dense problem in a metric (a Metric, or L as a number): (problem, parts); see solve.methods.dense_problem."""
    from .solve.methods import dense_parts, dense_problem
    if not isinstance(metric, Metric):
        metric = resolve(scene, "L", float(metric))
    parts = dense_parts(scene, blocks)
    return dense_problem(scene, blocks, parts, metric), parts


def _robustness(scene, backend, problem, masks, metric, entries, timer):
    """robustness.metric_robustness of the family on the dense path (elsewhere None: finalize says "undetermined"
    unless two metrics prove different verdicts)."""
    if backend.name != "dense":
        return None
    with timer("metric robustness"):
        return metric_robustness(problem, masks, scene.dim, scene.dof_per_particle, metric.rotation_length, entries)


def _check_options(metric: str, keep: str, method: str, rotation_length: float | None) -> None:
    """ValueError for an option `analyze` does not know."""
    if metric not in CHOICES:
        raise ValueError(f"metric must be one of {', '.join(CHOICES)}, got {metric!r}")
    if keep not in KEEP:
        raise ValueError(f"keep must be one of {', '.join(KEEP)}, got {keep!r}")
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    if rotation_length is not None and not (np.isfinite(rotation_length) and rotation_length > 0):
        raise ValueError(f"rotation_length must be a positive number, got {rotation_length!r}")
    if rotation_length is not None and metric == "inertia":
        raise ValueError("rotation_length: the inertia metric has no rotation length")


def _renamed(rotation_length, rotation_length_):
    """rotation_length, or the old name's value (deprecated for one release, with a DeprecationWarning)."""
    if rotation_length_ is None:
        return rotation_length
    _warnings.warn("analyze(rotation_length_=...) is deprecated: use rotation_length=", DeprecationWarning,
                   stacklevel=3)
    return rotation_length if rotation_length is not None else rotation_length_


def _solve_metrics(backend, state, metrics, primary, masks, timer, on_branch, progress, keep_all):
    """Each metric's branches, the primary metric first: its (metric, problem, branches, verdict, notes), every
    metric's family entry, and the branches solved per path over all metrics."""
    order = [primary] + [i for i in range(len(metrics)) if i != primary]
    entries = [None] * len(metrics)
    paths = {}                                                       # branches solved per path, all metrics
    for i in order:
        m = metrics[i]
        main = i == primary
        with timer("assembly" if main else f"metric {m.name}"):
            problem = backend.problem(state, m)
            if i == order[-1]:
                backend.release(state)                               # what only the metrics' problems needed
        with timer("branches" if main else f"metric {m.name}"):
            branches, notes = backend.solve(problem, masks, on_branch=on_branch if main else None,
                                            progress=progress, label=f"branches, metric {m.name}",
                                            keep_all=keep_all)
        for path, count in notes["paths"].items():
            paths[path] = paths.get(path, 0) + count
        verdict = summarize(branches, notes)
        entries[i] = family_entry(m, verdict)
        if main:
            result = (m, problem, branches, verdict, notes)
    return result, entries, paths


def _result_warnings(scene, state, notes, problem, branches, verdict, keep) -> list[str]:
    """The result's warnings: curvature, the method's, free spins, and the branches left out by `keep`."""
    warnings = curvature_warnings(scene, state.blocks) + notes.get("warnings", []) + _spin_warning(problem)
    if len(branches) < verdict.n_branches:
        warnings.append(f"{len(branches)} of {verdict.n_branches} branches kept (keep='{keep}'): those with a "
                        "consistent eigenpair of sign <= 0 and the one with the lowest eigenvalue; the counts are "
                        "over all branches (keep='all' keeps every one)")
    return warnings


def _refuse_over_memory(planned) -> None:
    """A sparse run whose peak memory estimate exceeds what is available is refused in one line (solve/memory.py)."""
    if planned.memory and not planned.memory["fits"]:
        raise OverBudget(planned.refusal)


def analyze(scene: Scene, *, metric: str = "family", rotation_length: float | None = None, max_sliding: int = 16,
            on_branch=None, method: str = "auto", k: int = 6, progress: bool = False,
            sample_branches: int | None = None, seed: int = 0, rotation_length_: float | None = None,
            device: str = "cpu", lowrank: bool | None = None, keep: str = "auto", attribution: bool = True,
            rim=None, uniqueness: bool = True, estimate: bool = True) -> Analysis:
    """Analyse every loading branch of `scene`: spectra, consistent modes and verdicts (Sec. 3, Appendix D).

    Parameters
    ----------
    scene : Scene
        N particles, M contacts, n_dof = N·(d + r) dofs (d = dim; r = 1 rotation in 2D, 3 in 3D).
    metric : {"family", "L", "L/10", "10L", "inertia"}
        "family": the verdict in L/10, L, 10L and inertia where masses are known, spectra in L,
        ``summary["metric_robust"]`` and ``summary["metrics"]``; otherwise that metric only.
    rotation_length : float, optional
        L of the scaled dofs [du, L dθ] (default: the mean contact radius; 1 = the paper's; old name rotation_length_).
    max_sliding, sample_branches, seed : int
        More than `max_sliding` potentially sliding contacts (2^Ms branches) are refused unless `sample_branches`
        is given: then the all-loading, all-unloading and that many seeded random branches are examined
        (``summary["branches"] == "partial"``; a proof only of instability, eq:instab).
    method, k, uniqueness : {"auto", "dense", "sparse"}, int, bool
        "dense": every eigenpair, ℍ^i spectra and Type-2 (eq:newstiffnesses; uniqueness=False: ℍ^i left out, the
        same stability); "sparse": the lowest `k` eigenpairs of each sym(𝓗^i) and its exact negative count, no
        (n_dof, n_dof) matrix; "auto": dense up to DENSE_MAX_DOF dofs. `warnings` says what a method leaves out.
    device, lowrank, keep : {"cpu", "gpu", "auto"}, bool or None, {"auto", "all", "verdict"}
        Where stacked eigenproblems run (granstab.solve.device); branches as low-rank updates of the elastic
        problem (None: from 2^10 branches on, or branches · n³ >= 5e8, or on a GPU); which branches the result keeps ("verdict": those the
        verdict rests on; "auto": all up to KEEP_ALL).
    on_branch, progress : callable or None, bool or a reporter
        Called with each `Branch` of the primary metric as it is finished; a bar with the time left, or a reporter
        with stages (granstab.io.progress.Heartbeat: a line a minute where no bar can be drawn).
    attribution, rim : an unstable dense result gets ``attribution`` (`attribute`; rim: particles with cut contacts).
    estimate : False: ``cost`` without the time estimate (no read of the load: a scan's clusters, a track's frames).

    Returns
    -------
    Analysis
        ``branches``: `Branch` (``mask`` (M,), ``stability_eigenvalues`` (k,) of sym(𝓗^i), ``stability_vectors``
        (n, k) scaled, ``accuracy`` (k,), ``codes`` (k,); n free dofs, k = n when dense); ``summary``: the verdict
        (eq:stab, eq:neutral, eq:instab); ``errors``; ``timings`` (s); ``motion(v)`` (n_dof,); ``to_dict()``.
    """
    rotation_length = _renamed(rotation_length, rotation_length_)
    _check_options(metric, keep, method, rotation_length)
    metrics = family(scene, rotation_length) if metric == "family" else [resolve(scene, metric, rotation_length)]
    primary = [m.name for m in metrics].index("L") if metric == "family" else 0
    planned = plan(scene, metric=metric, rotation_length=rotation_length, max_sliding=max_sliding,
                   sample_branches=sample_branches, method=method, k=k, device=device, lowrank=lowrank,
                   uniqueness=uniqueness, attribution=attribution, estimate=estimate, seed=seed)
    _refuse_over_memory(planned)
    backend = choose_method(scene, planned.method, k, device, planned.lowrank, uniqueness)
    timer = Timer()
    with timer("total"):
        state = backend.prepare(scene, timer)
        Ms = len(state.sliding)
        partial = Ms > max_sliding
        if partial and sample_branches is None:
            raise SceneError(f"{scene.source}: {Ms} potentially sliding contacts: 2^{Ms} branches exceed "
                             f"max_sliding = {max_sliding}")
        masks = (sample_masks(state.sliding, scene.n_contacts, sample_branches, seed) if partial
                 else enumerate_masks(state.sliding, scene.n_contacts))
        keep_all = keep == "all" or (keep == "auto" and len(masks) <= KEEP_ALL)
        (m, problem, branches, verdict, notes), entries, paths = _solve_metrics(
            backend, state, metrics, primary, masks, timer, on_branch, progress, keep_all)
        with timer("errors"):
            errors = backend.errors(state, problem, branches)
        if "residual_stability" in notes:                                # over every branch, kept or not
            errors["eigen_residual_stability"] = max(errors["eigen_residual_stability"], notes["residual_stability"])
        fam = metric == "family"
        robust = _robustness(scene, backend, problem, masks, m, entries, timer) if fam and not partial else None
        verdict = finalize(verdict, errors, int(np.sum(state.blocks.rolling_undetermined)), entries if fam else None,
                           robust, has_masses(scene))
        if partial:
            verdict = mark_partial(verdict, len(masks), Ms)
        verdict = replace(verdict, branches_kept=len(branches), free_spins=getattr(problem, "free_spins", 0))
    warnings = _result_warnings(scene, state, notes, problem, branches, verdict, keep)
    result = Analysis(scene=scene, problem=problem, metric=m, branches=branches, verdict=verdict, errors=errors,
                      timings=timer.times, warnings=warnings, backend=backend.name,
                      cost={**planned.to_dict(), "branches_per_metric": len(masks), "paths": paths})
    return _attributed(result, rim, attribution and backend.name == "dense", max_sliding=max_sliding,
                       sample_branches=sample_branches, seed=seed)


def _attributed(result: Analysis, rim, wanted: bool, **options) -> Analysis:
    """`result` with its `attribution` where it is unstable and `wanted` (the dense path; its time is its own)."""
    if wanted and result.verdict.verdict == "unstable":
        result.attribution = attribute(result, rim, **options)
    return result


def focus(analysis: Analysis, inside, share: float) -> Analysis:
    """The analysis with the verdict taken on the modes of the particles `inside` (indices) only: a negative or zero
    eigenpair (λ <= its bound) with less than `share` of its squared metric norm there is not theirs and is left out
    like a rigid one; positive ones change no verdict and all count (--boundary embedded: the cluster inside its
    surroundings)."""
    branches = []
    for b in analysis.branches:
        there = inside_share(analysis, b, inside)
        low = b.stability_eigenvalues <= b.accuracy
        branches.append(replace(b, codes=np.where((there < share) & low, RIGID, b.codes).astype(b.codes.dtype)))
    verdict = finalize(summarize(branches), analysis.errors, int(np.sum(contact_blocks(analysis.scene).rolling_undetermined)),
                       None)
    return replace(analysis, branches=branches, verdict=replace(verdict, branches_kept=len(branches)))


def inside_share(analysis: Analysis, branch, inside) -> np.ndarray:
    """The share of each stability eigenvector's squared metric norm on the particles `inside` (indices), (k,)."""
    problem, scene = analysis.problem, analysis.scene
    mask = np.zeros(scene.n_particles, dtype=bool)
    mask[inside] = True
    dofs = np.repeat(mask, scene.dof_per_particle)
    dofs = dofs if problem.free is None else dofs[problem.free]
    V = np.asarray(branch.stability_vectors)          # the low-rank path's vectors are computed when asked (LazyVectors)
    return np.sum(V[dofs] ** 2, axis=0) / np.sum(V ** 2, axis=0)


def mode_works(analysis: Analysis, rim: np.ndarray, blocks: ContactBlocks | None = None,
               inside=None) -> list[ModeWork]:
    """Every consistent negative eigenpair of the kept branches (resolved sign < 0), lowest first, with its work
    parts (attribution.contact_work on U = D P v: they sum to λ) and rim share (attribution.rim_share, among the
    particles `inside`, default all)."""
    scene, problem, metric = analysis.scene, analysis.problem, analysis.metric
    blocks = contact_blocks(scene) if blocks is None else blocks
    on_rim = np.zeros(scene.n_particles, dtype=bool)
    on_rim[rim] = True
    within = np.ones(scene.n_particles, dtype=bool)
    if inside is not None:
        within[:] = False
        within[inside] = True
    out = []
    for i, b in enumerate(analysis.branches):
        negative = np.isin(b.codes, (PLUS, MINUS, BOTH)) & (resolved_sign(b.stability_eigenvalues, b.accuracy) < 0)
        js = np.flatnonzero(negative)
        vectors = b.stability_vectors[:, js] if js.size else None     # once a branch (lowrank.LazyVectors: these only)
        for c, j in enumerate(js):
            v = np.zeros(scene.n_dof)
            v[problem.free if problem.free is not None else slice(None)] = vectors[:, c]
            u = np.zeros(scene.n_dof)
            u[problem.free if problem.free is not None else slice(None)] = problem.projection.apply(vectors[:, c])
            U = metric.physical(u)[blocks.index]
            parts = contact_work(blocks, np.arange(scene.n_contacts), U, np.asarray(b.mask) == 1).sum(axis=0)
            weights = (v ** 2).reshape(scene.n_particles, -1).sum(axis=1)
            out.append(ModeWork(branch=i, index=int(j), eigenvalue=float(b.stability_eigenvalues[j]),
                                work_parts=tuple(float(x) for x in parts),
                                rim_share=float(rim_share(weights, on_rim, within))))
    return sorted(out, key=lambda w: w.eigenvalue)


def control_verdict(scene: Scene, metric: Metric, **options) -> str:
    """The verdict of a control scene (attribute) in the analysis's metric; 'stable' when nothing is free to move."""
    if scene.fixed is not None and scene.fixed.all():
        return "stable"
    name, length = ("inertia", None) if metric.rotation_length is None else ("L", metric.rotation_length)
    return analyze(scene, metric=name, rotation_length=length, attribution=False, **options).verdict.verdict


def attribute(analysis: Analysis, rim=None, **options) -> Attribution:
    """Why `analysis` is unstable (mechanics/attribution.py): the work parts and rim share of its lowest consistent
    negative mode and of every other one, the controls (every contact elastic; the rim held fixed) in the same
    metric, and the `mechanism` label by the rule stated there.

    rim: the particles (indices) with cut contacts (the scan passes each cluster's); default none: a scene's loads
    are its own, so the rim-held control is the analysis itself. options: max_sliding, sample_branches, seed for
    the controls."""
    scene = analysis.scene
    rim = np.zeros(0, dtype=np.int64) if rim is None else np.asarray(rim, dtype=np.int64)
    modes = mode_works(analysis, rim)
    if not modes:
        raise ValueError(f"{scene.source}: no consistent negative eigenpair among the kept branches to attribute")
    elastic = control_verdict(replace(scene, state=("elastic",) * scene.n_contacts), analysis.metric, **options)
    held = np.zeros(scene.n_particles, dtype=bool) if scene.fixed is None else scene.fixed.copy()
    held[rim] = True
    fixed = (control_verdict(replace(scene, fixed=held), analysis.metric, **options) if rim.size
             else analysis.verdict.verdict)
    low = modes[0]
    label = mechanism(np.array([low.work_parts]), np.array([low.rim_share]), [elastic], [fixed], [True])[0]
    return Attribution(mechanism=str(label), work_parts=low.work_parts, rim_share=low.rim_share,
                       elastic_control=elastic, fixed_control=fixed, modes=tuple(modes))
