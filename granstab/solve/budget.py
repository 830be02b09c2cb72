"""Time budget of an analysis: an estimate from a measured per-branch cost, refusal of work that cannot finish in
the time asked, and a deadline that stops work that runs over (`granstab analyze --timeout`).

The full dense path solves, per branch, an n×n symmetric eigenproblem, a non-symmetric one and an SVD, and forms
projections and residuals with a few matrix products (dense.py, mechanics/branches.py); the low-rank path an n×n
symmetric eigenproblem, a Gram matrix's eigenvalues and a few products (lowrank.py); both are repeated for every
metric of the family. Their cost is measured here on this machine, on a stack of random matrices of the same
size (up to MEASURE_DIM; larger sizes scale as n^SCALE_EXPONENT up to EFFICIENT_DIM, n³ beyond), in CPU time, so the
estimate follows the machine it runs on but not its load of the moment.

Calibration (2026-11-26, AMD EPYC, one OpenBLAS thread, CPU time): the timed kernels at their true size took, per
matrix, low-rank 0.0043 / 0.019 / 0.11 / 0.24 s and full 0.016 / 0.076 / 0.44 / 0.90 s at n = 160 / 320 / 640 /
880, a growth of n^2.4 (BLAS-3 grows more efficient with size; scaled from 160 as n³ they were 2.4× too high at 880).
Against the CPU time of whole analyses (time.process_time, all threads: set-up, reduction, ℍ^i floors and an
unstable result's attribution included), estimate / measured: the 300-disk packing of benchmarks/packing300.py (879
dofs, low-rank) with 7 sliding contacts (128 branches), metric L, 29.8 / 30.4 s; with 1 (2 branches) metric L
0.87 / 1.24 s and the family 2.94 / 3.62 s; its all-elastic branch, L 0.64 / 0.74 s and the family 2.26 / 2.06 s;
random packings of 300 dofs (low-rank, 4 branches) L 0.09 / 0.06 s, family 0.26 / 0.22 s, and of 192 and 363 dofs
(full path, 8 and 4 branches) 0.17 / 0.17 s and 0.37 / 0.37 s: 0.7-1.4×. benchmarks/packing300.py reports the ratio
for each of its cases and flags one outside 0.5-3×. The family of that packing measured 12× its estimate before
(issue 26: "3× too low"): the unstable branches of L/10 and 10L left the low-rank path for the full one
(lowrank._special: the Gram matrix's floor could not tell; now `lowrank.svd_floor` does), and the estimate, which
assumes the path `use_lowrank` chooses for every metric, counted them as low-rank.
"""
from __future__ import annotations

import math
import signal
import time
from contextlib import contextmanager
from functools import cache

import numpy as np

MEASURE_DIM = 160      # matrices larger than this are timed at this size and scaled (`scaled`, calibration above)
SCALE_EXPONENT = 2.4   # cost ∝ n^2.4 from MEASURE_DIM to EFFICIENT_DIM (measured; module docstring) …
EFFICIENT_DIM = 1000   # … and ∝ n³ beyond, where BLAS-3 runs at its full rate (an assumption on the safe side)
MEASURE_STACK = 4      # matrices timed at once (a few tenths of a second in all, only for work that may be long)
ASK_SECONDS = 10.0     # without --timeout, the CLI refuses work estimated longer than this (one line, what to do) …
RUN_UNASKED_SECONDS = 90.0  # … unless it is the default plan's cheapest form and estimated within this at rest:
                            # then it runs, saying so up front (plan.fit; issue 41's held-out 2·10⁵-disk packing)
UNASKED_HEARTBEAT = 10.0    # … with a heartbeat line this often (the minute's Heartbeat, at a shorter period)
SETUP_BRANCHES = 2.0   # the low-rank path's work once a metric (the reduction, ℍ^i floors, an unstable result's
                       # attribution and its control analysis), in branches' worth: 0.5 s of 0.72 at 879 dofs
REFERENCE_PROBE = 0.0056  # CPU seconds per matrix of the low-rank probe at MEASURE_DIM on the calibration machine
                          # (2026-11-29, AMD EPYC, one thread; 0.0053-0.0060 in three runs)
TRIVIAL_WORK = 2e7     # metrics · branches · n³ below this is certainly under a second: nothing is measured


class OverBudget(Exception):
    """The work does not fit the time asked; the message is one line saying what to do."""


def branch_seconds(n: int, stack: int = MEASURE_STACK, lowrank: bool = False) -> float:
    """Measured seconds per branch for n dofs on one BLAS thread (a shared machine's threads give no more; the
    branch paths run one thread a core), in CPU time: the time on this machine's cores when they are free, so that
    what is refused does not depend on the load of the moment (a loaded machine takes longer; the heartbeat says
    so, and --timeout's deadline stops it). Full path (dense.py): eigh + eig + SVD and four products of a stack of
    random n×n matrices; low-rank path (lowrank.py): eigh, the Gram matrix's eigvalsh and three products. Measured
    once a process for each size (`_probe`), scaled beyond MEASURE_DIM."""
    m = max(1, min(n, MEASURE_DIM))
    return _probe(m, stack, lowrank) * scaled(n, m)


@cache
def _probe(m: int, stack: int, lowrank: bool) -> float:
    """`branch_seconds` of m×m matrices, timed (CPU seconds per matrix)."""
    from .threads import blas_threads

    rng = np.random.default_rng(0)
    A = rng.standard_normal((stack, m, m))
    S = A + np.swapaxes(A, 1, 2)
    with blas_threads(1):
        np.linalg.eig(A[:1, :2, :2])                        # first call loads LAPACK: not part of the cost
        start = time.thread_time()                          # CPU time: what a core gives, whatever the load
        np.linalg.eigh(S)
        if lowrank:
            np.linalg.eigvalsh(S)
        else:
            np.linalg.eig(A)
            np.linalg.svd(A, compute_uv=False)
        for _ in range(3 if lowrank else 4):                # projections, residuals, Gram matrix, signs
            A @ S
        return (time.thread_time() - start) / stack


def speed() -> float:
    """This machine's time for the probe's low-rank kernels at MEASURE_DIM over the calibration machine's
    (REFERENCE_PROBE): the factor by which costs calibrated there (the sparse path's) are scaled here."""
    return _probe(MEASURE_DIM, 2, True) / REFERENCE_PROBE      # two matrices: a few ms on a free core


def scaled(n: int, m: int) -> float:
    """The cost of n×n over that of m×m (m <= n): (n/m)^SCALE_EXPONENT up to EFFICIENT_DIM, n³ beyond."""
    knee = max(min(n, EFFICIENT_DIM), m)
    return (knee / m) ** SCALE_EXPONENT * (max(n, knee) / knee) ** 3


def estimate(n_dof: int, n_branches: int, n_metrics: int = 1, lowrank: bool = False, workers: int = 1) -> float:
    """Estimated seconds for `n_branches` dense branches of `n_dof` dofs in each of `n_metrics` metrics (the
    family repeats every branch per metric), on the full or the low-rank path (`workers` cores share the low-rank
    branches; its once-per-metric work counts SETUP_BRANCHES branches more). One measurement, at most a few tenths
    of a second, skipped (0) for trivially small work."""
    if n_metrics * n_branches * float(n_dof) ** 3 < TRIVIAL_WORK:
        return 0.0
    per = branch_seconds(n_dof, min(MEASURE_STACK, n_branches), lowrank)
    if lowrank:
        return n_metrics * per * (n_branches / max(workers, 1) + SETUP_BRANCHES)
    return n_metrics * n_branches * per


#: the sparse path (sparse.py, ritz.py: one factorisation and block shift-invert of the elastic matrix per metric,
#: then every branch as a Ritz update with its own checks), wall seconds on 2 free cores of the calibration machine
#: (2026-11-26, AMD EPYC), scaled to this machine by `speed()`: a metric's set-up ∝ n (periodic packings of 3·10⁴
#: and 3·10⁵ dofs, 4 branches, since the solver's speed-up of issue 24: 2.0 s and 17.4-18.8 s measured at a load
#: of 1-1.3, 2.3 s and 19.2 s estimated) and a branch's update a fixed cost plus ∝ n (a 3,072-dof random packing,
#: 10 sliding contacts, 1,024 branches: metric L 51 s, its family of 3 metrics 386 s measured; 115 and 344 s
#: estimated; the family's metrics since counted one by one, RITZ_FALLBACK). Many sliding contacts Ms (issue 38: frame
#: 23 of a sheared 1,400-disk LAMMPS run, Ms = 85, 10 sampled branches: 10.4× its estimate) cost more, measured
#: 2026-11-29 (CPU time, this machine, load 2-10) on random 2D packings of 1,728 and 4,107 dofs (Ms = 5, 6, 30, 100),
#: a 3D one of 3,000 (Ms = 30) and the sheared frame (4,101 dofs): the Ritz basis (ritz.py: the elastic block Krylov
#: space, then 2·TAYLOR·Ms Taylor columns less those dependent) was 102, 111, 349, 806, 305 and 792 columns (the old
#: model's k + 9 + 4 Ms: 35-415), `ritz_width`; its set-up (the elastic solve, the Taylor solves, orthonormalisation)
#: 0.09-3.0 s, the elastic solve in the set-up above and RITZ_INIT per n·w² (the Taylor columns); a branch RITZ_EIGH per w³ (its share of the stacked
#: eigh), RITZ_BRANCH_PER_DOF per n (its vectors, residuals, inertia) and each refinement RITZ_REFINE per n·(w +
#: 3(kk + GUARD))² plus RITZ_REFINE_PER_DOF per n: 0.5 a branch with no eigenvalue below σ (ν = 0: 0-1 measured),
#: ritz.SparseRitz.steps (4) where 0 < ν < kk (the sheared frame: 4 in each of 3; their negative modes lie outside the
#: basis built about σ). A branch with ν >= kk skips Ritz (ritz.py) and is solved by shift-invert, ARPACK_PAIR_*
#: per n·(kk + ν) (the sheared frame: 6 of 10 branches, ν = 8-15, 9.7 s of CPU time for 100 pairs); ν of each branch
#: is counted before the run by the plan's probe (plan.probe: one factorisation and the inertia of each branch's
#: Woodbury update, no eigen-solve). Beyond RITZ_BYTES (`ritz_fits`) each branch is a
#: shift-invert with a rank-2Ms Woodbury update (Ms = 200, 500: 2.7, 9.1 s), SHIFT_PER_DOF_SLIDING per n·Ms and
#: SHIFT_CUBE per Ms³ a branch.
SPARSE_SETUP_PER_DOF = 6e-5
SPARSE_BRANCH_FIXED = 0.11
SPARSE_BRANCH_PER_DOF = 6e-7
RITZ_INIT = 1.1e-9
RITZ_EIGH = 4e-10
RITZ_BRANCH_PER_DOF = 6e-6
RITZ_REFINE = 1.4e-10
RITZ_REFINE_PER_DOF = 5e-6
RITZ_REFINEMENTS = 0.5          # refinements of a branch with ν = 0 (0-1 measured); 0 < ν < kk: ritz steps (4)
RITZ_3D = (1.0, 3.0)            # 3D: (refinements of a branch with ν = 0, cost factor on the basis and each refinement):
                                # 3D random packings of 3,000 dofs, Ms = 20 and 30: 2.6 and 3 refinements a branch, the
                                # basis 0.8 and 0.97 s, a refinement 0.15 and 0.11 s (denser operator and factor than
                                # 2D's: 4.7×, 3.5× and 1.7× the 2D model); 2D: (RITZ_REFINEMENTS, 1). Refinements a
                                # branch with ν = 0, measured 2026-11-29 (ritz.SparseRitz.stats, benchmarks/estimates
                                # ritz_3d): random packings of 648, 3,000 (Ms 20, 60) and 5,184 dofs 3.6, 2.6, 0.9, 3;
                                # a sheared periodic LAMMPS frame of 2,316 dofs (Ms 20) 0: the count is not predicted
                                # (the basis width does not tell periodic from bounded), 1 sets those five within
                                # 3× of their CPU time (0.41-2.3×; 2.5 left the periodic frame at 0.23×)
RITZ_KRYLOV = 48                # the basis: kk + this (the elastic block Krylov space) …
RITZ_COLUMNS_PER_SLIDING = 8.5  # … + this a sliding contact (of the 2·TAYLOR = 12 its Taylor powers add at most)
ARPACK_PAIR_DOF = 4.6e-6         # a branch solved by shift-invert with the shared factor, per n·(kk + ν) pairs, …
ARPACK_PAIR_COLUMN = 2.1e-7      # … and per n·(kk + ν)·u, u = 6 + Ms the Woodbury columns of an average branch (each
                                 # solve applies them): the sheared frame (u 91, ν 8-15) 9.7 s measured, 9.7 s so; the
                                 # superquadric packing of FLOPPY_PAIR_DOF (u 16, ν 21-25, 30 pairs) 0.3-0.45 s a
                                 # branch measured at load 2-10, 0.36 s so
SHIFT_PER_DOF_SLIDING = 1.3e-7
SHIFT_CUBE = 4.1e-9
FLOPPY_PAIR_DOF = 6e-6  # a branch whose modes at or below zero (`plan.deficit`: a floppy 3D packing's rattling
                         # and rolling modes, ν of them negative under its prestress) outnumber k: Ritz cannot certify
                         # it, ARPACK solves k + ν pairs, per n·(k + deficit) (measured 2026-11-29 on a LIGGGHTS
                         # superquadric packing, 1,500 dofs, deficit 28, ν 15-18: 0.15-0.3 s a branch on a free core,
                         # 6-60 sampled branches; a 690-dof cluster of it, deficit 15: 0.045 s; the calibration above
                         # had left it out: 7-9× low; with 3e-6, 2.2-2.8× low on 16 and 64 branches at load 5-9)
FLOPPY_CROWD = 4        # … counted up to this many k's: a larger crowd below the shift is bisected and only the
                        # eigenvalues below it are solved (sparse.py; an assumption, not measured beyond deficit 28)
ARPACK_BRANCH_PER_DOF = 1.1e-4   # a branch solved again by shift-invert ARPACK with the shared LU (ritz.SparseRitz's
                                 # fall-back, sparse.lowest_modes with the branch's Woodbury operator), per dof:
                                 # measured 2026-11-29 (CPU time, this machine, speed() 1.07) 0.22 s a branch at 1,728
                                 # dofs and 0.50-0.51 s at 4,107 (two packings), 0.033 s at 867
RITZ_FALLBACK = {"10L": 1.0}     # the share of a metric's branches (the elastic one aside) whose Ritz update does not
                                 # converge and is redone by ARPACK (ritz.SparseRitz.stats): measured 2026-11-29 on
                                 # random 2D packings of 867, 1,728 and 4,107 (two) dofs, 8 branches: 10L 7 of 8 in
                                 # every one (its Ritz basis 43 columns, against 72-83 for L and L/10), L and L/10
                                 # none; 64 branches of 4,107 dofs: 10L 63 (issue 38's sparse family, 3.3× over its
                                 # estimate, where each metric after L counted a fixed 3.5 L's: 10L took 8.8 L's of
                                 # CPU time, L/10 0.6-1.1). Inertia: not measured, counted as L.


def sparse_estimate(n_dof: int, n_branches: int, n_metrics=1, n_sliding: int = 0, k: int = 6,
                    deficit: int = 0, below: dict | None = None, dim: int = 2) -> float:
    """Estimated wall seconds of the sparse path (calibration above, scaled by `speed`): per metric, the elastic
    solve's set-up and every branch's update, Ritz (one basis for all branches) or, by `use_ritz`,
    shift-invert ARPACK; where Ritz is used, the branches of a metric whose Ritz updates fall back to ARPACK
    (RITZ_FALLBACK); where `deficit` (plan.deficit) is k + 1 or more, every branch's ARPACK solve of k + ν pairs.
    `n_metrics`: the metrics' names (a tuple), or their number (the family's first ones: L, L/10, 10L); `below`:
    per metric name, the probed ν of a sample of its branches (plan.probe; none: ν = 0); dim: the scene's (RITZ_3D)."""
    names = n_metrics if isinstance(n_metrics, tuple) else ("L", "L/10", "10L")[:n_metrics]
    below = below or {}
    return sum(sum(sparse_parts(n_dof, n_branches, name, n_sliding, k, deficit, below.get(name), dim).values())
               for name in names) * speed()


def ritz_width(n_dof: int, n_sliding: int, kk: int) -> int:
    """The predicted columns of ritz.SparseRitz's basis (calibration above; at most the dofs)."""
    return int(min(n_dof, kk + RITZ_KRYLOV + RITZ_COLUMNS_PER_SLIDING * n_sliding))


RITZ_BYTES = 512 * 2 ** 20   # the stacked Ritz updates of SparseRitz (Ms width² doubles) at most; beyond: shift-invert


def ritz_fits(n_dof: int, n_sliding: int, kk: int) -> bool:
    """Whether the branches of Ms = n_sliding contacts are Ritz updates of one elastic solve (methods.SparseMethod):
    the updates, one width² matrix a contact (ritz.SparseRitz.updates) of the basis's width (`ritz_width`), within
    RITZ_BYTES. The run (methods.SparseMethod._modes) and the estimate (`sparse_parts`) ask the same."""
    return 8 * n_sliding * float(ritz_width(n_dof, n_sliding, kk)) ** 2 <= RITZ_BYTES


RITZ_MIN_BRANCHES = 3       # SparseRitz from 3 branches on; for 2 (track's whole stage: all-loading, all-unloading;
                            # a periodic packing with one contact at yield) only where its basis is narrow (`use_ritz`)


def use_ritz(n_branches: int, n_dof: int, n_sliding: int, kk: int) -> bool:
    """Whether methods.SparseMethod._modes solves the branches as Ritz updates of one elastic solve (`ritz_fits`);
    else each by shift-invert. From RITZ_MIN_BRANCHES branches on, always; for two, only when the sliding contacts'
    Taylor columns are no more than the elastic Krylov columns (RITZ_COLUMNS_PER_SLIDING·Ms ≤ kk + RITZ_KRYLOV),
    i.e. the basis costs at most about one more elastic solve. Measured (CPU time, issues 39 and 41): a sheared
    2,000-disk frame (5,937 dofs, Ms 60, kk 61: 510 columns against 109) 12.7 s as Ritz, 5.9 s by shift-invert;
    the periodic packing of 2·10⁵ disks (Ms 1, kk 7) 50 s and 3.8 GB as Ritz, 74 s and 5.9 GB by shift-invert
    (a factor a branch). The run and the estimate ask the same."""
    narrow = RITZ_COLUMNS_PER_SLIDING * n_sliding <= kk + RITZ_KRYLOV
    return (n_branches >= RITZ_MIN_BRANCHES or (n_branches == 2 and narrow)) and ritz_fits(n_dof, n_sliding, kk)


def sparse_parts(n_dof: int, n_branches: int, metric: str = "L", n_sliding: int = 0, k: int = 6,
                 deficit: int = 0, below=None, dim: int = 2) -> dict:
    """One metric's part of `sparse_estimate` on the calibration machine, by step: "setup", "ritz" (the basis and
    the branches it solves) or "shift_invert", "direct" (the branches with kk or more eigenvalues below σ, straight
    to shift-invert), "fallback" (RITZ_FALLBACK's ARPACK solves), "floppy". `below`: the probed ν of a sample of
    the branches (their shares stand for all n_branches), or None (ν = 0)."""
    from .ritz import GUARD, STEPS
    Ms, kk, n = n_sliding, k + 1, n_dof
    nu = np.zeros(1) if below is None or not len(below) else np.asarray(below, float)
    pair = n * (ARPACK_PAIR_DOF + ARPACK_PAIR_COLUMN * (6 + Ms))   # a shift-invert pair (ARPACK_PAIR_*)
    out = {"setup": SPARSE_SETUP_PER_DOF * n}
    if use_ritz(n_branches, n, Ms, kk):
        w = ritz_width(n, Ms, kk)
        ritz = n_branches * np.mean(nu < kk)
        refinements, heavier = RITZ_3D if dim == 3 else (RITZ_REFINEMENTS, 1.0)
        steps = n_branches * np.mean(np.where(nu == 0, refinements, STEPS) * (nu < kk))
        basis = heavier * RITZ_INIT * n * w * w if ritz > 0 else 0.0    # none where every branch has ν >= kk
        out["ritz"] = (basis + ritz * (RITZ_EIGH * float(w) ** 3 + RITZ_BRANCH_PER_DOF * n)
                       + heavier * steps * (RITZ_REFINE * n * (w + 3 * (kk + GUARD)) ** 2 + RITZ_REFINE_PER_DOF * n))
        out["direct"] = n_branches * np.mean((kk + nu) * (nu >= kk)) * pair
        out["fallback"] = RITZ_FALLBACK.get(metric, 0.0) * max(ritz - 1, 0) * ARPACK_BRANCH_PER_DOF * n
    else:
        out["shift_invert"] = n_branches * (SPARSE_BRANCH_FIXED + SPARSE_BRANCH_PER_DOF * n
                                            + SHIFT_PER_DOF_SLIDING * n * Ms + SHIFT_CUBE * float(Ms) ** 3
                                            + np.mean(nu) * pair)
    if deficit >= kk:                   # the probed branches with ν >= kk are priced with their own ν above
        out["floppy"] = n_branches * np.mean(nu < kk) * FLOPPY_PAIR_DOF * n * (kk + min(deficit, FLOPPY_CROWD * kk))
    return {key: float(v) for key, v in out.items()}


def refuse_over(source: str, seconds: float, timeout: float | None, work: str, alternatives: str = "") -> None:
    """Raise OverBudget (one line, with what to do) when the estimate exceeds the time asked (`timeout`; None: the
    CLI's ASK_SECONDS, which --timeout lifts)."""
    limit = ASK_SECONDS if timeout is None else timeout
    if seconds <= limit:
        return
    asked = (f"more than the {limit:.3g} s a run takes without --timeout: give --timeout {math.ceil(1.2 * seconds)} "
             "to run it (a line a minute on stderr says where it is), or " if timeout is None else
             f"more than the {limit:.3g} s left of --timeout: ")
    raise OverBudget(f"{source}: refused: {work} need about {seconds:.3g} s on this machine's free cores, {asked}"
                     f"{alternatives}cap the potentially sliding contacts (--max-sliding, or state = \"elastic\" for "
                     "contacts known to stick), analyse a smaller cluster around the region of interest"
                     + (", or raise --timeout" if timeout is not None else ""))


DENSE_ADVICE = ("cap the potentially sliding contacts (--max-sliding), use --method sparse with a small --k, "
                "analyse a smaller cluster, or raise --timeout")
SPARSE_ADVICE = ("lower --k, cap the potentially sliding contacts (--max-sliding), one metric instead of the family "
                 "(--metric L), analyse a smaller cluster, or raise --timeout")


@contextmanager
def deadline(seconds: float | None, source: str, advice: list):
    """Stop the enclosed work with OverBudget after `seconds` of wall time (SIGALRM; main thread only, where the
    CLI runs; elsewhere, or with None, no deadline). `advice[0]` (which the caller may update once it knows the
    path taken) ends the message."""
    import threading
    if not seconds or threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum, frame):
        raise OverBudget(f"{source}: stopped after --timeout {seconds:g} s, unfinished; {advice[0]}")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
