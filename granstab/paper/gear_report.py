"""Sec. 4.1, Fig. 6: the gear-like mode of a regular disk packing and the rolling stiffness that stops it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import rc_context
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrowPatch

import granstab
from granstab.mechanics.branches import BOTH, MINUS, PLUS
from granstab.paper import gear

from .figures import STYLE, bound, claim, g, save, section, write_csv


def steps() -> int:
    """Progress ticks of `run`."""
    return 16


def run(out: Path, tick, say) -> dict:
    """The gear packing study → CSV data, the mode figure and claims 4.1-k, 4.1-l."""
    data = gear.study(progress=tick)
    g0, g1 = data["gear"], data["with_rolling"]
    say(f"gear: {g0['n_zero']} zeros without rolling stiffness (overlap with the counter-rotation "
        f"{g0['overlap']:.15f}), {g1['n_zero']} with k_r = {gear.PRESET_ROLLING:g} (gear-like eigenvalue "
        f"{g1['gear_like_eigenvalue']:.4g})")
    files = [write_csv(out / "gear_rolling_sweep.csv",
                        ["rolling_stiffness", "n_zero", "gear_like_eigenvalue", "gear_like_overlap", "rayleigh",
                         "estimate_4krM_over_N", "lowest_nonrigid", "verdict"],
                        [[r["rolling"], r["n_zero"], r["gear_like_eigenvalue"], r["gear_like_overlap"],
                          r["rayleigh"], r["estimate"], r["lowest_nonrigid"], r["verdict"]] for r in data["rolling"]])]
    files.append(write_csv(out / "gear_rho_sweep.csv", ["rho_over_r", "n_zero", "gear_like_eigenvalue", "verdict"],
                            [[r["rho_over_r"], r["n_zero"], r["gear_like_eigenvalue"], r["verdict"]]
                             for r in data["rho"]]))
    files.append(write_csv(out / "gear_parity.csv", ["n", "n_particles", "n_zero", "gear_like_eigenvalue",
                                                      "rigid_part_of_gear", "verdict"],
                            [[r["nx"], r["n_particles"], r["n_zero"], r["gear_like_eigenvalue"],
                              r["rigid_part_of_gear"], r["verdict"]] for r in data["parity"]]))
    mode = _gear_mode()
    files.append(write_csv(out / "gear_mode.csv", ["disk", "i", "j", "u1", "u2", "L_theta3", "checkerboard"],
                            mode["rows"]))
    files += figure_gear(data, mode, out)
    claims = [
        claim("4.1-k", "Sec. 4.1, Fig. 6", "a regular packing with M^pq = 0 admits a gear-like bifurcation mode",
              "synchronized counter-rotation",
              f"gear_packing.toml (4×4 disks, r = ρ): {g0['n_zero']} zero eigenvalues of sym(𝓗) (3 rigid + 1); "
              "the extra null vector is the checkerboard counter-rotation: 1 - |cos| "
              f"{bound(max(1 - g0['overlap'], 0))}, "
              f"translation share {bound(max(g0['translation_share'], 1e-300))}; verdict {g0['verdict']}"),
        claim("4.1-l", "Sec. 4.1", "the mode is inhibited by a genuine rotational (rolling) stiffness",
              "inhibited", f"gear_packing_rolling.toml (k_r = {gear.PRESET_ROLLING:g} k R²): {g1['n_zero']} zeros; "
              f"the gear-like eigenvalue is {g(g1['gear_like_eigenvalue'], 4)} k (Rayleigh quotient "
              f"{g(g1['rayleigh'], 4)} = 4 k_r M_c/N); verdict {g1['verdict']}", "reproduced"),
    ]
    return {"data": data, "mode": mode, "claims": claims, "files": files}


def _gear_mode() -> dict:
    """The computed extra null vector of the zero-rolling packing, per disk (from the core's branch)."""
    sc = gear.packing(**{k: gear.DEFAULT[k] for k in ("nx", "ny", "R", "f_h", "f_v", "k", "alpha", "mu")})
    res = granstab.analyze(sc, metric="L")
    b = res.branches[0]
    j = [i for i, c in enumerate(b.codes) if c in (PLUS, MINUS, BOTH) and abs(b.stability_eigenvalues[i]) <= b.zero_tol]
    v = b.stability_vectors[:, j[0]]
    v = v / v[2] * abs(v[2]) / np.abs(v[2::3]).max() if v[2] != 0 else v
    nx = gear.DEFAULT["nx"]
    rows = []
    for p, name in enumerate(sc.names):
        i, jj = p % nx, p // nx
        rows.append([name, i, jj, float(v[3 * p]), float(v[3 * p + 1]), float(v[3 * p + 2]), (-1) ** (i + jj)])
    return {"rows": rows, "x": sc.x, "R": gear.DEFAULT["R"], "theta": v[2::3], "u": v.reshape(-1, 3)[:, :2],
            "eigenvalue": float(b.stability_eigenvalues[j[0]])}


def figure_gear(data, mode, out: Path) -> list[Path]:
    with rc_context(STYLE):
        fig = Figure(figsize=(10.5, 4.7), layout="constrained")
        ax, bx = fig.subplots(1, 2, width_ratios=[1, 1.15])
        R = mode["R"]
        for (x, y), th in zip(mode["x"], mode["theta"]):
            color = "tab:blue" if th > 0 else "tab:red"
            ax.add_patch(Circle((x, y), R, fc=color, alpha=0.25, ec=color, lw=1.5))
            start, end = (x + 0.55 * R, y - 0.15 * R), (x - 0.55 * R, y - 0.15 * R)
            if th < 0:
                start, end = end, start
            ax.add_patch(FancyArrowPatch(start, end, connectionstyle=f"arc3,rad={0.9 if th > 0 else -0.9}",
                                         arrowstyle="-|>", mutation_scale=12, lw=1.4, color=color))
            ax.text(x, y - 0.5 * R, f"{th:+.2f}", ha="center", va="center", fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlim(-1.3 * R, mode["x"][:, 0].max() + 1.3 * R)
        ax.set_ylim(-1.3 * R, mode["x"][:, 1].max() + 1.3 * R)
        ax.set_xlabel("x₁ / R")
        ax.set_ylabel("x₂ / R")
        ax.set_title("Zero mode of gear_packing.toml (k_r = 0)\nrotation L dθ of each disk (normalised); "
                     "blue ccw, red cw")
        rows = [r for r in data["rolling"] if r["rolling"] > 0]
        kr = np.array([r["rolling"] for r in rows])
        bx.loglog(kr, [r["gear_like_eigenvalue"] for r in rows], "o", ms=7,
                  label=r"gear-like eigenvalue of sym($\mathcal{H}$)")
        bx.loglog(kr, [r["estimate"] for r in rows], "-", color="0.3",
                  label="4 k_r M_c / N (Rayleigh quotient of the gear vector)")
        bx.loglog(kr, [r["lowest_nonrigid"] for r in rows], "x", ms=7, color="tab:green",
                  label="lowest non-rigid eigenvalue")
        bx.axvline(gear.PRESET_ROLLING, color="0.6", ls=":", lw=1)
        bx.text(gear.PRESET_ROLLING * 1.1, 2e-3, "gear_packing_rolling.toml", rotation=90, fontsize=8, color="0.4")
        z = data["rolling"][0]
        bx.set_title(f"Rolling stiffness lifts the mode\n(k_r = 0: {z['n_zero']} zeros, gear-like |λ| "
                     f"{bound(abs(z['gear_like_eigenvalue']) / z['norm'])} of its norm)")
        bx.set_xlabel("rolling stiffness k_r / (k R²)")
        bx.set_ylabel("eigenvalue / k")
        bx.grid(True, which="both", alpha=0.3)
        bx.legend(loc="upper left")
        return save(fig, out, "gear_mode")


def markdown(gr: dict, link) -> str:
    """REPRODUCTION.md, Sec. 4.1 gear-like mode: the mode, the rolling and ρ/r sweeps, the parity finding."""
    L, add = section()
    data = gr["data"]
    g0, g1 = data["gear"], data["with_rolling"]
    add("## 4.1 Gear-like mode (`granstab reproduce gear`, Fig. 6)\n")
    add("`gear_packing.toml`: a 4 × 4 square packing of disks (R = 1, centres 2 apart, so r = ρ at every contact), "
        "normal forces f_h = 0.01, f_v = 0.02 on horizontal/vertical contacts, no rolling stiffness; "
        f"`gear_packing_rolling.toml`: the same with k_r = {gear.PRESET_ROLLING:g} k R².\n")
    add(f"![gear mode]({link('gear_mode.png')})\n")
    add(f"- Without rolling stiffness sym(𝓗) has {g0['n_zero']} zero eigenvalues; the part of the null space outside "
        f"the rigid motions is one vector, the checkerboard counter-rotation (-1)^(i+j) with no translation: 1 - |cos| "
        f"{bound(max(1 - g0['overlap'], 0))} with it, translation share "
        f"{bound(max(g0['translation_share'], 1e-300))}, rotation "
        f"amplitudes equal within {bound(max(g0['rotation_pattern_spread'], 1e-300))} (`gear_mode.csv`). It is "
        "consistent in both directions and has zero work: neutral (Type 2).")
    add(f"- With k_r = {gear.PRESET_ROLLING:g}: {g1['n_zero']} zeros (rigid only); the gear-like eigenvalue is "
        f"{g(g1['gear_like_eigenvalue'], 5)} k (|cos| with the gear vector {g(g1['gear_like_overlap'], 6)}), "
        "close to the "
        f"Rayleigh quotient 4 k_r M_c/N = {g(g1['estimate'], 4)} k. Verdict {g1['verdict']}.")
    add("- Sweep of k_r (`gear_rolling_sweep.csv`): " + "; ".join(
        f"k_r = {g(r['rolling'])}: {r['n_zero']} zeros, gear-like "
        f"{g(r['gear_like_eigenvalue'], 4) if r['rolling'] else '0'}"
        for r in data["rolling"]) + ".")
    add("- The zero needs r = ρ exactly (docs/errata.md): with ρ/r = " + ", ".join(
        f"{g(r['rho_over_r'])} → {g(r['gear_like_eigenvalue'], 3) if r['rho_over_r'] != 1 else '0'} ({r['verdict']})"
        for r in data["rho"]) + " (`gear_rho_sweep.csv`): the mode inherits the sign of λ⁽⁶⁾ = f(ρ - r).")
    par = {r["nx"]: r for r in data["parity"]}
    add(f"- Finding beyond the paper: an n × n packing with n odd has unequal numbers of clockwise and "
        "counter-clockwise disks, so the gear vector carries a net rotation "
        f"({g(par[3]['rigid_part_of_gear'], 3)} of it for 3 × 3). P^nrr removes that rotation and mixes the "
        "corotation of the loads (Hg3) into the mode, which is then "
        f"not a zero: {g(par[3]['gear_like_eigenvalue'], 3)} k for 3 × 3 ({par[3]['verdict']}), "
        f"{g(par[5]['gear_like_eigenvalue'], 3)} k for 5 × 5, against exact zeros for 2 × 2 and 4 × 4 "
        "(`gear_parity.csv`). The paper's Fig. 6 does not say which packing it shows.\n")
    return "\n".join(L)
