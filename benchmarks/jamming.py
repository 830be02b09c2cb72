"""Moduli of jammed packings against the literature (issue 24, docs/jamming.md): ensembles of jammed frictionless
harmonic bidisperse disks at pressures over two decades, made without granstab (`granstab_bench.jamming_packings`:
FIRE and Newton, the pressure found to 1e-10, rattlers removed), written as periodic contact-level scenes and
measured with `granstab.moduli`. Reported: the bulk and shear moduli B and G (jax-md's isotropic summaries), the
excess contacts, the fitted exponents G ~ p^a, B ~ p^b, Δz ~ p^c, G/B ~ Δz^e against the published 1/2, 0, 1/2, 1,
the fraction of packings with a negative shear modulus at fixed shape and at fixed stress (Dagois-Bohy et al.
2012), and the cost of making and of measuring each packing, side by side."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

import granstab

from . import jamming_packings as jp
from .figures import save
from .formatting import fmt_t, progress, table

PRESSURES = tuple(float(p) for p in np.logspace(-4, -2, 5))
QUICK = {"sizes": {64: 3}, "pressures": (1e-3, 1e-2), "onset": 1e-4, "shapes": ("fixed", "relaxed")}
FULL = {"sizes": {128: 12, 256: 4}, "pressures": PRESSURES, "onset": 1e-5, "shapes": ("fixed", "relaxed")}
SCALING_PN2 = 10.0   # the fits' window: p N² ≥ 10, above the finite-size crossover p N² ~ 1 (Goodrich et al. 2012)
EXPECTED = {"G": 0.5, "B": 0.0, "dz": 0.5, "G/B vs dz": 1.0}
BOOTSTRAP = 400


def measure(packing: dict) -> dict:
    """granstab's moduli of one packing (through the documented scene schema) beside the generator's own numbers."""
    x, radius, cell = packing["x"], packing["radius"], packing["cell"]
    t = time.process_time()
    scene = granstab.scene_from_dict(jp.scene_dict(x, radius, cell))
    result = granstab.moduli(scene)
    cpu = time.process_time() - t
    branch = result.branches[0]
    return {"pressure": packing["pressure"], "p_error": abs(result.pressure / packing["pressure"] - 1),
            "B": result.bulk, "G": result.shear, "C_min": float(branch.eigenvalues.min()),
            "fixed_stress_min": float(branch.fixed_stress_eigenvalues.min()),
            "shear_stress": float(np.hypot(result.stress[0, 1], 0.5 * (result.stress[0, 0] - result.stress[1, 1]))),
            "residual": result.errors["residual"], "symmetry_defect": result.errors["symmetry_defect"],
            "load_residual": result.errors["load_residual"], "rattlers": packing["rattlers"],
            "fire_steps": packing["steps"], "cpu_moduli": cpu, **jp.contact_numbers(x, radius, cell)}


def fit(pressures, samples: np.ndarray, seed: int = 0) -> dict:
    """The exponent a of mean(samples) ~ p^a (least squares in log-log over the pressures; samples (seeds, P)) and
    its bootstrap standard error over the seeds; resamples whose mean is not positive at some pressure are left
    out and counted."""
    logp = np.log(pressures)

    def slope(rows):
        mean = rows.mean(axis=0)
        return np.polyfit(logp, np.log(mean), 1)[0] if (mean > 0).all() else np.nan

    rng = np.random.default_rng(seed)
    boot = np.array([slope(samples[rng.integers(0, len(samples), len(samples))]) for _ in range(BOOTSTRAP)])
    return {"exponent": float(slope(samples)), "error": float(np.nanstd(boot)),
            "bootstrap_left_out": int(np.isnan(boot).sum())}


def fits(pressures, rows: list) -> dict:
    """Exponents of G, B and Δz in p and of G/B in Δz over one size's rows (seeds × pressures, complete seeds)."""
    seeds = sorted({r["seed"] for r in rows})
    grid = {key: np.array([[next(r[key] for r in rows if r["seed"] == s and r["pressure"] == p) for p in pressures]
                           for s in seeds]) for key in ("G", "B", "dz")}
    out = {"G": fit(pressures, grid["G"]), "B": fit(pressures, grid["B"]), "dz": fit(pressures, grid["dz"])}
    ratio, dz = grid["G"].mean(0) / grid["B"].mean(0), grid["dz"].mean(0)
    ok = (ratio > 0) & (dz > 0)
    out["G/B vs dz"] = {"exponent": float(np.polyfit(np.log(dz[ok]), np.log(ratio[ok]), 1)[0]) if ok.sum() > 1
                        else float("nan"), "error": float("nan"), "bootstrap_left_out": 0}
    out["G/B over dz"] = [float(v) for v in ratio / dz]
    return out


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL
    bar = progress(len(cfg["shapes"]) * sum(cfg["sizes"].values()), "jamming ensembles")
    rows, sizes, failed = [], {}, []
    for shape in cfg["shapes"]:
        for n, seeds in cfg["sizes"].items():
            for seed in range(seeds):
                bar.set_postfix_str(f"{shape} N={n} seed {seed}")
                t = time.process_time()
                try:
                    made = jp.packings(n, cfg["pressures"], seed=seed, onset=cfg["onset"],
                                       relax_shape=shape == "relaxed")
                except RuntimeError as error:               # reported, never hidden
                    failed.append({"shape": shape, "n": n, "seed": seed, "error": str(error)})
                    made = []
                cpu = (time.process_time() - t) / max(len(made), 1)
                rows += [{"shape": shape, "n": n, "seed": seed, "cpu_make": cpu, **measure(m)} for m in made]
                bar.update()
            sel = [r for r in rows if r["n"] == n and r["shape"] == shape]
            window = [p for p in cfg["pressures"] if p * n * n >= SCALING_PN2]
            sizes[f"{shape} {n}"] = {"all": fits(list(cfg["pressures"]), sel),
                                     "scaling": fits(window, [r for r in sel if r["pressure"] in window])
                                     if len(window) > 1 else None, "window": window}
    bar.close()
    return {"pressures": list(cfg["pressures"]), "onset": cfg["onset"], "rows": rows, "failed": failed,
            "fits": sizes, "expected": EXPECTED}


def _summary(results: dict) -> list:
    """One row per cell protocol, size and pressure: means ± standard errors over the seeds, fractions, costs."""
    out = []
    for shape, n in sorted({(r["shape"], r["n"]) for r in results["rows"]}):
        for p in results["pressures"]:
            sel = [r for r in results["rows"] if r["shape"] == shape and r["n"] == n and r["pressure"] == p]
            if not sel:
                continue
            col = {k: np.array([r[k] for r in sel]) for k in sel[0] if k not in ("shape", "n", "seed", "pressure")}
            sem = {k: v.std(ddof=1) / np.sqrt(len(v)) if len(v) > 1 else np.nan for k, v in col.items()}
            out.append({"shape": shape, "n": n, "p": p, "count": len(sel),
                        **{k: float(v.mean()) for k, v in col.items()},
                        **{f"{k}_sem": float(v) for k, v in sem.items()},
                        "neg_fixed_shape": float((col["C_min"] < 0).mean()),
                        "neg_fixed_stress": float((col["fixed_stress_min"] < 0).mean()),
                        "p_error_max": float(col["p_error"].max())})
    return out


def _failures(results: dict) -> list:
    """The lines naming the seeds whose pressure search failed (left out of every mean and fit), if any."""
    failed = results.get("failed") or []
    return ["Seeds left out (pressure search failed): "
            + "; ".join(f"{f['shape']} cell, N = {f['n']} seed {f['seed']}: {f['error']}" for f in failed), ""] \
        if failed else []


def _exponent(f: dict | None, key: str) -> str:
    if f is None:
        return "—"
    e = f[key]
    return f"{e['exponent']:.3f} ± {e['error']:.3f}" if np.isfinite(e["error"]) else f"{e['exponent']:.3f}"


def markdown(results: dict) -> str:
    rows = [[s["shape"], str(s["n"]), f"{s['p']:.3g}", f"{s['p'] * s['n'] ** 2:.3g}", str(s["count"]),
             f"{s['B']:.4f} ± {s['B_sem']:.4f}", f"{s['G']:.5f} ± {s['G_sem']:.5f}",
             f"{s['dz']:.4f} ± {s['dz_sem']:.4f}", f"{s['z_minus_2d']:.4f}",
             f"{s['G'] / s['B'] / s['dz']:.3f}" if s["dz"] > 0 else "—",
             f"{s['neg_fixed_shape']:.0%} / {s['neg_fixed_stress']:.0%}", f"{s['shear_stress'] / s['p']:.1e}",
             f"{s['p_error_max']:.0e}", f"{s['rattlers']:.1f}", fmt_t(s["cpu_make"]), fmt_t(s["cpu_moduli"])]
            for s in _summary(results)]
    frows = [[name.split()[0], name.split()[1], key, _exponent(f["all"], key),
              _exponent(f["scaling"], key) + (f" ({len(f['window'])} pressures)" if f["scaling"] else ""),
              f"{EXPECTED[key]:g}"] for name, f in results["fits"].items() for key in EXPECTED]
    return "\n".join([
        "## Jammed packings: moduli against the literature",
        "",
        "Jammed frictionless harmonic bidisperse disks (diameters 1 and 1.4, 1:1, U = ½kδ², k = 1) in a periodic "
        "cell, made without granstab by `granstab_bench.jamming_packings` (FIRE, Newton to round-off; "
        f"decompressed to p = {results['onset']:g}, near the onset, then compressed through the pressures, each "
        "found to 1e-10; rattlers — fewer than 3 contacts — removed recursively), written as periodic contact-level "
        "scenes (μ = 0) and measured by `granstab.moduli` (the one branch of a frictionless packing). *cell*: "
        "*fixed* keeps the square shape (O'Hern et al. 2003); *relaxed* lets the shape relax at each pressure "
        "(FIRE on the enthalpy: zero shear stress, Dagois-Bohy et al. 2012). B, G: jax-md's isotropic summaries of "
        "C (mean ± standard error over the seeds); Δz = 2(Nc − Nc_min)/N with Nc_min = 2(N − 1) + 1 (Goodrich, "
        "Liu & Nagel 2012), z − 2d beside it; *G < 0*: the share of packings with a negative eigenvalue of C at "
        "fixed cell shape / of C − Q at fixed stress; *τ/p*: the mean shear stress over p; *p error*: the largest "
        "|p_granstab / p − 1| (granstab's stress of the scene against the target). Costs are CPU time per "
        "packing: making it (FIRE steps and the pressure search) and `granstab.moduli`. What the numbers mean and "
        "the sources: [docs/jamming.md](docs/jamming.md).",
        "",
        *_failures(results),
        table(["cell", "N", "p / k", "p N²", "packings", "B", "G", "Δz", "z − 2d", "G/(B Δz)",
               "G < 0 (shape / stress)", "τ/p", "p error", "rattlers", "make (CPU)", "moduli (CPU)"], rows),
        "",
        "Exponents (least squares in log-log of the seeds' means; ± a bootstrap standard error over the seeds) "
        f"over all pressures and over those with p N² ≥ {SCALING_PN2:g} (above the finite-size crossover), against "
        "the published values:",
        "",
        table(["cell", "N", "quantity", "all pressures", f"p N² ≥ {SCALING_PN2:g}", "published"], frows),
    ])


def plot(results: dict, figdir: Path):
    summary = _summary(results)
    fig = Figure(figsize=(9, 3.6))
    left, right = fig.subplots(1, 2)
    for (shape, n), mk in zip(sorted({(s["shape"], s["n"]) for s in summary}), ("o", "s", "^", "v", "D", "P")):
        sel = [s for s in summary if s["shape"] == shape and s["n"] == n]
        p = np.array([s["p"] for s in sel])
        face = "none" if shape == "fixed" else None
        for key, color in (("B", "C0"), ("G", "C1"), ("dz", "C2")):
            y, err = np.array([s[key] for s in sel]), np.array([s[f"{key}_sem"] for s in sel])
            left.errorbar(p[y > 0], y[y > 0], yerr=np.minimum(err, 0.95 * y)[y > 0], fmt=mk + "-", color=color,
                          mfc=face, ms=4, capsize=2, lw=0.8, label=f"{key}, {shape}, N = {n}")
        ratio, dz = np.array([s["G"] / s["B"] for s in sel]), np.array([s["dz"] for s in sel])
        right.loglog(dz[ratio > 0], ratio[ratio > 0], mk, color="C3", mfc=face, label=f"{shape} cell, N = {n}")
    p = np.array([min(results["pressures"]), max(results["pressures"])])
    left.loglog(p, 0.8 * np.sqrt(p), "k:", label="0.8 (p/k)^½")
    dz = np.array([0.02, 0.6])
    right.loglog(dz, 0.3 * dz, "k:", label="0.3 Δz")
    left.set_xlabel("pressure p / k")
    left.set_ylabel("B, G (units of k), Δz")
    right.set_xlabel("Δz")
    right.set_ylabel("G / B")
    for ax in (left, right):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=5, ncol=2 if ax is left else 1)
    save(fig, figdir / "jamming.png")
