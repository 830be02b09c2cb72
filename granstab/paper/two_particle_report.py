"""Sec. 4.1, two particles: the λ⁽⁶⁾ field, the sample table, the presets; figure, data and claims."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import rc_context
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

import granstab
from granstab.paper import two_particle

from .figures import STYLE, bound, claim, g, save, section, write_csv

#: the coarse grid on which granstab.analyze itself is run for the λ⁽⁶⁾ check (it contains ρ/r = 1 and f = 0)
CORE_RHO = np.linspace(0.2, 3.0, 29)
CORE_FORCE = np.linspace(-0.005, 0.02, 26)
#: the fine grid of the figure; ρ/r = 1 and f = 0 fall between grid lines, where bilinear interpolation of
#: λ⁽⁶⁾ = f(ρ - r) is exact, so the drawn zero contour is exactly the two lines
FIG_RHO = np.linspace(0.2, 3.0, 140)
FIG_FORCE = np.linspace(-0.005, 0.02, 125)


def steps() -> int:
    """Progress ticks of `run`."""
    return 2 + CORE_RHO.size * CORE_FORCE.size


def run(out: Path, tick, say) -> dict:
    """λ⁽⁶⁾ field (closed forms, granstab's blocks, analyze on a coarse grid), samples, presets → files, claims."""
    field = two_particle.lambda6_field(FIG_RHO, FIG_FORCE, verify=True)   # closed forms + the paper's matrices
    grid = two_particle.core_blocks_field(FIG_RHO, FIG_FORCE)        # granstab's own H, every grid point
    tick()
    core = two_particle.core_field(CORE_RHO, CORE_FORCE, progress=tick)
    samples = two_particle.sample_table()
    tick()
    general = two_particle.general_case_check()
    presets, glove = _presets(), _hand_in_glove()
    say(f"two-particle: λ6 field {grid['lam6'].size} points, |granstab - closed| / ‖𝓗‖ ≤ "
        f"{max(grid['error_lam5'], grid['error_lam6']):.1e} (paper matrices "
        f"{max(field['error_lam5'], field['error_lam6']):.1e}); analyze on {core['lam6'].size} points ≤ "
        f"{max(core['error_lam5'], core['error_lam6']):.1e}")

    files = _write_data(out, grid, samples, field, core)   # data
    files += figure_lambda6(grid, out)

    # claims
    F, R = np.meshgrid(field["f_over_kr"], field["rho_over_r"], indexing="ij")
    lam6 = grid["lam6"]
    sign_ok = bool(np.all(np.sign(lam6) == np.sign(F * (R - 1))))
    on_lines = np.isclose(core["rho_over_r"][None, :], 1.0) | np.isclose(core["f_over_kr"][:, None], 0.0, atol=1e-12)
    neutral_on_lines = bool(np.all(core["verdict"][on_lines] == "neutral"))
    off = ~on_lines
    compressive = core["f_over_kr"][:, None] > 1e-12
    sharp = core["rho_over_r"][None, :] < 1
    verdict_ok = bool(np.all(core["verdict"][off & compressive & sharp] == "unstable")
                      and np.all(core["verdict"][off & compressive & ~sharp] == "stable"))
    lam5_min = float(grid["lam5"].min())
    claims = [
        claim("4.1-a", "Sec. 4.1, eq:exampleH2", "H of the two-particle system (Table 1)",
              "eq:exampleH2", f"core H = eq:exampleH2 for 20 random unequal r, ρ, k, α, f: max rel. diff "
              f"{bound(general)}", "reproduced (with erratum 2)",
              "eq:exampleH2 agrees with the corrected B of Appendix C (erratum 2, docs/errata.md), not with the "
              "printed one."),
        claim("4.1-b", "Sec. 4.1", "both stiffnesses symmetric (elastic contact, normal force)", "symmetric",
              f"max |H - Hᵀ|/‖𝓗‖ over the grid {bound(grid['asymmetry'])} (granstab), "
              f"{bound(field['max_asymmetry'])} (eq:exampleH2)", "reproduced"),
        claim("4.1-c", "Sec. 4.1, obs. 1", "three zero eigenvalues (two translations, one rotation)", "3",
              f"3 off the lines ρ = r and f = 0 (sample table); rigid leakage of 𝓗 {bound(field['max_rigid_leakage'])}"),
        claim("4.1-d", "Sec. 4.1, obs. 2", "λ⁽⁴⁾ = 2k, ν⁽⁴⁾ = [1, 0, 0, -1, 0, 0]/√2", "2k",
              f"2k on the whole grid: error {bound(grid['error_lam4'])} ‖𝓗‖ (granstab's H), "
              f"{bound(field['error_lam4'])} (paper's matrix), {bound(core['error_lam4'])} (analyze, coarse grid)"),
        claim("4.1-e", "Sec. 4.1, obs. 3", "a positive shearing eigenvalue λ⁽⁵⁾", "positive (no formula)",
              "λ⁽⁵⁾ = 2αk(1+r²) - f[(1+r²)² - rρ(2+r²)]/(ρ(1+r²)); min over the grid "
              f"{g(lam5_min, 4)} k > 0; closed form = granstab within {bound(grid['error_lam5'])} ‖𝓗‖ "
              f"(paper's matrix {bound(field['error_lam5'])}, analyze {bound(core['error_lam5'])})",
              "reproduced (closed form new)"),
        claim("4.1-f", "Sec. 4.1, obs. 4, Fig. 5", "λ⁽⁶⁾ (rolling) can be positive, zero or negative",
              "contour plot only", f"λ⁽⁶⁾ = f(ρ - r), exact for all k, α: granstab within "
              f"{bound(grid['error_lam6'])} ‖𝓗‖ (paper's matrix {bound(field['error_lam6'])}, analyze "
              f"{bound(core['error_lam6'])}); "
              f"ν⁽⁶⁾ = [0, 0, 1, 0, 0, -1]/√2 (1 - overlap {bound(max(1 - field['min_overlap6'], 0))})",
              "reproduced (closed form new)"),
        claim("4.1-g", "Sec. 4.1, Fig. 5", "sharp contacts (ρ/r < 1) unstable, flat (ρ/r > 1) stable, for any f > 0",
              "λ⁽⁶⁾ < 0 sharp, > 0 flat",
              f"sign(λ⁽⁶⁾) = sign(f(ρ/r - 1)) at all {lam6.size} grid points: {sign_ok}; core verdicts "
              f"unstable/stable on the {int(np.sum(off & compressive))} compressive off-line points: {verdict_ok}",
              "reproduced" if sign_ok and verdict_ok else "DIFFERS",
              "For cohesive forces (f < 0) the signs swap: sharp contacts stable, flat unstable."),
        claim("4.1-h", "Sec. 4.1", "Type-2 neutral equilibrium where λ⁽⁶⁾ = 0: disks (ρ/r = 1) or f = 0",
              "ρ/r = 1 or f = 0",
              f"zero set of λ⁽⁶⁾ = exactly these two lines; core: 4 zeros and verdict 'neutral' at all "
              f"{int(on_lines.sum())} points on them: {neutral_on_lines}",
              "reproduced" if neutral_on_lines else "DIFFERS"),
        claim("4.1-i", "Sec. 4.1", "two circular disks pressed together: neutral equilibrium and stability",
              "λ⁽⁶⁾ = 0", f"two_disks.toml: |λ⁽⁶⁾| {bound(abs(presets['two_disks.toml']['lam6']))} k, "
              f"{presets['two_disks.toml']['n_zero']} zeros, verdict {presets['two_disks.toml']['verdict']}"),
        claim("4.1-j", "Sec. 4.1", "hand in glove (ρ^p ≈ -ρ^q): the geometric stiffness dominates",
              "f/(ρ^p+ρ^q) large", f"hand_in_glove.toml (ρ^p = 1, ρ^q = -1.002, f/(kr) = 0.01): ‖Hg‖₂/‖Hm‖₂ = "
              f"{g(glove['ratio'], 3)}; eigenvalues {', '.join(g(v, 4) for v in glove['eig'])}; {glove['verdict']}"),
    ]
    return {"field": field, "grid": grid, "core": core, "samples": samples, "presets": presets, "glove": glove,
            "claims": claims, "files": files}


def _write_data(out: Path, grid: dict, samples: list, field: dict, core: dict) -> list:
    """The λ⁽⁵⁾, λ⁽⁶⁾ grids and the sample table as CSV, every field in one NPZ; the files written."""
    files = []
    for name in ("lam6", "lam5"):
        rows = [[f] + list(grid[name][i]) for i, f in enumerate(grid["f_over_kr"])]
        files.append(write_csv(out / f"two_particle_{name}_grid.csv",
                                ["f_over_kr \\ rho_over_r"] + [f"{r:.6g}" for r in grid["rho_over_r"]], rows))
    rows = []
    for s in samples:
        rows.append([s["rho_over_r"], s["f_over_kr"], *s["core_sorted"], *s["core_modes"], s["closed"][4],
                     s["closed"][5], s["n_zero"], s["verdict"]])
    files.append(write_csv(out / "two_particle_samples.csv",
                            ["rho_over_r", "f_over_kr", "eig1", "eig2", "eig3", "eig4", "eig5", "eig6", "lambda4",
                             "lambda5", "lambda6", "lambda5_closed", "lambda6_closed", "n_zero", "verdict"], rows))
    np.savez(out / "two_particle.npz", **{k: v for k, v in grid.items() if isinstance(v, np.ndarray)},
             paper_lam4=field["lam4_stacked"], paper_lam5=field["lam5_stacked"], paper_lam6=field["lam6_stacked"],
             closed_lam5=field["lam5"], closed_lam6=field["lam6"],
             analyze_lam6=core["lam6"], analyze_lam5=core["lam5"], analyze_rho=core["rho_over_r"],
             analyze_f=core["f_over_kr"])
    return files


def _presets() -> dict:
    """The core's modes of the three two-particle presets."""
    return {name: two_particle.core_modes(1.0, rho, 0.01) for name, rho in
            (("two_particle.toml", 0.5), ("two_particle_flat.toml", 2.0), ("two_disks.toml", 1.0))}


def _hand_in_glove() -> dict:
    """hand_in_glove.toml, built by the study (tests check the preset file against the same builder)."""
    sc = two_particle.scene(1.0, 1.0, 0.01, rq=2.0, rhoq=-1.002, state="auto")
    K = granstab.stiffness(sc)
    Hg = K.Hg1 + K.Hg2 + K.Hg3
    res = granstab.analyze(sc, metric="L", rotation_length=1.0)
    lam = res.branches[0].stability_eigenvalues
    return {"ratio": float(np.linalg.norm(Hg, 2) / np.linalg.norm(K.Hm, 2)),
            "eig": [float(v) for v in lam[np.abs(lam) > res.branches[0].zero_tol]],
            "verdict": res.summary["verdict"]}


def figure_lambda6(field, out: Path) -> list[Path]:
    with rc_context(STYLE):
        fig = Figure(figsize=(7.6, 5.8), layout="constrained")
        ax = fig.add_subplot()
        R, F, L = field["rho_over_r"], field["f_over_kr"], field["lam6"]
        levels = np.linspace(-0.016, 0.04, 29)
        cf = ax.contourf(R, F, L, levels=levels, cmap="RdBu", norm=TwoSlopeNorm(0.0, -0.016, 0.04), extend="both")
        lines = ax.contour(R, F, L, levels=[-0.012, -0.008, -0.004, 0.004, 0.01, 0.02, 0.03],
                           colors="0.25", linewidths=0.6)
        ax.clabel(lines, fmt=lambda v: f"{v:+.3g}".replace("-", "−"), fontsize=7.5)
        ax.contour(R, F, L, levels=[0.0], colors="k", linewidths=2.2)
        cb = fig.colorbar(cf, ax=ax, ticks=np.arange(-0.016, 0.041, 0.008))
        cb.set_label(r"$\lambda^{(6)}/(k r^2)$   (rolling eigenvalue of $\mathbb{H}$)")
        ax.set_xlabel("ρ / r   (radius of curvature at the contact / contact radius)")
        ax.set_ylabel("f / (k r)   (normal force; > 0 compression)")
        ax.set_title(r"Two equal particles ($r^p = r^q$, $\rho^p = \rho^q$, $\alpha = 1$): "
                     r"rolling eigenvalue $\lambda^{(6)} = f\,(\rho - r)$")
        box = {"boxstyle": "round,pad=0.3", "fc": "white", "ec": "0.6", "alpha": 0.9}
        ax.text(0.6, 0.0145, r"SHARP  $\rho/r < 1$" "\n" r"unstable: $\lambda^{(6)} < 0$", ha="center",
                va="center", bbox=box)
        ax.text(2.0, 0.0145, r"FLAT  $\rho/r > 1$" "\n" r"stable: $\lambda^{(6)} > 0$", ha="center",
                va="center", bbox=box)
        ax.text(0.6, -0.0032, "cohesive f < 0: sharp stable", ha="center", va="center", fontsize=8, bbox=box)
        ax.text(1.6, -0.0032, "cohesive f < 0: flat unstable", ha="center", va="center", fontsize=8, bbox=box)
        ax.annotate(r"$\lambda^{(6)} = 0$ on $\rho/r = 1$ (disks)" "\n" r"and on $f = 0$: neutral (Type 2)",
                    xy=(1.0, 0.006),
                    xytext=(1.35, 0.0065), fontsize=8, arrowprops={"arrowstyle": "->", "lw": 0.8}, bbox=box)
        for (rho, f, marker, label) in ((0.5, 0.01, "X", "two_particle.toml"), (1.0, 0.01, "s", "two_disks.toml"),
                                        (2.0, 0.01, "o", "two_particle_flat.toml")):
            ax.plot(rho, f, marker, ms=8, mfc="gold", mec="k", label=f"preset {label}")
        fig.legend(loc="outside lower center", ncols=3, frameon=False)
        ax.set_xlim(R[0], R[-1])
        ax.set_ylim(F[0], F[-1])
        return save(fig, out, "two_particle_lambda6")


def markdown(tp: dict, link) -> str:
    """REPRODUCTION.md, Sec. 4.1 two particles: closed forms, the λ⁽⁶⁾ figure, the sample table."""
    L, add = section()
    field, core = tp["field"], tp["core"]
    add("## 4.1 Two-particle system (`granstab reproduce two-particle`)\n")
    add("Table 1 of Appendix C: two particles on the e1 axis, normal n = e1, compressive normal force f (f^pq = "
        "[-f, 0]), elastic contact (k, αk), no moment stiffness; presets `two_particle.toml` (sharp, ρ/r = 0.5), "
        "`two_particle_flat.toml` (ρ/r = 2), `two_disks.toml` (ρ = r), `hand_in_glove.toml` (ρ^p = 1, ρ^q = -1.002).\n")
    add("**Closed forms** (symmetric case r^p = r^q = r, ρ^p = ρ^q = ρ; derived with sympy from eq:exampleH2 and "
        "eq:exampleC, whose characteristic polynomial factors as λ³(λ - 2k)(λ - λ⁽⁵⁾)(λ - λ⁽⁶⁾)):\n")
    add("- λ⁽¹⁻³⁾ = 0 (two translations, the rotation about the centre)")
    add("- λ⁽⁴⁾ = 2k, ν⁽⁴⁾ = [1, 0, 0, -1, 0, 0]/√2 (normal indentation)")
    add("- λ⁽⁵⁾ = 2αk(1 + r²) - f[(1 + r²)² - rρ(2 + r²)] / (ρ(1 + r²)) (tangential shearing; the 1 in 1 + r² is one "
        "length², i.e. the paper's literal metric with r = 1 here)")
    add("- λ⁽⁶⁾ = f(ρ - r) for every k and α, ν⁽⁶⁾ = [0, 0, 1, 0, 0, -1]/√2 (rolling): λ⁽⁶⁾/(k r²) = "
        "(f/(kr))(ρ/r - 1), zero exactly on ρ/r = 1 and on f = 0.\n")
    add(f"![λ6 contour]({link('two_particle_lambda6.png')})\n")
    grid = tp["grid"]
    add(f"The figure and the grid data are granstab's: one scene holding all {grid['lam6'].size} grid points "
        f"({len(grid['f_over_kr'])} × {len(grid['rho_over_r'])}, ρ/r ∈ [{g(grid['rho_over_r'][0])}, "
        f"{g(grid['rho_over_r'][-1])}], f/(kr) ∈ [-0.005, 0.02], α = 1) as separate pairs, whose per-contact "
        "stiffness blocks (Hg1 + Hg2 + Hg3 + Hm) are projected with eq:exampleC and solved as stacked 6×6 "
        "eigenproblems on the complement of the rigid motions; modes are named by their overlap with ν⁽⁴⁾ and ν⁽⁶⁾. "
        "Largest difference from the closed forms, relative to ‖𝓗‖₂: "
        f"λ⁽⁴⁾ {bound(grid['error_lam4'])}, λ⁽⁵⁾ {bound(grid['error_lam5'])}, λ⁽⁶⁾ {bound(grid['error_lam6'])}; the "
        f"paper's own matrices give {bound(field['error_lam4'])}, {bound(field['error_lam5'])}, "
        f"{bound(field['error_lam6'])}. The full pipeline, granstab.analyze, on a {len(core['f_over_kr'])} × "
        f"{len(core['rho_over_r'])} grid that contains ρ/r = 1 and f = 0: λ⁽⁴⁾ {bound(core['error_lam4'])}, λ⁽⁵⁾ "
        f"{bound(core['error_lam5'])}, λ⁽⁶⁾ {bound(core['error_lam6'])}. Data: `two_particle_lam6_grid.csv`, "
        "`two_particle_lam5_grid.csv` (rows f/(kr), columns ρ/r), `two_particle.npz` (all arrays).\n")
    add("All six eigenvalues of ℍ (granstab, sorted) at sample points, r = k = α = 1, and the named modes:\n")
    add("| ρ/r | f/(kr) | eigenvalues of ℍ (sorted) | λ⁽⁴⁾ | λ⁽⁵⁾ | λ⁽⁵⁾ closed | λ⁽⁶⁾ | λ⁽⁶⁾ closed "
        "| zeros | verdict |")
    add("|---|---|---|---|---|---|---|---|---|---|")
    for s in tp["samples"]:
        eig = ", ".join("0" if abs(v) < 1e-12 else g(v, 6) for v in s["core_sorted"])
        lam4, lam5, lam6 = s["core_modes"]
        add(f"| {g(s['rho_over_r'])} | {g(s['f_over_kr'])} | {eig} | {g(lam4, 6)} | {g(lam5, 7)} | "
            f"{g(s['closed'][4], 7)} | {'0' if abs(lam6) < 1e-12 else g(lam6, 6)} | "
            f"{'0' if abs(s['closed'][5]) < 1e-15 else g(s['closed'][5], 6)} | {s['n_zero']} | {s['verdict']} |")
    add("")
    glove = tp["glove"]
    add(f"Hand in glove (`hand_in_glove.toml`): ‖Hg‖₂/‖Hm‖₂ = {g(glove['ratio'], 3)}; the non-zero eigenvalues "
        f"{', '.join(g(v, 4) for v in glove['eig'])} (two convex particles: about 0.01, 2 and 4): the socket holds the "
        f"ball, verdict {glove['verdict']}. The factor f/(ρ^p + ρ^q) = -5 k of eq:exampleH2 makes the geometric "
        "stiffness dominate, as the paper says.\n")
    return "\n".join(L)
