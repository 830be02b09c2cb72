"""The λ⁽⁶⁾ field of the symmetric pair over (ρ/r, f/(kr)) (Fig. Contours), and its PNG (no viser).

λ⁽⁶⁾ is the rolling eigenvalue: its eigenvector is ν ∝ [0, 0, 1, 0, 0, -1] (docs/errata.md, symmetric case), which is
orthogonal to the rigid modes, so λ⁽⁶⁾ = νᵀ sym(𝓗) ν = νᵀ H ν in the scaled dofs [du, L dθ] of the analysis
(L = r).
The field is computed for a normal contact force (no mobilised friction, as in the paper's figure) at the
current α and rolling stiffness, in units of k. Without rolling stiffness the field is the batched one of
granstab.paper.two_particle (the paper's own 6×6 matrices); with it, the core's per-contact blocks
(granstab.mechanics.stiffness.contact_blocks) give every grid point at once. tests/app/test_app_state.py checks that the two
agree where both apply.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

import granstab
from granstab.mechanics.stiffness import contact_blocks

RHO_R = np.round(np.arange(0.2, 3.0 + 1e-9, 0.05), 10)                 # (57,)
F_KR = np.round(np.arange(-0.005, 0.02 + 1e-9, 0.0005), 10)             # (51,)


@dataclass(frozen=True, eq=False)
class Field:
    rho_r: np.ndarray          # (n_rho,)
    f_kr: np.ndarray           # (n_f,)
    lam: np.ndarray            # (n_f, n_rho): λ⁽⁶⁾/k
    alpha: float
    rolling: float
    source: str                # which code computed it


def _studies_field(alpha: float, rolling: float):
    """The batched field of granstab.paper.two_particle, if it exists and fits this call (else None)."""
    try:
        from granstab.paper import two_particle
    except ImportError:
        return None
    fn = getattr(two_particle, "lambda6_field", None)
    if fn is None or rolling != 0.0:
        return None
    return np.asarray(fn(RHO_R, F_KR, alpha=alpha)["lam6"]), "granstab.paper.two_particle.lambda6_field"


def _grid_scene(alpha: float, rolling: float, r: float = 1.0):
    """One scene holding a separate symmetric pair (k = 1) for every grid point, contacts in (f, ρ) row order."""
    rho, f = np.meshgrid(RHO_R * r, F_KR * r, indexing="xy")           # (n_f, n_rho), k = 1
    rho, f = rho.ravel(), f.ravel()
    M = rho.size
    t = np.array([0.0, 1.0])
    x = np.zeros((2 * M, 2))
    x[1::2, 0] = 2 * r
    K = (-1.0 / rho)[:, None, None] * np.outer(t, t)
    arrays = {"p": np.arange(0, 2 * M, 2), "q": np.arange(1, 2 * M, 2),
              "point": np.tile([r, 0.0], (M, 1)) + x[0::2], "normal": np.tile([1.0, 0.0], (M, 1)),
              "curvature_p": K, "curvature_q": K.copy(), "force": np.stack([-f, np.zeros(M)], axis=1),
              "moment": np.zeros((M, 1)), "k": np.ones(M), "alpha": np.full(M, alpha), "mu": np.full(M, 0.5),
              "rolling": np.full((M, 1, 1), rolling * r * r),
              "state": tuple("auto" if v >= 0 else "elastic" for v in f)}
    return granstab.build_scene(2, [f"{s}{i}" for i in range(M) for s in "pq"], x, arrays, source="λ⁽⁶⁾ grid")


@lru_cache(maxsize=8)
def lambda6_field(alpha: float, rolling: float, use_studies: bool = True) -> Field:
    """λ⁽⁶⁾/k on the (ρ/r, f/(kr)) grid for tangential/normal stiffness ratio α and rolling stiffness/(kr²).

    Every grid point is one contact of a single scene, so the core builds all per-contact H blocks at once
    (granstab.mechanics.stiffness.contact_blocks); λ⁽⁶⁾ = νᵀ H ν with ν = [0, 0, 1, 0, 0, -1]/√2 in each block (r = L = 1)."""
    got = _studies_field(alpha, rolling) if use_studies else None
    if got is not None:
        lam, source = got
        return Field(RHO_R, F_KR, lam.reshape(len(F_KR), len(RHO_R)), alpha, rolling, source)
    blocks = contact_blocks(_grid_scene(alpha, rolling)).blocks
    H = sum(blocks[name] for name in ("Hg1", "Hg2", "Hg3", "Hm"))      # (M, 6, 6), r = 1
    nu = np.array([0, 0, 1.0, 0, 0, -1.0]) / np.sqrt(2)
    lam = np.einsum("i,mij,j->m", nu, H, nu).reshape(len(F_KR), len(RHO_R))
    return Field(RHO_R, F_KR, lam, alpha, rolling, "granstab.mechanics.stiffness.contact_blocks (all grid points at once)")


def _contour(field: Field, size=(6, 4.5), dpi=120):
    """Matplotlib figure and axes of the λ⁽⁶⁾/k contour: filled levels, the zero line (black), a colour bar."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=size, dpi=dpi)
    lim = float(np.abs(field.lam).max()) or 1.0
    cs = ax.contourf(field.rho_r, field.f_kr, field.lam, levels=np.linspace(-lim, lim, 21), cmap="RdBu")
    ax.contour(field.rho_r, field.f_kr, field.lam, levels=[0.0], colors="k", linewidths=1.5)
    fig.colorbar(cs, ax=ax, label="λ⁽⁶⁾ / k")
    ax.set_xlabel("ρ/r")
    ax.set_ylabel("f/(kr)")
    return fig, ax


def _png(fig) -> bytes:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def field_png(field: Field, mark=None) -> bytes:
    """The contour plot as PNG bytes (matplotlib, Agg), with the current (ρ/r, f/(kr)) marked."""
    fig, ax = _contour(field)
    if mark is not None:
        ax.plot([mark[0]], [mark[1]], marker="*", color="gold", markeredgecolor="k", markersize=16)
    ax.set_title(f"rolling eigenvalue λ⁽⁶⁾, α = {field.alpha:g}, rolling stiffness = {field.rolling:g} kr²")
    fig.tight_layout()
    return _png(fig)


@lru_cache(maxsize=8)
def field_picture(field: Field) -> tuple[bytes, tuple]:
    """The contour without a mark, for the page, as PNG bytes and where its plot area lies in the picture: (left,
    bottom, right, top) in fractions of the width and height (the page places the current-state ★ over it). Drawn
    at twice the size the side panel shows it (≈ 410 px wide): sharp, with readable labels."""
    fig, ax = _contour(field, size=(4.1, 3.4), dpi=200)
    fig.tight_layout()
    box = ax.get_position()
    return _png(fig), (box.x0, box.y0, box.x1, box.y1)
