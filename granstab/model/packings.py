"""Large scenes for benchmarks and scale tests: lattice and random disk/sphere packings, built without any
per-particle or per-contact Python loop (10⁵ particles and 10⁶ contacts in a few seconds).

Every scene is valid contact-level data (Sec. 2): unit normals along the centre lines, tangent curvatures,
compressive forces inside the friction cone, loads from equilibrium (eq:equil1, the scene-format default).

* `lattice(dim, size)`: equal disks/spheres on a triangular (2D) or face-centred cubic (3D) lattice, or a
  square/simple-cubic one. The geometry is that of compliant round particles: centre distance a, overlap δ, so the
  contact point sits midway and each side's curvature is that of the parallel curve through it, -1/(a/2)
  (docs/errata.md, "Where the curvature is evaluated"); `curvature_ratio` = ρ/r ≠ 1 makes the contacts sharper (< 1)
  or flatter (> 1) than a disk.
* `random_packing(dim, n)`: a random contact network: jittered triangular/fcc lattice sites, polydisperse radii,
  contacts between lattice neighbours with the contact point on the centre line at the radius ratio and the
  curvature of the local radius (times `curvature_ratio`), random force magnitudes and mobilised friction.
  It is valid contact-level data, not a mechanically relaxed packing (no relaxation is run).

* `jammed(dim, n, phi)`: a jammed frictionless periodic packing of harmonic bidisperse disks/spheres
  (U = ½k(s - r)², s the centre distance, r the sum of the radii) in a square/cubic (or sheared) cell at packing
  fraction phi, relaxed to force balance at round-off (L-BFGS, then Newton), rattlers removed; its contacts carry
  images across the cell (model/periodic.py). Test fixtures and examples of periodic scenes.

`chain(dim, n)`: a straight or zig-zag chain of disks/spheres under compression, floppy (many clustered
near-zero eigenvalues) and banded.

`lattice`, `random_packing` and `chain` accept `f_over_k` (normal force / (k r)), `mobilised` (|f_t| / μ f_n, in [0, 1)), `n_sliding` (that many
contacts put exactly at yield: 2^n_sliding loading branches), `moments` (contact moments as a fraction of
f r; 0 = none), `rolling` (rolling stiffness / (k r²)), `seed`.
"""
from __future__ import annotations

import numpy as np

from .periodic import minimum_image
from .scene import Scene, build_scene
from .tolerances import DEFAULT, Tolerances
from .vec import rot_dim, tangent_basis

KINDS = {2: ("triangular", "square"), 3: ("fcc", "cubic")}


def lattice_sites(dim: int, size, kind: str | None = None):
    """Sites (N, d) with unit nearest-neighbour distance and the neighbour pairs (P, 2) of the lattice.

    size: number of cells per axis (int or d ints). Triangular: rows offset by 1/2, row spacing √3/2;
    fcc: the four-site cubic cell of edge √2 (12 neighbours); square/cubic: the unit grid.
    """
    kind = kind or KINDS[dim][0]
    if kind not in KINDS[dim]:
        raise ValueError(f"lattice kind for {dim}D must be one of {KINDS[dim]}, got {kind!r}")
    shape = tuple(np.broadcast_to(np.asarray(size, dtype=int), (dim,)))
    if min(shape) < 1:
        raise ValueError(f"lattice size must be >= 1, got {size!r}")
    grid = np.stack(np.meshgrid(*[np.arange(s) for s in shape], indexing="ij"), axis=-1).reshape(-1, dim)
    if kind == "square" or kind == "cubic":
        x = grid.astype(float)
    elif kind == "triangular":
        x = np.c_[grid[:, 0] + 0.5 * (grid[:, 1] % 2), grid[:, 1] * np.sqrt(3) / 2]
    else:  # fcc: cubic cells of edge √2 with four sites each
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
        x = ((grid[:, None, :] + basis[None]) * np.sqrt(2)).reshape(-1, 3)
    pairs = neighbour_pairs(x, 1.0)
    return x, pairs


def neighbour_pairs(x: np.ndarray, distance: float, rtol: float = 1e-6) -> np.ndarray:
    """All pairs (P, 2), i < j, at centre distance <= distance·(1 + rtol) (k-d tree, no Python loop)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(x).query_pairs(distance * (1 + rtol), output_type="ndarray")
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def _arrays(dim, x, p, q, frac, curvature_ratio, f_n, rng, mu, k, alpha, mobilised, n_sliding, moments, rolling):
    """Contact arrays of build_scene for contacts p-q: point at x_p + frac·(x_q - x_p), normal along the centre
    line, curvature -1/(ρ) with ρ = curvature_ratio · distance to the contact point, force -f_n n + f_t."""
    M = len(p)
    r = rot_dim(dim)
    d = x[q] - x[p]
    dist = np.linalg.norm(d, axis=1)
    n = d / dist[:, None]
    point = x[p] + frac[:, None] * d
    rho_p = curvature_ratio * frac * dist
    rho_q = curvature_ratio * (1 - frac) * dist
    T = tangent_basis(n)                                              # (M, d, d-1)
    P = T @ np.swapaxes(T, 1, 2)                                      # tangent projector
    Kp = -P / rho_p[:, None, None]
    Kq = -P / rho_q[:, None, None]
    mu_arr = np.full(M, float(mu))
    share = np.full(M, float(mobilised))
    if mobilised > 0:
        share = rng.uniform(0.0, mobilised, M)
    sliding = np.zeros(M, bool)
    if n_sliding:
        if n_sliding > M:
            raise ValueError(f"n_sliding = {n_sliding} exceeds the {M} contacts")
        sliding[rng.choice(M, n_sliding, replace=False)] = True
        share[sliding] = 1.0
    direction = T @ rng.standard_normal((M, dim - 1, 1))
    direction = direction[..., 0]
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    force = -f_n[:, None] * n + (share * mu_arr * f_n)[:, None] * direction
    if np.any(sliding):
        # exactly at yield: |f_t| = μ f_n to round-off, so Q = 0 within yield_rtol
        ft = force[sliding] + f_n[sliding, None] * n[sliding]
        force[sliding] = -f_n[sliding, None] * n[sliding] + ft * (mu * f_n[sliding] / np.linalg.norm(ft, axis=1))[:, None]
    moment = np.zeros((M, r))
    radius = 0.5 * dist
    if moments:
        moment = rng.uniform(-moments, moments, (M, r)) * (f_n * radius)[:, None]
    roll = np.zeros((M, r, r))
    if rolling:
        roll = (rolling * k * radius ** 2)[:, None, None] * np.eye(r)
    state = np.full(M, "auto", dtype=object)
    arrays = {"p": p.astype(np.intp), "q": q.astype(np.intp), "point": point, "normal": n, "curvature_p": Kp,
              "curvature_q": Kq, "force": force, "moment": moment, "k": np.full(M, float(k)),
              "alpha": np.full(M, float(alpha)), "mu": mu_arr, "rolling": roll, "state": tuple(state)}
    return arrays


def lattice(dim: int = 2, size=10, *, kind: str | None = None, radius: float = 1.0, f_over_k: float = 1e-3,
            curvature_ratio: float = 1.0, mu: float = 0.5, k: float = 1.0, alpha: float = 1.0,
            mobilised: float = 0.0, n_sliding: int = 0, moments: float = 0.0, rolling: float = 0.0,
            seed: int = 0, tol: Tolerances = DEFAULT) -> Scene:
    """Equal disks (2D) or spheres (3D) of radius `radius` on a lattice of size^dim cells, uniformly compressed
    (normal force f = f_over_k·k·r at every contact, overlap δ = f/k: centre distance 2r - δ)."""
    sites, pairs = lattice_sites(dim, size, kind)
    rng = np.random.default_rng(seed)
    delta = f_over_k * radius
    x = sites * (2 * radius - delta)
    p, q = pairs[:, 0], pairs[:, 1]
    f_n = np.full(len(p), f_over_k * k * radius)
    arrays = _arrays(dim, x, p, q, np.full(len(p), 0.5), curvature_ratio, f_n, rng, mu, k, alpha, mobilised,
                     n_sliding, moments, rolling)
    title = f"{kind or KINDS[dim][0]} lattice, {len(x)} particles, {len(p)} contacts, f/(kr) = {f_over_k:g}"
    return _scene(dim, x, arrays, title, tol)


def random_packing(dim: int = 2, n_particles: int = 1000, *, radius: float = 1.0, polydispersity: float = 0.2,
                   jitter: float = 0.1, f_over_k: float = 1e-3, curvature_ratio: float = 1.0, mu: float = 0.5,
                   k: float = 1.0, alpha: float = 1.0, mobilised: float = 0.5, n_sliding: int = 0,
                   moments: float = 0.0, rolling: float = 0.0, seed: int = 0,
                   tol: Tolerances = DEFAULT) -> Scene:
    """A random contact network of about `n_particles` particles (see the module docstring): jittered
    triangular/fcc sites, radii r·(1 ± polydispersity), force magnitudes f_over_k·k·r·U(0.5, 1.5), tangential
    forces uniform in [0, mobilised]·μ f_n in a random tangent direction."""
    cells = _cells_for(dim, n_particles)
    sites, pairs = lattice_sites(dim, cells)
    rng = np.random.default_rng(seed)
    x = (sites + jitter * rng.uniform(-0.5, 0.5, sites.shape)) * 2 * radius
    R = radius * (1 + polydispersity * rng.uniform(-1, 1, len(x)))
    p, q = pairs[:, 0], pairs[:, 1]
    frac = R[p] / (R[p] + R[q])
    f_n = f_over_k * k * radius * rng.uniform(0.5, 1.5, len(p))
    arrays = _arrays(dim, x, p, q, frac, curvature_ratio, f_n, rng, mu, k, alpha, mobilised, n_sliding, moments,
                     rolling)
    title = f"random {dim}D packing, {len(x)} particles, {len(p)} contacts, f/(kr) ~ {f_over_k:g}"
    return _scene(dim, x, arrays, title, tol)


def chain(dim: int = 2, n_particles: int = 3000, *, zigzag: float = 0.0, radius: float = 1.0,
          f_over_k: float = 1e-3, curvature_ratio: float = 1.0, mu: float = 0.5, k: float = 1.0,
          alpha: float = 1.0, seed: int = 0, tol: Tolerances = DEFAULT) -> Scene:
    """A chain of equal disks/spheres, each pressed on the next (normal force f_over_k·k·r, the end forces carried
    as loads): a floppy structure whose transverse and rolling modes give many clustered near-zero eigenvalues
    (ρ = r: disks roll on each other neutrally). `zigzag`: the angle (radians) each bond makes with the axis,
    alternately up and down (0: straight); its Hessian is banded."""
    rng = np.random.default_rng(seed)
    i = np.arange(n_particles - 1)
    bond = np.zeros((n_particles - 1, dim))
    bond[:, 0], bond[:, 1] = np.cos(zigzag), np.sin(zigzag) * np.where(i % 2, -1.0, 1.0)
    x = np.zeros((n_particles, dim))
    x[1:] = np.cumsum(bond * (2 * radius - f_over_k * radius), axis=0)
    f_n = np.full(len(i), f_over_k * k * radius)
    arrays = _arrays(dim, x, i, i + 1, np.full(len(i), 0.5), curvature_ratio, f_n, rng, mu, k, alpha, 0.0, 0,
                     0.0, 0.0)
    title = f"{'zig-zag' if zigzag else 'straight'} {dim}D chain, {n_particles} particles, f/(kr) = {f_over_k:g}"
    return _scene(dim, x, arrays, title, tol)


def _cells_for(dim: int, n_particles: int) -> int:
    per_cell = 1 if dim == 2 else 4
    return max(1, int(round((n_particles / per_cell) ** (1 / dim))))


def _scene(dim, x, arrays, title, tol) -> Scene:
    N = len(x)
    width = len(str(N - 1))
    names = np.char.add("p", np.char.zfill(np.arange(N).astype(str), width)).tolist()
    return build_scene(dim, names, x, arrays, title=title, source=title, tol=tol)


def harmonic_contacts(x: np.ndarray, radius: np.ndarray, cell: np.ndarray, k: float = 1.0):
    """Overlapping pairs of disks/spheres (x (N, d), radius (N,)) in the periodic `cell` under the minimum image:
    (p, q, image, branch b (P, d), distance s (P,), overlap δ (P,)); q's copy is x^q + image @ cell."""
    N, d = x.shape
    p, q = np.triu_indices(N, 1)
    b, shifts = minimum_image(x[q] - x[p], cell)
    image = -shifts
    s = np.linalg.norm(b, axis=1)
    delta = radius[p] + radius[q] - s
    on = delta > 0
    return p[on], q[on], image[on], b[on], s[on], delta[on]


def _harmonic_force_balance(x, radius, cell, k):
    """Energy U = Σ ½kδ², its gradient (N, d) and the translational Hessian (N d, N d) of the harmonic pairs."""
    N, d = x.shape
    p, q, _, b, s, delta = harmonic_contacts(x, radius, cell, k)
    n = b / s[:, None]
    f = (k * delta)[:, None] * n                                       # the force on q by p
    grad = np.zeros((N, d))
    np.add.at(grad, p, f)
    np.add.at(grad, q, -f)
    block = k * n[:, :, None] * n[:, None, :] - (k * delta / s)[:, None, None] * (np.eye(d) - n[:, :, None] * n[:, None, :])
    H = np.zeros((N, d, N, d))
    for a, c, sign in ((p, p, 1), (q, q, 1), (p, q, -1), (q, p, -1)):
        np.add.at(H, (a, slice(None), c), sign * block)
    return 0.5 * k * float(delta @ delta), grad, H.reshape(N * d, N * d)


def _relax(x, radius, cell, k, newton: int = 8):
    """Minimise the harmonic energy at fixed cell: L-BFGS, then Newton steps to force balance at round-off. One
    BLAS thread (threadpoolctl, where installed): L-BFGS's many tiny BLAS calls are 20x slower with a thread pool."""
    from contextlib import nullcontext

    from scipy.optimize import minimize
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:                                                 # pragma: no cover - optional
        threadpool_limits = None

    shape = x.shape

    def fun(v):
        U, g, _ = _harmonic_force_balance(v.reshape(shape), radius, cell, k)
        return U, g.ravel()

    with threadpool_limits(1) if threadpool_limits else nullcontext():
        x = minimize(fun, x.ravel(), jac=True, method="L-BFGS-B",
                     options={"maxiter": 20000, "gtol": 1e-10, "ftol": 0.0}).x.reshape(shape)
    for _ in range(newton):
        _, g, H = _harmonic_force_balance(x, radius, cell, k)
        x = x - np.linalg.lstsq(H, g.ravel(), rcond=1e-12)[0].reshape(shape)
    return x


def jammed(dim: int = 2, n: int = 32, phi: float | None = None, *, k: float = 1.0, ratio: float = 1.4,
           shear: float = 0.0, seed: int = 0, tol: Tolerances = DEFAULT) -> Scene:
    """A jammed frictionless periodic packing of harmonic disks (2D) or spheres (3D), see the module docstring.

    n bidisperse particles (half of radius 0.5, half 0.5·ratio) at packing fraction `phi` (default 0.90 in 2D,
    0.70 in 3D; jamming is near 0.84 and 0.64) in a cell [[L, 0], [shear·L, L]] (3D: the third row tilted along x),
    relaxed, rattlers (fewer than d + 1 contacts) removed and the rest relaxed again. The contacts have μ = 0 and
    α = 0 (F = k n⊗n), forces -kδ n, the contact point midway through the overlap, the curvatures of circles about
    each centre through it (-1/|r^pq|, -1/|r^qp|), and images across the cell."""
    phi = phi if phi is not None else (0.90 if dim == 2 else 0.70)
    rng = np.random.default_rng(seed)
    radius = np.where(np.arange(n) < n // 2, 0.5, 0.5 * ratio)
    ball = np.pi * radius ** 2 if dim == 2 else 4.0 / 3.0 * np.pi * radius ** 3
    side = (ball.sum() / phi) ** (1.0 / dim)
    cell = side * np.eye(dim)
    cell[-1, 0] = shear * side
    x = _relax(rng.uniform(0, 1, (n, dim)) @ cell, radius, cell, k)
    while True:
        p, q, *_ = harmonic_contacts(x, radius, cell, k)
        count = np.bincount(np.r_[p, q], minlength=len(x))
        keep = count >= dim + 1
        if keep.all():
            break
        if keep.sum() <= dim:
            raise ValueError(f"jammed: no rigid backbone at phi = {phi} with {n} particles (raise phi or n)")
        x, radius = _relax(x[keep], radius[keep], cell, k), radius[keep]
    x = x - np.floor(x @ np.linalg.inv(cell)) @ cell                  # inside the cell
    return _harmonic_scene(dim, x, radius, cell, k, tol)


def _harmonic_scene(dim, x, radius, cell, k, tol) -> Scene:
    p, q, image, b, s, delta = harmonic_contacts(x, radius, cell, k)
    M = len(p)
    n = b / s[:, None]
    point = x[p] + (radius[p] - 0.5 * delta)[:, None] * n
    T = tangent_basis(n)
    P = T @ np.swapaxes(T, 1, 2)
    rho_p, rho_q = radius[p] - 0.5 * delta, radius[q] - 0.5 * delta
    r = rot_dim(dim)
    arrays = {"p": p.astype(np.intp), "q": q.astype(np.intp), "point": point, "normal": n,
              "curvature_p": -P / rho_p[:, None, None], "curvature_q": -P / rho_q[:, None, None],
              "force": -(k * delta)[:, None] * n, "moment": np.zeros((M, r)), "k": np.full(M, float(k)),
              "alpha": np.zeros(M), "mu": np.zeros(M), "rolling": np.zeros((M, r, r)), "state": ("auto",) * M}
    volume = float(np.linalg.det(cell))
    pressure = -float(np.einsum("mi,mi->", arrays["force"], b)) / (dim * volume)
    title = f"jammed harmonic {dim}D packing, {len(x)} particles, {M} contacts, pressure {pressure:.3g} k"
    N = len(x)
    names = [f"p{i}" for i in range(N)]
    return build_scene(dim, names, x, arrays, title=title, source=title, tol=tol, cell=cell, image=image)


__all__ = ["chain", "harmonic_contacts", "jammed", "lattice", "lattice_sites", "neighbour_pairs", "random_packing"]
