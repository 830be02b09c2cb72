"""Eigenvalues of the symmetric part of the sliding contact stiffness (Sec. 4.2; erratum 3, docs/errata.md).

F^sliding = k[αI + (1-α) n⊗n] - h⊗g with g = k(αh + μn) (eq:ContactF, eq:G). In the basis (n, h) of 2D,
F = k [[1, 0], [-μ, 0]]: the α-terms cancel along h, so sym(F) = k [[1, -μ/2], [-μ/2, 0]] has the eigenvalues

    k (1 ± √(1 + μ²)) / 2          for every α          (the paper prints (1 - √(1+μ²))/2 without the k),

and in 3D the second tangent direction adds α k. The study evaluates them three ways over μ and α (and two values
of k, to show the unit): from the core's contact law (granstab.model.law.contact_stiffness), from the assembled
mechanical stiffness of a two-particle scene at yield (the translational block Hm[p, p] equals F^pq, eq:Hm), and
in closed form; a random contact orientation makes sure nothing depends on n = e1.
"""
from __future__ import annotations

import numpy as np

import granstab
from granstab.model.law import contact_stiffness
from granstab.model.vec import tangent_basis

MU = np.linspace(0.05, 1.5, 30)     # μ > 0: with μ = 0 a contact at yield has no sliding direction h
ALPHA = (0.25, 0.5, 1.0, 2.0)
K_VALUES = (1.0, 2.5)


def closed_form(mu, alpha, k: float = 1.0, dim: int = 2) -> np.ndarray:
    """Sorted eigenvalues of sym(F^sliding): k(1 - √(1+μ²))/2, [αk,] k(1 + √(1+μ²))/2, shape (..., dim)."""
    mu, alpha = np.broadcast_arrays(np.asarray(mu, float), np.asarray(alpha, float))
    root = np.sqrt(1.0 + mu ** 2)
    vals = [k * (1 - root) / 2, k * (1 + root) / 2] + ([alpha * k] if dim == 3 else [])
    return np.sort(np.stack(vals, -1), axis=-1)


def _frame(dim: int, seed: int):
    """A random unit normal and a unit tangent of it (the sliding direction)."""
    rng = np.random.default_rng(seed)
    n = rng.standard_normal(dim)
    n /= np.linalg.norm(n)
    T = tangent_basis(n)
    h = T @ rng.standard_normal(dim - 1)
    return n, h / np.linalg.norm(h)


def law_eigenvalues(mu, alpha, k: float = 1.0, dim: int = 2, seed: int = 0) -> np.ndarray:
    """Sorted eigenvalues of sym(F) from granstab.model.law.contact_stiffness, batched over broadcast μ, α: (..., dim)."""
    mu, alpha = np.broadcast_arrays(np.asarray(mu, float), np.asarray(alpha, float))
    n, h = _frame(dim, seed)
    m = mu.size
    force = np.tile(-n + (mu.reshape(-1)[:, None] * h), (1, 1))      # f·n = -1, |f_t| = μ: at yield
    F = contact_stiffness(np.tile(n, (m, 1)), np.full(m, k), alpha.reshape(-1), mu.reshape(-1), force,
                          np.ones(m, bool))
    lam = np.linalg.eigvalsh(0.5 * (F + np.swapaxes(F, 1, 2)))
    return lam.reshape(mu.shape + (dim,))


def scene_eigenvalues(mu: float, alpha: float, k: float = 1.0, dim: int = 2, seed: int = 0) -> np.ndarray:
    """Sorted eigenvalues of sym(Hm[p, p]) of a two-particle scene whose contact is at yield, on its sliding branch."""
    n, h = _frame(dim, seed)
    f = 0.01 * k
    force = -f * n + mu * f * h
    contact = {"p": "p", "q": "q", "point": (0.5 * n).tolist(), "normal": n.tolist(), "force": force.tolist(),
               "k": k, "alpha": alpha, "mu": mu, "state": "sliding"}
    if dim == 2:
        contact.update(curvature_p=-2.0, curvature_q=-2.0)
    else:
        K = (-2.0 * (np.eye(3) - np.outer(n, n))).tolist()
        contact.update(curvature_p=K, curvature_q=K)
    sc = granstab.scene_from_dict({"dim": dim, "particles": [{"name": "p", "x": [0.0] * dim},
                                                             {"name": "q", "x": n.tolist()}],
                                   "contacts": [contact]}, source="<sliding_contact>")
    Hm = granstab.stiffness(sc, mask=[1]).Hm[:dim, :dim]
    return np.linalg.eigvalsh(0.5 * (Hm + Hm.T))


def study(mu=MU, alphas=ALPHA, k_values=K_VALUES, progress=None) -> dict:
    """Eigenvalues of sym(F^sliding) over μ × α × k in 2D and 3D: law, assembled scene and closed form."""
    out = {"mu": np.asarray(mu, float), "alpha": np.asarray(alphas, float), "k": np.asarray(k_values, float),
           "cases": []}
    worst = {"law": 0.0, "scene": 0.0}
    for dim in (2, 3):
        for k in k_values:
            M, A = np.meshgrid(out["mu"], out["alpha"], indexing="ij")
            law = law_eigenvalues(M, A, k, dim)
            closed = closed_form(M, A, k, dim)
            scene = np.array([[scene_eigenvalues(m, a, k, dim) for a in out["alpha"]] for m in out["mu"]])
            scale = k * np.maximum(1.0, A)[..., None]                # eigenvalues are of size k and αk
            err_law = float(np.max(np.abs(law - closed) / scale))
            err_scene = float(np.max(np.abs(scene - closed) / scale))
            worst["law"] = max(worst["law"], err_law)
            worst["scene"] = max(worst["scene"], err_scene)
            out["cases"].append({"dim": dim, "k": k, "law": law, "scene": scene, "closed": closed,
                                 "error_law": err_law, "error_scene": err_scene})
            if progress:
                progress()
    out["error_law"], out["error_scene"] = worst["law"], worst["scene"]
    out["paper_mu"] = 0.5
    out["paper_negative"] = float((1 - np.sqrt(1 + 0.5 ** 2)) / 2)   # in units of k: -0.0590
    return out
