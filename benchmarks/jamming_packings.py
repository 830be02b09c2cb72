"""Jammed frictionless harmonic disk packings at a target pressure, made without granstab (numpy and scipy only), so
that granstab's moduli of them are checked against the literature and against finite differences of an energy
that granstab never sees (docs/jamming.md).

The model of O'Hern, Silbert, Liu & Nagel (PRE 68, 011306, 2003): bidisperse disks (half of diameter 1, half of
diameter `ratio` = 1.4) in a periodic square cell, pair energy U = ½ k δ² for an overlap δ = R_p + R_q − s > 0 (s the
centre distance to the minimum image). Protocol:
random positions at packing fraction 0.90, FIRE (Bitzek et al., PRL 97, 170201, 2006) and Newton steps to force
balance at round-off, then the cell is rescaled affinely (a bracketed secant in its size, each step relaxed again)
until p = −tr σ / d equals the target to 1e-10; rattlers (fewer than d + 1 contacts, removed recursively, as the
literature does) are taken out and the pressure found again. With `onset`, a seed is first decompressed near its
jamming onset and then compressed through the pressures, each from the last; with `relax_shape`, the cell's shape
relaxes too at each pressure (FIRE on the enthalpy: zero shear stress, Dagois-Bohy et al., PRL 109, 095703, 2012).

Conventions of the scene contract (docs/periodic.md): q's copy at x_q + image @ cell, branch b^pq = copy − x_p, the
force on p by q f^pq = −k δ n, σ = (1/V) Σ f^pq ⊗ b^pq (tension positive), so p = Σ k δ s / (d V).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

DIAMETER_SMALL = 1.0


def pairs(x: np.ndarray, radius: np.ndarray, cell: np.ndarray, candidates=None, gap: float = 0.0):
    """Pairs closer than contact + gap under the minimum image (all pairs i < j, or those of `candidates`):
    p, q, image (P, d), branch b (P, d), distance s, overlap δ = R_p + R_q − s (> −gap)."""
    p, q = np.triu_indices(len(x), 1) if candidates is None else candidates
    frac = (x[q] - x[p]) @ np.linalg.inv(cell)
    image = -np.round(frac).astype(np.int64)
    b = (frac + image) @ cell
    s = np.linalg.norm(b, axis=1)
    delta = radius[p] + radius[q] - s
    on = delta > -gap
    return p[on], q[on], image[on], b[on], s[on], delta[on]


def energy(x, radius, cell, k: float = 1.0, candidates=None):
    """U = Σ ½ k δ² and its gradient (N, d) (pairs among `candidates` where given)."""
    p, q, _, b, s, delta = pairs(x, radius, cell, candidates)
    f = (k * delta / s)[:, None] * b                       # force on q by p (repulsive, along b)
    grad = np.zeros_like(x)
    np.add.at(grad, p, f)
    np.add.at(grad, q, -f)
    return 0.5 * k * float(delta @ delta), grad


def hessian(x, radius, cell, k: float = 1.0) -> np.ndarray:
    """∂²U/∂x∂x (N d, N d) of the harmonic pairs: k n⊗n − (k δ / s)(I − n⊗n) per pair."""
    N, d = x.shape
    p, q, _, b, s, delta = pairs(x, radius, cell)
    n = b / s[:, None]
    nn = n[:, :, None] * n[:, None, :]
    block = k * nn - (k * delta / s)[:, None, None] * (np.eye(d) - nn)
    H = np.zeros((N, d, N, d))
    for a, c, sign in ((p, p, 1.0), (q, q, 1.0), (p, q, -1.0), (q, p, -1.0)):
        np.add.at(H, (a, slice(None), c), sign * block)
    return H.reshape(N * d, N * d)


def stress(x, radius, cell, k: float = 1.0) -> np.ndarray:
    """σ = (1/V) Σ f^pq ⊗ b^pq with f^pq = −k δ n (the force on p by q): tension positive."""
    _, _, _, b, s, delta = pairs(x, radius, cell)
    f = -(k * delta / s)[:, None] * b
    return np.einsum("mi,mj->ij", f, b) / abs(np.linalg.det(cell))


def pressure(x, radius, cell, k: float = 1.0) -> float:
    return float(-np.trace(stress(x, radius, cell, k)) / x.shape[1])


def fire(x, radius, cell, k: float = 1.0, ftol: float = 1e-9, max_steps: int = 200_000, dt_max: float = 0.2,
         skin: float = 0.2):
    """FIRE (Bitzek et al. 2006, their parameters: N_min 5, f_inc 1.1, f_dec 0.5, α 0.1, f_α 0.99), unit masses,
    until max |force| < ftol; a Verlet list (pairs within contact + skin, rebuilt once a particle moved skin/2).
    Returns (x, steps)."""
    v = np.zeros_like(x)
    dt, alpha, since = 0.1 * dt_max, 0.1, 0
    built, near = None, None
    for step in range(max_steps):
        if built is None or np.abs(x - built).max() > 0.25 * skin:
            built, near = x.copy(), pairs(x, radius, cell, gap=skin)[:2]
        F = -energy(x, radius, cell, k, near)[1]
        if np.abs(F).max() < ftol:
            return x, step
        if float(np.vdot(F, v)) > 0:
            v = (1 - alpha) * v + alpha * np.linalg.norm(v) * F / np.linalg.norm(F)
            since += 1
            if since > 5:
                dt, alpha = min(1.1 * dt, dt_max), 0.99 * alpha
        else:
            v[:] = 0.0
            dt, alpha, since = 0.5 * dt, 0.1, 0
        v = v + dt * F                                      # semi-implicit Euler, unit masses
        x = x + dt * v
    return x, max_steps


def enthalpy_forces(x, radius, cell, pressure_: float, k: float = 1.0):
    """Minus the gradient of the enthalpy H = U + p V over the positions (N, d) and the cell's deformation D
    (cell = cell₀ D, x = X D at D = I): (−∂U/∂x, −∂H/∂D) with ∂U/∂D = Σ b ⊗ ∂U/∂b and ∂(pV)/∂D = p V I."""
    p, q, _, b, s, delta = pairs(x, radius, cell)
    g = -(k * delta / s)[:, None] * b                        # ∂U/∂b
    grad = np.zeros_like(x)
    np.add.at(grad, p, -g)
    np.add.at(grad, q, g)
    return -grad, -(b.T @ g + pressure_ * abs(np.linalg.det(cell)) * np.eye(x.shape[1]))


def fire_cell(x, radius, cell, target: float, k: float = 1.0, ftol: float = 1e-9, max_steps: int = 400_000,
              dt_max: float = 0.2):
    """FIRE on the enthalpy at pressure `target` over the positions and the cell's shape and size (the cell's
    coordinates D·L, L = √V, so that its stiffness is ~B like a particle's): the shear stress relaxes to zero
    and the packing settles where it is stable at fixed stress (Dagois-Bohy et al. 2012's remedy). Until every
    force (the cell's: |∂H/∂D| / L) is below ftol; returns (x, cell, steps)."""
    d = x.shape[1]
    L = np.sqrt(abs(np.linalg.det(cell)))
    v, w = np.zeros_like(x), np.zeros((d, d))
    dt, alpha, since = 0.1 * dt_max, 0.1, 0
    for step in range(max_steps):
        F, T = enthalpy_forces(x, radius, cell, target, k)
        T = T / L
        if max(np.abs(F).max(), np.abs(T).max()) < ftol:
            return x, cell, step
        power = float(np.vdot(F, v) + np.vdot(T, w))
        if power > 0:
            scale = np.sqrt((np.vdot(v, v) + np.vdot(w, w)) / (np.vdot(F, F) + np.vdot(T, T)))
            v, w = (1 - alpha) * v + alpha * scale * F, (1 - alpha) * w + alpha * scale * T
            since += 1
            if since > 5:
                dt, alpha = min(1.1 * dt, dt_max), 0.99 * alpha
        else:
            v[:], w[:] = 0.0, 0.0
            dt, alpha, since = 0.5 * dt, 0.1, 0
        v, w = v + dt * F, w + dt * T
        D = np.eye(d) + dt * w / L                             # x → (x + dt v) D, cell → cell D
        x, cell = (x + dt * v) @ D, cell @ D
    return x, cell, max_steps


def newton(x, radius, cell, k: float = 1.0, floor: float = 0.0, steps: int = 6):
    """Newton steps on the force balance (least squares, QR with pivoting: the translations and rattlers' dofs are
    null) until max |force| < floor; only taken from a state FIRE brought close to a minimum."""
    from scipy.linalg import lstsq

    for _ in range(steps):
        g = energy(x, radius, cell, k)[1]
        if np.abs(g).max() < floor:
            break
        step = lstsq(hessian(x, radius, cell, k), g.ravel(), cond=1e-12, lapack_driver="gelsy")[0]
        x = x - step.reshape(x.shape)
    return x


def relax(x, radius, cell, k: float = 1.0, force_scale: float = 1e-3):
    """FIRE to max |force| < 1e-5 force_scale, then Newton steps; FIRE again, tighter, where a contact change spoilt
    Newton. Force balance at round-off (max |force| below 1e-11 force_scale or, where that is under the round-off
    of the positions, 100 ε k L) or a RuntimeError. Returns (x, FIRE steps)."""
    total, floor = 0, max(1e-11 * force_scale, 100 * np.finfo(float).eps * k * np.abs(cell).max())
    for ftol in (1e-5, 1e-8, 1e-11):
        x, steps = fire(x, radius, cell, k, ftol=ftol * force_scale)
        x, total = newton(x, radius, cell, k, floor), total + steps
        if np.abs(energy(x, radius, cell, k)[1]).max() < floor:
            return x, total
    raise RuntimeError("no force balance at round-off (Newton does not converge from FIRE's state)")


def rattlers(x, radius, cell) -> np.ndarray:
    """Mask of the rattlers: particles left with fewer than d + 1 contacts once the other rattlers are removed."""
    N, d = x.shape
    keep = np.ones(N, bool)
    while True:
        p, q, *_ = pairs(x[keep], radius[keep], cell)
        count = np.bincount(np.r_[p, q], minlength=int(keep.sum()))
        low = count < d + 1
        if not low.any():
            return ~keep
        keep[np.flatnonzero(keep)[low]] = False


def _next_factor(seen, lo: float, hi: float, target: float, d: int) -> float:
    """The next cell factor: the secant through the last two (factor, p), both jammed, where it stays inside the
    bracket (lo, hi) and the last step at least halved the error (not across a jump of p); else the bracket's
    midpoint; else a step from p ≈ φ − φ_J (slope 1, φ ~ 0.85), compressing by at least Δφ = 0.002 from an
    unjammed state (p below 1% of the target)."""
    factor, p = seen[-1]
    if len(seen) > 1:
        (f0, p0), (f1, p1) = seen[-2:]
        halved = len(seen) == 2 or abs(p1 - target) < 0.5 * abs(p0 - target)
        if halved and min(p0, p1) > 0.01 * target and p0 != p1:
            new = f1 + (target - p1) * (f0 - f1) / (p0 - p1)
            if lo < new < hi:
                return new
    if lo > 0 and np.isfinite(hi):
        return 0.5 * (lo + hi)
    dphi = max(target - p, 2e-3) if p < 0.01 * target else target - p
    return factor * np.exp(-dphi / (d * 0.85))


def at_pressure(x, radius, cell, target: float, k: float = 1.0, rtol: float = 1e-10, max_iter: int = 100):
    """Rescale the cell by a factor (positions affinely) and relax until p = target to rtol (the round-off of p is
    ~ε·diameter/δ ~ 1e-12 of p at p = 1e-4), the factor from `_next_factor` (p falls as the cell grows; an unjammed
    state, p = 0, is below the target). Where p jumps across the target (a rearrangement between two factors 1e-13
    apart), it goes on afresh from the state after the jump. Returns (x, cell, FIRE steps in all)."""
    d = x.shape[1]
    x, total = relax(x, radius, cell, k, target)
    relaxed, seen = {1.0: x}, []                             # factor -> relaxed positions; (factor, p) in order
    lo, hi = 0.0, np.inf                                     # factors known too dense / too loose
    factor = 1.0
    for _ in range(max_iter):
        p = pressure(relaxed[factor], radius, cell * factor, k)
        if abs(p - target) <= rtol * target:
            return relaxed[factor], cell * factor, total
        seen.append((factor, p))
        lo, hi = (max(lo, factor), hi) if p > target else (lo, min(hi, factor))
        if lo > 0 and hi / lo - 1 < 1e-13:
            relaxed, seen, lo, hi, factor = {hi: relaxed[hi]}, [], 0.0, np.inf, hi
            continue
        new = _next_factor(seen, lo, hi, target, d)
        near = min(relaxed, key=lambda f: abs(f - new))
        x, steps = relax(relaxed[near] * (new / near), radius, cell * new, k, target)
        relaxed[new], factor, total = x, new, total + steps
    raise RuntimeError(f"pressure {target:g} not reached to {rtol:g} in {max_iter} rescalings (last p = {p:.6g})")


def packings(n: int, pressures, seed: int = 0, ratio: float = 1.4, k: float = 1.0, phi0: float = 0.90,
             onset: float | None = None, relax_shape: bool = False):
    """One seed's packings at each pressure, rattlers removed: a list of dicts {pressure (the target), x (N', d),
    radius (N',), cell (d, d), rattlers (how many were removed), steps (FIRE steps)}. n bidisperse disks, half of
    diameter 1, half of diameter `ratio`, random positions at phi0. `onset` (a pressure): first decompressed to it
    (near the jamming onset, p N² ≲ 1), then compressed to the pressures in increasing order, each from the last,
    as O'Hern et al. make states above φ_c; None: decompressed from phi0 to each pressure in decreasing order.
    `relax_shape`: at each pressure the cell's shape relaxes too (`fire_cell`: zero shear stress, stable at fixed
    stress, Dagois-Bohy et al. 2012), before the size is set to the exact pressure at that shape."""
    rng = np.random.default_rng(seed)
    radius = 0.5 * DIAMETER_SMALL * np.where(np.arange(n) < n // 2, 1.0, ratio)
    side = np.sqrt(np.pi * (radius ** 2).sum() / phi0)
    cell = side * np.eye(2)
    x = rng.uniform(0.0, side, (n, 2))
    total = 0
    if onset:
        x, cell, total = at_pressure(x, radius, cell, onset, k)
    out = []
    for target in sorted(pressures, reverse=not onset):
        removed = 0
        while True:                                         # at the pressure, then without its rattlers, again
            x, cell, s = at_pressure(x, radius, cell, target, k)
            total += s
            if relax_shape:
                x, cell, s = fire_cell(x, radius, cell, target, k, ftol=1e-8 * target)
                x, cell, s2 = at_pressure(x, radius, cell, target, k)
                total += s + s2
            gone = rattlers(x, radius, cell)
            if not gone.any():
                break
            x, radius, removed = x[~gone], radius[~gone], removed + int(gone.sum())
        x = x - np.floor(x @ np.linalg.inv(cell)) @ cell    # inside the cell
        out.append({"pressure": target, "x": x.copy(), "radius": radius.copy(), "cell": cell.copy(),
                    "rattlers": removed, "steps": total})
        total = 0
    return out


def contact_numbers(x, radius, cell) -> dict:
    """Contacts Nc, particles N', z = 2 Nc / N', z − 2d and the excess over the minimal count of a jammed periodic
    packing Nc_min = d(N' − 1) + 1 (Goodrich, Liu & Nagel, PRL 109, 095704, 2012): Δz = 2(Nc − Nc_min) / N'."""
    N, d = x.shape
    Nc = len(pairs(x, radius, cell)[0])
    minimal = d * (N - 1) + 1
    return {"contacts": Nc, "particles": N, "z": 2 * Nc / N, "z_minus_2d": 2 * Nc / N - 2 * d,
            "excess": Nc - minimal, "dz": 2 * (Nc - minimal) / N}


def scene_dict(x, radius, cell, k: float = 1.0, title: str = "") -> dict:
    """The packing as a contact-level periodic scene in the documented JSON/TOML schema (docs/formats.md): μ = 0
    (frictionless: F = k n⊗n), the contact point midway through the overlap, each side's curvature that of the
    circle about its centre through that point (−1/(R − δ/2)), q's image per contact, the force −k δ n on p."""
    p, q, image, b, s, delta = pairs(x, radius, cell)
    n = b / s[:, None]
    point = x[p] + (radius[p] - 0.5 * delta)[:, None] * n
    contacts = [{"p": f"p{i}", "q": f"p{j}", "image": img.tolist(), "point": pt.tolist(), "normal": nn.tolist(),
                 "curvature_p": -1.0 / (radius[i] - 0.5 * dl), "curvature_q": -1.0 / (radius[j] - 0.5 * dl),
                 "force": (-k * dl * nn).tolist()}
                for i, j, img, pt, nn, dl in zip(p, q, image, point, n, delta)]
    return {"dim": 2, "title": title or f"jammed harmonic disks, {len(x)} particles, {len(p)} contacts",
            "cell": cell.tolist(), "defaults": {"k": k, "alpha": 0.0, "mu": 0.0},
            "particles": [{"name": f"p{i}", "x": xi.tolist()} for i, xi in enumerate(x)], "contacts": contacts}


def save(path, made: list) -> None:
    """Packings (dicts of `packings`, each with its "seed") to JSON: Python writes each float as its shortest exact
    repr, so the positions read back bit for bit (the stress to 1e-10 needs them to ~1e-15)."""
    import json

    keep = ("seed", "pressure", "cell", "x", "radius")
    rows = [{k: (np.asarray(m[k]).tolist() if k in ("cell", "x", "radius") else m[k]) for k in keep} for m in made]
    Path(path).write_text(json.dumps({"model": "frictionless harmonic disks, k = 1 (granstab_bench.jamming_packings)",
                                      "packings": rows}, separators=(",", ":")) + "\n", encoding="utf-8")


def load(path) -> list:
    """The packings of `save`, as arrays."""
    import json

    rows = json.loads(Path(path).read_text(encoding="utf-8"))["packings"]
    return [{"seed": int(r["seed"]), "pressure": float(r["pressure"]), "cell": np.array(r["cell"]),
             "x": np.array(r["x"]), "radius": np.array(r["radius"])} for r in rows]
