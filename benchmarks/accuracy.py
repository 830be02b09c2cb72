"""Error against run time: every way of getting an answer (closed form, dense, sparse at several tolerances,
LOBPCG, finite differences of exact geometry) with its median run time and its distance to a reference."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from granstab.analysis import analyze
from granstab.mechanics.branches import RIGID
from granstab.mechanics.rigid import Projection, dof_scale, rotation_length, rotations
from granstab.model import shapes
from granstab.paper import two_particle as tp
from granstab.solve import sparse

from .figures import save
from .formatting import fmt_e, fmt_t, table
from .references import dense_lowest, nonrigid
from .timing import once, timeit

QUICK = {"sizes": (30,), "repeat": 3, "slow": 0.5, "min_time": 0.0}
FULL = {"sizes": (60, 200), "repeat": 5, "slow": 3.0, "min_time": 0.1}
EXACT_GEOMETRY = Path(__file__).resolve().parent.parent / "tests" / "exact_geometry.py"
K = 6
FLOOR = 1e-17          # an exact result (error 0) is drawn on this line
MARKERS = {"closed": "*", "dense": "s", "sparse shift": "o", "sparse LOBPCG": "^", "exact": "D", "sparse low": "v"}


def exact_geometry():
    """tests/exact_geometry.py (complex-step derivative of exact rigid-body statics), None if the checkout lacks it."""
    if not EXACT_GEOMETRY.exists():
        return None
    spec = importlib.util.spec_from_file_location("exact_geometry", EXACT_GEOMETRY)
    module = sys.modules.setdefault("exact_geometry", importlib.util.module_from_spec(spec))
    spec.loader.exec_module(module)
    return module


def projected_lowest(scene, H, k, length):
    """Lowest k non-rigid eigenvalues of P sym(D H D) P in scaled dofs, from a dense physical H (n × n)."""
    D = dof_scale(scene.n_particles, scene.dim, length)
    Hs = D[:, None] * H * D[None, :]
    Hs = 0.5 * (Hs + Hs.T)
    C = rotations(scene, length)
    proj = Projection.from_rotations(C)
    A = proj.both(proj.right(Hs))
    lam, V = np.linalg.eigh(0.5 * (A + A.T))
    return nonrigid(lam, V, scene, C)[:k]


def lowest_nonrigid(result, k):
    """The k lowest non-rigid eigenvalues of sym(𝓗) of an analysis' first branch."""
    b = result.branches[0]
    return np.sort(b.stability_eigenvalues[b.codes != RIGID])[:k]


def pair_case(eg, cfg) -> list:
    """λ⁽⁶⁾ of two ellipses (tip radius ρ = 0.5, r = 1) pressed by δ = 0.01 against f(ρ − r): (case, way, t, err)."""
    rho, delta = 0.5, 0.01
    b = np.sqrt(rho * 1.0)
    pair = [("p", shapes.Ellipse(1.0, b), ((0.0, 0.0), 0.0)), ("q", shapes.Ellipse(1.0, b), ((2.0 - delta, 0.0), 0.0))]
    sc = shapes.scene_from_shapes(2, pair, k=1.0, alpha=1.0, mu=0.5)
    f = float(-sc.force[0, 0])
    exact6 = f * (rho - 1.0)                       # λ⁽⁶⁾ = f(ρ_eff - r_eff), both reduced by δ/2 (docs/errata.md)
    ways = [("closed form f(ρ − r)", lambda: tp.lambda6(1.0, rho, f)),
            ("dense core analyze()", lambda: min(analyze(sc, rotation_length=1.0).branches[0].stability_eigenvalues)),
            ("sparse lowest_modes (dense fallback at 6 dofs)",
             lambda: sparse.lowest_modes(sparse.sparse_problem(sc, length=1.0), k=1).eigenvalues[0])]
    if eg is not None:
        ways += [("exact geometry, complex step (tests/exact_geometry.py)",
                  lambda: projected_lowest(sc, eg.stiffness_exact(eg.cluster_from_scene(sc, pair)), 1, 1.0)[0]),
                 ("exact geometry, central differences h = 1e-3 (Richardson)",
                  lambda: projected_lowest(sc, eg.central_difference(eg.cluster_from_scene(sc, pair)), 1, 1.0)[0])]
    points = []
    for name, fn in ways:
        t, val = timeit(fn, repeat=cfg["repeat"], min_time=cfg["min_time"], slow=cfg["slow"])
        points.append(("pair, λ⁽⁶⁾", name, t, abs(float(val) - exact6) / 2.0))   # relative to ‖𝓗‖ ≈ 2k
    return points


def cluster_case(eg, n_side, cfg) -> tuple[list, str]:
    """A triangular patch of about n_side disks with tangential forces: the lowest 6 non-rigid eigenvalues of
    sym(𝓗) of every way against the exact-geometry reference (dense eigh without it). Points and the reference."""
    cols = int(np.sqrt(n_side))
    rws = int(np.ceil(n_side / cols))
    a = 2.0 - 1e-3
    parts = [(f"d{j}_{i}", shapes.Disk(1.0), (((i + 0.5 * (j % 2)) * a, j * a * np.sqrt(3) / 2), 0.0))
             for j in range(rws) for i in range(cols)]
    sc = shapes.scene_from_shapes(2, parts, k=1.0, alpha=0.8, mu=0.5, mobilised=0.4)
    L = rotation_length(sc)
    norm = sparse.sparse_problem(sc).norm
    if eg is not None:
        t_ref, ref = once(lambda: projected_lowest(sc, eg.stiffness_exact(eg.cluster_from_scene(sc, parts)), K, L))
        label_ref = "exact geometry, complex step"
    else:
        t_ref, ref = once(lambda: dense_lowest(sc, K))
        label_ref = "dense eigh (no exact-geometry harness in this checkout)"
    case = f"{sc.n_particles} disks, lowest {K}"
    ways = [("dense core analyze()", lambda: lowest_nonrigid(analyze(sc, method="dense"), K)),
            ("dense sym(𝓗) + numpy eigh", lambda: dense_lowest(sc, K))]
    for tol in (1e-1, 1e-3, 1e-6, 0.0):
        ways.append((f"sparse shift-invert, tol {tol:g}" if tol else "sparse shift-invert, tol 0 (machine)",
                     lambda tol=tol: sparse.lowest_modes(sparse.sparse_problem(sc), k=K, tol=tol,
                                                         method="shift-invert").eigenvalues))
    for tol in (1e-2, 1e-4, 1e-8):
        ways.append((f"sparse LOBPCG, residual tol {tol:g}",
                     lambda tol=tol: sparse.lowest_modes(sparse.sparse_problem(sc), k=K, tol=tol,
                                                         method="lobpcg").eigenvalues))
    if eg is not None:
        ways.append(("exact geometry, central differences (Richardson)",
                     lambda: projected_lowest(sc, eg.central_difference(eg.cluster_from_scene(sc, parts)), K, L)))
    points = [(case, label_ref + " (reference)", t_ref, 0.0)]
    for name, fn in ways:
        t, val = timeit(fn, repeat=cfg["repeat"], min_time=cfg["min_time"], slow=cfg["slow"])
        points.append((case, name, t, float(np.abs(np.asarray(val) - ref).max() / norm)))
    return points, label_ref


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    eg = exact_geometry()
    points = pair_case(eg, cfg)
    for n in cfg["sizes"]:
        points += cluster_case(eg, n, cfg)[0]
    return {"exact_geometry": eg is not None,
            "points": [{"case": c, "way": w, "t": t, "error": e} for c, w, t, e in points]}


def plot(results: dict, figdir: Path):
    """Error against run time: one panel per case, one marker and colour per way, named in each panel's legend;
    an exact result (error 0) sits on the floor line, the reference itself is not drawn."""
    points = [p for p in results["points"] if not p["way"].endswith("(reference)")]
    cases = list(dict.fromkeys(p["case"] for p in points))
    fig = Figure(figsize=(5.2 * len(cases), 5.0))
    axes = fig.subplots(1, len(cases), squeeze=False)
    for ax, case in zip(axes[0], cases):
        for i, p in enumerate([p for p in points if p["case"] == case]):
            mk = next((m for key, m in MARKERS.items() if p["way"].startswith(key)), "x")
            ax.loglog(p["t"], max(p["error"], FLOOR), mk, ms=8, color=f"C{i % 10}", label=p["way"].replace("𝓗", "H"))
        ax.axhline(FLOOR, color="gray", lw=0.5)
        ax.set_title(case.replace("λ⁽⁶⁾", "λ6"), fontsize=9)
        ax.set_xlabel("run time (s, median)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=1, frameon=False)
    axes[0][0].set_ylabel("error / ‖H‖  (floor 1e-17 = exact)")
    fig.suptitle("error against run time (markers: ★ closed form, ■ dense, ● shift-invert, ▲ LOBPCG, "
                 "◆ exact geometry)", fontsize=9)
    save(fig, figdir / "error_vs_time.png", bbox_inches="tight")


def markdown(results: dict) -> str:
    rows = [[p["case"], p["way"], fmt_t(p["t"]),
             "0 (reference)" if p["way"].endswith("(reference)") else fmt_e(p["error"])] for p in results["points"]]
    eg_note = ("The exact-geometry reference is tests/exact_geometry.py (another helper's harness): rigid disks/"
               "ellipses with compliant contacts, the loads that hold them in equilibrium differentiated by the "
               "complex step (exact to round-off) — an answer independent of granstab's stiffness code. Its own "
               "error is its distance to the dense core (the rows 'dense core' in each case). A finite difference "
               "of the core's OWN loads would not be exact geometry and is not used."
               if results["exact_geometry"] else
               "tests/exact_geometry.py is not in this checkout: the exact-geometry reference is MISSING and the "
               "dense core is the reference instead (a finite difference of the core's own loads would not be "
               "exact geometry, so none is offered).")
    return "\n".join([
        "## Error against run time",
        "",
        "Each way of getting the answer, its run time (median) and its error. Pair: λ⁽⁶⁾ of two ellipses "
        "(tip radius ρ = 0.5, r = 1) pressed by δ = 0.01, against the closed form f(ρ − r) (exact for the pressed "
        "pair, docs/errata.md: both radii shrink by δ/2). Clusters: triangular patches of disks with tangential "
        "forces, the lowest 6 non-rigid eigenvalues of sym(𝓗) against the exact-geometry reference; error = "
        "max |Δλ| / ‖Hs‖. Sparse tolerances: eigsh's relative accuracy (shift-invert), LOBPCG's residual tolerance.",
        "",
        eg_note,
        "",
        table(["case", "way", "time", "error"], rows),
        "",
        "![error vs time](docs/bench/error_vs_time.png)",
    ])
