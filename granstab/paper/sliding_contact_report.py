"""Sec. 4.2, erratum 3: the eigenvalues of sym(F^sliding) over μ and α."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import rc_context
from matplotlib.figure import Figure

from granstab.paper import sliding_contact

from .figures import STYLE, bound, claim, g, save, section, write_csv


def steps() -> int:
    """Progress ticks of `run`."""
    return 4


def run(out: Path, tick, say) -> dict:
    """The sliding-contact study → CSV data, the figure and claim 4.2-l."""
    data = sliding_contact.study(progress=tick)
    say(f"sliding-contact: sym(F^sliding) eigenvalues = k(1 ± √(1+μ²))/2 (3D: + αk): law {data['error_law']:.1e}, "
        f"assembled {data['error_scene']:.1e} (relative)")
    rows = []
    for case in data["cases"]:
        for i, mu in enumerate(data["mu"]):
            for j, alpha in enumerate(data["alpha"]):
                rows.append([case["dim"], case["k"], mu, alpha, *case["law"][i, j], *([np.nan] * (3 - case["dim"])),
                             *case["closed"][i, j], *([np.nan] * (3 - case["dim"]))])
    files = [write_csv(out / "sliding_contact.csv", ["dim", "k", "mu", "alpha", "law1", "law2", "law3", "closed1",
                                                       "closed2", "closed3"], rows)]
    files += figure_sliding_contact(data, out)
    claims = [claim("4.2-l", "Sec. 4.2, erratum 3", "eigenvalues of sym(F^sliding) over μ and α",
                    "(1 ± √(1+μ²))/2", f"k(1 ± √(1+μ²))/2 for every α and k (3D adds αk): law within "
                    f"{bound(data['error_law'])}, assembled Hm within {bound(data['error_scene'])} "
                    "(relative to k, αk), "
                    f"μ ∈ [{g(data['mu'][0])}, {g(data['mu'][-1])}], α ∈ {{{', '.join(g(a) for a in data['alpha'])}}}, "
                    f"k ∈ {{{', '.join(g(k) for k in data['k'])}}}", "reproduced (with erratum 3)",
                    "The printed (1 - √(1+μ²))/2 lacks the factor k; the positive one is k(1 + √(1+μ²))/2.")]
    return {"data": data, "claims": claims, "files": files}


def figure_sliding_contact(data, out: Path) -> list[Path]:
    with rc_context(STYLE):
        fig = Figure(figsize=(7.6, 4.8), layout="constrained")
        ax = fig.add_subplot()
        mu = data["mu"]
        fine = np.linspace(0, mu[-1], 200)
        root = np.sqrt(1 + fine ** 2)
        ax.plot(fine, (1 + root) / 2, "-", color="tab:blue", lw=2, label="k(1 + √(1+μ²))/2")
        ax.plot(fine, (1 - root) / 2, "-", color="tab:red", lw=2, label="k(1 - √(1+μ²))/2  (negative)")
        markers = {0.25: "o", 0.5: "s", 1.0: "^", 2.0: "D"}
        for case in data["cases"]:
            if case["k"] != 1.0:
                continue
            for j, alpha in enumerate(data["alpha"]):
                lam = case["law"][:, j, :]
                if case["dim"] == 2:
                    ax.plot(mu[::3], lam[::3, 0], markers[alpha], mfc="none", color="k", ms=6,
                            label=f"granstab, 2D, α = {alpha:g}")
                    ax.plot(mu[::3], lam[::3, 1], markers[alpha], mfc="none", color="k", ms=6)
                else:
                    third = np.take_along_axis(lam, np.argmin(np.abs(lam - alpha), axis=1)[:, None], 1)[:, 0]
                    ax.plot(mu[1::3], third[1::3], ".", color="tab:green", ms=6)
        for alpha in data["alpha"]:
            ax.axhline(alpha, color="tab:green", lw=0.8, ls=":")
        ax.plot([], [], ":", color="tab:green", label="3D: third eigenvalue α k (α = 0.25, 0.5, 1, 2; dots)")
        ax.axvline(0.5, color="0.5", lw=0.8, ls="--")
        ax.annotate(f"μ = 0.5: {data['paper_negative']:.4f} k", xy=(0.5, data["paper_negative"]), xytext=(0.75, -0.45),
                    arrowprops={"arrowstyle": "->"}, fontsize=9)
        ax.set_xlabel("friction coefficient μ")
        ax.set_ylabel(r"eigenvalue of sym($F^{\mathrm{sliding}}$) / k")
        ax.set_title("Sliding contact stiffness (eq:ContactF): eigenvalues of its symmetric part")
        ax.set_xlim(0, mu[-1])
        ax.grid(True, alpha=0.3)
        ax.set_ylim(-0.5, 2.85)
        ax.legend(loc="upper left", fontsize=8, ncols=2, framealpha=0.95)
        return save(fig, out, "sliding_contact")


def markdown(sc: dict, link) -> str:
    """REPRODUCTION.md, Sec. 4.2 sliding contact: eigenvalues of sym(F^sliding) against k(1 ± √(1+μ²))/2."""
    L, add = section()
    add("## 4.2 Sliding contact stiffness (`granstab reproduce sliding-contact`)\n")
    data = sc["data"]
    add(f"![sliding contact]({link('sliding_contact.png')})\n")
    add("F^sliding = k[αI + (1-α) n⊗n] - h⊗g, g = k(αh + μn) (eq:ContactF). In the basis (n, h) it is "
        "k[[1, 0], [-μ, 0]]: the α terms cancel along h, so sym(F) has eigenvalues k(1 ± √(1+μ²))/2 for every α; in "
        "3D the second tangent adds αk. granstab's contact law and the translational block of the assembled Hm of a "
        "two-particle scene at yield (which equals F^pq) give these values within "
        f"{bound(max(data['error_law'], data['error_scene']))} (relative to k and αk) for μ ∈ "
        f"[{g(data['mu'][0])}, {g(data['mu'][-1])}], α ∈ {{{', '.join(g(a) for a in data['alpha'])}}}, "
        f"k ∈ {{{', '.join(g(k) for k in data['k'])}}}, 2D and 3D, random contact orientations "
        f"(`sliding_contact.csv`). At μ = 0.5: {g(data['paper_negative'], 6)} k. The paper prints "
        "(1 - √(1+μ²))/2 without the k (erratum 3, docs/errata.md).\n")
    return "\n".join(L)
    return "\n".join(L)
