"""Periodic media (issue 24, docs/periodic.md): the extended stiffness [[H, Ξ], [Ξ', B]] against the derivative of
exact periodic rigid-body statics, the moduli against an independent energy Hessian of harmonic spheres, tiling,
zero modes, the stress's sign, frictional branches and the fixed-stress verdict.

Tolerances (why): the complex-step reference is exact to round-off, so the extended matrix must agree to a few
hundred eps of its norm (1e-12, as tests/mechanics/test_fd_exact.py). The moduli are a Schur complement of matrices with
entries ~k, formed in double precision from forces at round-off equilibrium (load residual ~1e-14 of |f|): they
must agree within 1e-10 of max|C| (the issue's "round-off").
"""
from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from exact_geometry import cluster_from_scene, loads, press
from scipy.spatial.transform import Rotation

import granstab
from granstab.mechanics.branches import RIGID
from granstab.mechanics.cell import cell_parts, mandel_basis, stress, stress_work, to_mandel, to_tensor
from granstab.mechanics.stiffness import assemble_parts, contact_blocks
from granstab.model import packings
from granstab.model import shapes as S
from granstab.model.periodic import tile
from granstab.model.scene import build_scene
from granstab.moduli import moduli

CSTEP = 1e-30
EXACT_RTOL = 1e-12
MODULI_RTOL = 1e-10


# ------------------------------------------------------------------ exact periodic geometry (complex step)

def _unfolded(dim):
    """Three bodies a, b, c and a copy a' of a pressed to overlap 1e-2 along a chain a-b-c-a'; the lattice vector
    a_1 = x_a' - x_a, the others long enough to touch nothing. Returns (parts, pairs, cell)."""
    if dim == 2:
        parts = [("a", S.Ellipse(1.0, 0.6), ((0, 0), 0.2)), ("b", S.Ellipse(0.8, 0.5), ((1.6, 0.3), 1.0)),
                 ("c", S.Ellipse(0.9, 0.45), ((3.0, -0.2), -0.4)), ("a'", S.Ellipse(1.0, 0.6), ((4.5, 0.2), 0.2))]
    else:
        def R(_, v):
            return Rotation.from_rotvec(v).as_matrix()
        parts = [("a", S.Ellipsoid(1.0, 0.7, 0.6), ((0, 0, 0), R(3, [0.3, -0.2, 0.5]))),
                 ("b", S.Ellipsoid(0.9, 0.6, 0.5), ((1.6, 0.3, 0.2), R(3, [-0.4, 0.1, 0.9]))),
                 ("c", S.Sphere(0.6), ((2.9, -0.1, 0.3), None)),
                 ("a'", S.Ellipsoid(1.0, 0.7, 0.6), ((4.3, 0.2, 0.1), R(3, [0.3, -0.2, 0.5])))]
    pairs = [(0, 1), (1, 2), (2, 3)]
    parts = press(parts, pairs, 1e-2)
    x = np.array([pose[0] for _, _, pose in parts], float)
    cell = 6.0 * np.eye(dim)
    cell[0] = x[3] - x[0]
    cell[1:, 0] = 0.3
    return parts, pairs, cell


@cache
def periodic_case(dim):
    """(granstab scene with the seam contact c-a through image (1, 0, ...), exact cluster, owner of each body)."""
    parts, pairs, cell = _unfolded(dim)
    flat = S.scene_from_shapes(dim, parts, k=1.0, alpha=0.7, mu=0.5, mobilised=0.6)
    assert [(int(p), int(q)) for p, q in zip(flat.p, flat.q)] == pairs
    owner = np.array([0, 1, 2, 0])
    image = np.zeros((3, dim), dtype=int)
    image[2, 0] = 1
    arrays = {key: getattr(flat, key) for key in ("point", "normal", "curvature_p", "curvature_q", "force",
                                                  "moment", "k", "alpha", "mu", "rolling")}
    arrays.update(p=flat.p, q=owner[flat.q], state=flat.state)
    scene = build_scene(dim, ["a", "b", "c"], flat.x[:3], arrays, cell=cell, image=image, source="cell")
    return scene, cluster_from_scene(flat, parts), owner


def exact_extended(dim, pinned: bool = False) -> np.ndarray:
    """∂[b, w (folded onto the particles); Σ_bodies b ⊗ X : E_a] / ∂[u, θ, ε_a] of the exact statics, with
    x = (I + ε) X + u for every body and its copies (Lagrangian virial: the cell's work-conjugate load). `pinned`:
    the seam copy moves with the strain like a itself, not like its image — what dropping the image's strain
    would give (a negative control)."""
    scene, cl, owner = periodic_case(dim)
    N, d, r = scene.n_particles, dim, scene.dof_per_particle - dim
    E = mandel_basis(d)
    n_var = N * (d + r) + len(E)
    X = cl.x0
    out = np.zeros((n_var, n_var))
    for j in range(n_var):
        y = np.zeros(n_var, complex)
        y[j] = 1j * CSTEP
        U = y[:N * (d + r)].reshape(N, d + r)
        eps = np.einsum("a,aij->ij", y[N * (d + r):], E)
        moved = X @ eps.T
        if pinned:
            moved[3] = X[0] @ eps.T
        L = loads(cl, moved + U[owner, :d], U[owner, d:])
        folded = np.zeros((N, d + r), complex)
        np.add.at(folded, owner, L)
        cell = np.einsum("bi,bj,aij->a", L[:, :d], X, E)
        out[:, j] = np.concatenate([folded.ravel(), cell]).imag / CSTEP
    return out


@pytest.mark.parametrize("dim", [2, 3])
def test_extended_stiffness_matches_exact_periodic_statics(dim):
    """H, Ξ, Ξ' and B (mechanics/cell.py) against the complex-step derivative of exact periodic statics: ellipses
    (ellipsoids) in a sheared cell, one contact across the seam, tangential forces, the cell deformed affinely."""
    scene, _, _ = periodic_case(dim)
    blocks = contact_blocks(scene)
    parts = cell_parts(scene, blocks, np.zeros(0, dtype=int))
    H = granstab.stiffness(scene).H
    K = np.block([[H, parts.Xi], [parts.Xi_left, parts.B]])
    K_exact = exact_extended(dim)
    err = np.abs(K - K_exact).max() / np.abs(K_exact).max()
    assert err < EXACT_RTOL, err
    n = H.shape[0]
    assert np.abs(K_exact[:n, n:]).max() > 0.1 and np.abs(K_exact[n:, n:]).max() > 0.1   # the cell blocks are tested
    assert np.abs(K - exact_extended(dim, pinned=True)).max() > 1e-3 * np.abs(K_exact).max()   # the image matters


# ------------------------------------------------------------------ independent harmonic energy Hessian

def harmonic_extended_hessian(scene) -> tuple:
    """The Hessian of U = Σ ½k(r - s)² over [u (N d), ε (Mandel)] with x = (I + ε)X + u, s = |b|, b = (I + ε) b⁰
    + u_q - u_p, written from the energy alone (complex step of its analytic gradient; r = s⁰ + δ⁰ from the
    scene's overlap k δ⁰ = |f|): (H (Nd, Nd), Ξ (Nd, m), B (m, m))."""
    N, d = scene.n_particles, scene.dim
    E = mandel_basis(d)
    b0 = scene.branch
    r = np.linalg.norm(b0, axis=1) + np.linalg.norm(scene.force, axis=1) / scene.k
    n_var = N * d + len(E)

    def gradient(y):
        u = y[:N * d].reshape(N, d)
        eps = np.einsum("a,aij->ij", y[N * d:], E)
        b = b0 + b0 @ eps.T + u[scene.q] - u[scene.p]
        s = np.sqrt(np.sum(b * b, axis=1))
        dUdb = (scene.k * (s - r) / s)[:, None] * b
        gu = np.zeros((N, d), complex)
        np.add.at(gu, scene.q, dUdb)
        np.add.at(gu, scene.p, -dUdb)
        ge = np.einsum("mi,mj,aij->a", dUdb, b0, E)
        return np.concatenate([gu.ravel(), ge])

    Hfull = np.zeros((n_var, n_var))
    for j in range(n_var):
        y = np.zeros(n_var, complex)
        y[j] = 1j * CSTEP
        Hfull[:, j] = gradient(y).imag / CSTEP
    n = N * d
    return Hfull[:n, :n], Hfull[:n, n:], Hfull[n:, n:]


def harmonic_moduli(scene) -> np.ndarray:
    """C (Mandel) = (B - Ξᵀ H⁺ Ξ)/V from the independent Hessian (H⁺: pseudo-inverse, translations its null space)."""
    H, Xi, B = harmonic_extended_hessian(scene)
    return (B - Xi.T @ np.linalg.pinv(H, rcond=1e-10, hermitian=True) @ Xi) / scene.volume


@cache
def jammed(dim, phi, shear=0.0):
    return packings.jammed(dim, 24 if dim == 2 else 20, phi, shear=shear, seed=1)


PACKINGS = [(2, 0.88, 0.0), (2, 0.95, 0.1), (3, 0.68, 0.0), (3, 0.75, 0.1)]


@pytest.mark.parametrize("dim, phi, shear", PACKINGS)
def test_frictionless_moduli_equal_the_energy_hessians(dim, phi, shear):
    """Jammed harmonic disks/spheres at two pressures (one in a sheared cell): granstab's moduli equal those of the
    independent energy Hessian to round-off, are major-symmetric, and the stress is the energy's first derivative."""
    scene = jammed(dim, phi, shear)
    result = moduli(scene)
    reference = harmonic_moduli(scene)
    scale = np.abs(reference).max()
    assert np.abs(result.mandel - reference).max() < MODULI_RTOL * scale
    assert result.errors["symmetry_defect"] < 1e-12 and result.errors["residual"] < 1e-12
    assert np.abs(result.C - np.transpose(result.C, (2, 3, 0, 1))).max() < 1e-12 * scale    # major symmetry
    assert np.abs(result.C - np.transpose(result.C, (1, 0, 2, 3))).max() == 0                  # minor symmetry
    assert len(result.branches) == 1 and result.branches[0].name == "elastic"


@pytest.mark.parametrize("dim", [2, 3])
def test_stress_is_tension_positive_and_the_energy_derivative(dim):
    """σ = (1/V) Σ f ⊗ b: a compressed packing has negative trace (pressure > 0), and σ equals ∂(U/V)/∂ε at ε = 0
    of the harmonic energy (central differences, h = 1e-6: error ~h² ~ 1e-12 of σ)."""
    scene = jammed(dim, 0.9 if dim == 2 else 0.7)
    sigma = stress(scene)
    assert np.trace(sigma) < 0 and moduli(scene).pressure > 0
    E = mandel_basis(dim)
    r = np.linalg.norm(scene.branch, axis=1) + np.linalg.norm(scene.force, axis=1) / scene.k

    def energy(eps):
        s = np.linalg.norm(scene.branch @ (np.eye(dim) + eps).T, axis=1)
        return 0.5 * np.sum(scene.k * np.maximum(r - s, 0) ** 2)

    h = 1e-6
    dU = np.array([(energy(h * Ea) - energy(-h * Ea)) / (2 * h) for Ea in E]) / scene.volume
    assert np.abs(dU - np.einsum("ij,aij->a", sigma, E)).max() < 1e-8 * np.abs(sigma).max()


@pytest.mark.parametrize("dim, phi, shear", [(2, 0.9, 0.05), (3, 0.7, 0.0)])
def test_tiling_gives_the_same_moduli_and_contains_the_spectrum(dim, phi, shear):
    """Moduli are intensive: the packing tiled 2×2 (2×2×2) has the same C and σ to round-off, and the spectrum of
    its sym(H) contains the original's (every mode of the cell is a periodic mode of the supercell)."""
    scene = jammed(dim, phi, shear) if dim == 2 else packings.jammed(3, 16, phi, seed=1)   # 3D: 128 tiled
    big = tile(scene, 2)
    assert big.n_particles == 2 ** dim * scene.n_particles and big.n_contacts == 2 ** dim * scene.n_contacts
    small, large = moduli(scene), moduli(big)
    scale = np.abs(small.mandel).max()
    assert np.abs(small.mandel - large.mandel).max() < MODULI_RTOL * scale
    assert np.abs(small.stress - large.stress).max() < 1e-12 * np.abs(small.stress).max()
    lam, lam_big = (np.linalg.eigvalsh(_sym(assemble_parts(s, contact_blocks(s))["H"].toarray())) for s in (scene, big))
    gap = np.abs(lam[:, None] - lam_big[None]).min(axis=1)
    assert gap.max() < 1e-10 * np.abs(lam).max()
    assert not np.allclose(lam_big[:len(lam)], lam)                    # the supercell has modes of its own


def _sym(H):
    return 0.5 * (H + H.T)


@pytest.mark.parametrize("dim", [2, 3])
def test_zero_modes_are_translations_and_free_spins(dim):
    """A jammed frictionless packing without rattlers: sym(H) has exactly d + N·r zero eigenvalues (r = 1 in 2D,
    3 in 3D): the d translations and the free spins, which `moduli` reports as such; `analyze` calls the packing
    stable (the spins are not a neutral mode) with the translations as its only rigid zeros."""
    scene = jammed(dim, 0.9 if dim == 2 else 0.72)
    r = 1 if dim == 2 else 3
    lam = np.linalg.eigvalsh(_sym(granstab.stiffness(scene).H))
    tol = 1e-10 * np.abs(lam).max()
    assert int(np.sum(np.abs(lam) < tol)) == dim + r * scene.n_particles
    assert lam[np.abs(lam) >= tol].min() > 1e3 * tol                 # a gap: the rest is clearly positive
    zero = moduli(scene).zero_modes
    assert zero["translations"] == dim and zero["free_spins"] == r * scene.n_particles and zero["rattlers"] == 0
    result = granstab.analyze(scene, metric="L")
    assert result.summary["verdict"] == "stable", result.summary["reason"]
    assert result.summary["free_spins"] == r * scene.n_particles
    sparse = granstab.analyze(scene, metric="L", method="sparse", k=6)     # the same spins set aside there
    assert sparse.summary["verdict"] == "stable" and sparse.summary["free_spins"] == r * scene.n_particles
    dense_low = np.sort(result.branches[0].stability_eigenvalues[result.branches[0].codes != RIGID])[:4]
    sparse_low = np.sort(sparse.branches[0].stability_eigenvalues)[dim:dim + 4]      # after the d translations
    assert np.abs(dense_low - sparse_low).max() < 1e-10 * dense_low.max()


def test_rattler_is_reported_not_failed():
    """A particle with no contact in a periodic packing is a rattler: set aside and reported, C unchanged."""
    scene = jammed(2, 0.9)
    names = scene.names + ("loose",)
    lonely = build_scene(2, names, np.vstack([scene.x, scene.x[:1] + 1e-3]),
                         {k: getattr(scene, k) for k in ("p", "q", "point", "normal", "curvature_p", "curvature_q",
                                                         "force", "moment", "k", "alpha", "mu", "rolling", "state")},
                         cell=scene.cell, image=scene.image, source="rattler")
    a, b = moduli(scene), moduli(lonely)
    assert b.zero_modes["rattlers"] == 1 and b.zero_modes["free_spins"] == scene.n_particles
    assert np.abs(a.mandel - b.mandel).max() < 1e-13 * np.abs(a.mandel).max()


# ------------------------------------------------------------------ frictional branches and stress control

def frictional(n_sliding: int, seed: int = 2):
    """A jammed 2D packing given friction: μ = 0.5, α = 0.7, tangential forces from a small random shear-like
    redistribution would break equilibrium, so the forces stay normal and `n_sliding` contacts are declared at
    yield by giving them μ = 0 ... instead: the yield test needs |f_t| = μ|f_n|. Built from the square lattice of
    test_periodic_scene with tangential forces that balance by symmetry."""
    from test_periodic_scene import make, square_cell
    fields = square_cell(n=2, f=1e-2, mu=0.5, alpha=0.7)
    arrays = dict(fields["arrays"])
    t = np.c_[-arrays["normal"][:, 1], arrays["normal"][:, 0]]
    arrays["force"] = arrays["force"] + 0.5 * 1e-2 * t * np.where(np.arange(len(t)) < n_sliding, 1.0, 0.4)[:, None]
    return make({**fields, "arrays": arrays})


def test_frictional_branches_and_consistent_direction():
    """Sliding contacts: the all-loading branch is softer than the elastic one in some direction, the moduli of
    each branch are its Schur complement (checked by a direct dense solve), and a strain direction picks the
    branches whose sliding contacts load (S >= 0) exactly where the mask slides (Appendix D)."""
    scene = frictional(2)
    assert scene.at_yield().sum() >= 1
    result = moduli(scene, strain=[[0.0, 1.0], [1.0, 0.0]])
    elastic, loading = result.branches
    assert elastic.name == "elastic" and loading.name == "all loading"
    assert loading.eigenvalues.min() < elastic.eigenvalues.min()
    for b in result.branches:                                           # direct Schur complement on this branch
        H = granstab.stiffness(scene, mask=b.mask).H
        parts = cell_parts(scene, contact_blocks(scene), np.flatnonzero(scene.at_yield()))
        on = b.mask[scene.at_yield()] == 1
        Xi = parts.Xi + _A(scene)[:, on] @ parts.S_cell[:, on].T
        left = parts.Xi_left + parts.A_cell[:, on] @ _S(scene)[:, on].T
        Bm = parts.B + parts.A_cell[:, on] @ parts.S_cell[:, on].T
        C = (Bm - left @ np.linalg.pinv(H, rcond=1e-12) @ Xi) / scene.volume
        assert np.abs(C - b.mandel).max() < 1e-9 * np.abs(C).max()
    direction = result.direction
    assert direction["enumerated"] and direction["n_branches"] == 2 ** int(scene.at_yield().sum())
    for found in direction["consistent"]:
        assert found["modulus"] == pytest.approx(
            np.einsum("ij,ijkl,kl->", np.array(direction["strain"]), np.array(found["C"]),
                      np.array(direction["strain"])), rel=1e-12)
    assert direction["consistent"] and ("Type-1" in direction.get("note", "")) == (len(direction["consistent"]) > 1)


def _A(scene):
    from granstab.mechanics.assembly import sliding_factors
    return sliding_factors(contact_blocks(scene), np.flatnonzero(scene.at_yield()))[0]


def _S(scene):
    from granstab.mechanics.assembly import sliding_factors
    return sliding_factors(contact_blocks(scene), np.flatnonzero(scene.at_yield()))[1]


def test_stress_work_term_and_fixed_stress_verdict():
    """Q of a hydrostatic stress -p I is -p(δ⊗δ - I) (the enthalpy U + pV); the fixed-stress stiffness C - Q is
    what the verdict reads; a pressure above the shear stiffness makes C - Q indefinite (-p tr ε² on a shear),
    so the same cell is stable held and unstable at fixed stress (the Dagois-Bohy effect in its simplest form)."""
    p = 0.3
    Q = stress_work(-p * np.eye(3))
    eye = np.eye(3)
    expect = -p * (np.einsum("ij,kl->ijkl", eye, eye)
                   - 0.5 * (np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye)))
    assert np.abs(to_tensor(Q) - expect).max() < 1e-15 and np.abs(to_mandel(expect) - Q).max() < 1e-15
    scene = jammed(2, 0.88)
    result = moduli(scene)
    assert result.verdicts["fixed_stress"]["verdict"] == "stable"
    b = result.branches[0]
    assert np.allclose(b.fixed_stress, b.mandel - stress_work(result.stress), rtol=0, atol=1e-15)
    assert np.linalg.eigvalsh(b.mandel - stress_work(-2 * np.abs(b.mandel).max() * np.eye(2))).min() < 0


def test_moduli_refuse_a_scene_without_cell():
    with pytest.raises(granstab.SceneError, match="moduli need a periodic scene"):
        moduli(granstab.load_scene("presets/two_particle.toml"))


def one_disk_cell(a: float = 0.99, k: float = 1.0):
    """One frictionless disk of diameter 1 in a square cell of side a < 1: it touches its own images along x and
    y (overlap δ = 1 - a, force f = kδ). Closed forms (V = a²): C_xxxx = C_yyyy = k, C_xxyy = 0, Mandel shear
    C_(xy)(xy) = -f/a (the compressed contacts' transverse -f/a, no normal stretch); σ = -(f/a) I."""
    f = k * (1.0 - a)
    normal = np.eye(2)
    t = np.c_[-normal[:, 1], normal[:, 0]]
    K = -(2 / a) * t[:, :, None] * t[:, None, :]
    arrays = {"p": np.array([0, 0]), "q": np.array([0, 0]), "point": 0.5 * a * normal, "normal": normal,
              "curvature_p": K, "curvature_q": K.copy(), "force": -f * normal, "moment": np.zeros((2, 1)),
              "k": np.full(2, k), "alpha": np.zeros(2), "mu": np.zeros(2), "rolling": np.zeros((2, 1, 1)),
              "state": ("auto", "auto")}
    return build_scene(2, ["d"], np.zeros((1, 2)), arrays, cell=a * np.eye(2), image=np.eye(2, dtype=int),
                       source="one disk"), f


def test_one_disk_cell_closed_form_stable_held_unstable_at_fixed_stress():
    """The square lattice as a one-disk cell: C and σ equal the closed forms to round-off; held (fixed cell) it is
    stable — nothing can move but the translations and the spin — while at fixed stress C - Q has the shear
    eigenvalue -f/a - p = -2f/a < 0 along a consistent (frictionless: always) strain: unstable, proven."""
    a = 0.99
    scene, f = one_disk_cell(a)
    result = moduli(scene)
    expect = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -f / a]])
    assert np.abs(result.mandel - expect).max() < 1e-14
    assert np.abs(result.stress + (f / a) * np.eye(2)).max() < 1e-16
    assert result.zero_modes == {**result.zero_modes, "free_spins": 1, "rattlers": 0, "mechanisms": 0}
    fixed_stress = result.verdicts["fixed_stress"]
    assert fixed_stress["verdict"] == "unstable" and fixed_stress["sufficient"]
    assert fixed_stress["min_eigenvalue"] == pytest.approx(-2 * f / a, rel=1e-12)
    assert result.verdicts["fixed_cell"]["verdict"] == "stable"


def test_cli_moduli_table_json_and_errors(tmp_path, capsys):
    from granstab.cli import main
    scene, f = one_disk_cell()
    path = tmp_path / "cell.json"
    granstab.save_scene(scene, path)
    assert main(["moduli", str(path)]) == 0
    out = capsys.readouterr().out
    assert "stress σ (tension positive)" in out and "fixed stress: UNSTABLE (proven" in out
    assert main(["moduli", str(path), "--json", "--strain", "0,1,1,0"]) == 0
    data = __import__("json").loads(capsys.readouterr().out)
    assert np.allclose(np.array(data["C"]), moduli(scene).C, rtol=0, atol=1e-15)
    assert data["direction"]["consistent"][0]["modulus"] == pytest.approx(-f / 0.99, rel=1e-12)
    assert main(["moduli", "presets/two_particle.toml"]) == 2
    assert "moduli need a periodic scene" in capsys.readouterr().err
    assert main(["moduli", str(path), "--strain", "1,2,3"]) == 2
    assert capsys.readouterr().err.strip() == "--strain: 4 numbers expected (a 2x2 tensor row by row), got 3"


def test_many_sliding_contacts_are_sampled_and_said_so():
    """Beyond max_sliding the branches are a stated sample: the range of the directional moduli over them, a note
    that it is not a bound, and no proof of stability at fixed stress."""
    scene = frictional(2)
    result = moduli(scene, strain=[[1.0, 0.0], [0.0, -1.0]], max_sliding=1, sample_branches=8)
    direction = result.direction
    assert not direction["enumerated"] and not direction["unique"]
    assert "a sample, not a bound" in direction["note"] and direction["range"][0] <= direction["range"][1]
    assert {b.name for b in result.branches} == {"elastic", "all loading"}
    assert not result.verdicts["fixed_stress"]["sufficient"] or result.verdicts["fixed_stress"]["verdict"] == "unstable"


def test_cli_moduli_heartbeat_keeps_the_json_clean(tmp_path, monkeypatch, capsys):
    """`granstab moduli` off a terminal: no silent minute. With the heartbeat interval set small and each branch
    slowed, stderr carries heartbeat lines naming the stage (branches i of n) and stdout the JSON alone."""
    import sys
    import time

    from granstab.cli import main
    from granstab.io import progress
    monkeypatch.setattr(progress, "HEARTBEAT_FIRST", 0.1)
    monkeypatch.setattr(progress, "HEARTBEAT_EVERY", 0.1)
    gm = sys.modules["granstab.moduli"]                              # the module (granstab.moduli is the function)
    branch = gm._branch

    def slowed(*args, **kwargs):                                      # a few heartbeats long on any machine
        time.sleep(0.2)
        return branch(*args, **kwargs)

    monkeypatch.setattr(gm, "_branch", slowed)
    scene = frictional(2)
    path = tmp_path / "cell.json"
    granstab.save_scene(scene, path)
    assert main(["moduli", str(path), "--json"]) == 0
    out, err = capsys.readouterr()
    data = __import__("json").loads(out)
    assert np.allclose(np.array(data["C"]), moduli(scene).C, rtol=0, atol=0)
    beats = err.splitlines()
    assert len(beats) >= 2 and all(line.startswith(f"granstab: moduli {path}: ") for line in beats)
    assert any("branches (" in line and "of 4)" in line for line in beats)


def test_cli_moduli_json_of_a_3d_jammed_packing_is_the_contract(tmp_path, capsys):
    """`granstab moduli --json` of a 3D frictionless harmonic periodic scene written to a file (the held-out set's
    form): C as nested 3×3×3×3 lists equal to the independent energy Hessian's moduli (MODULI_RTOL of max|C|), the
    stress 3×3 and the volume |det(cell)| (1e-12 relative: a product of three numbers)."""
    from granstab.cli import main
    scene = jammed(3, 0.68)
    path = tmp_path / "jammed3d.json"
    granstab.save_scene(scene, path)
    assert main(["moduli", str(path), "--json"]) == 0
    data = __import__("json").loads(capsys.readouterr().out)
    C = np.array(data["C"])
    assert C.shape == (3, 3, 3, 3) and np.array(data["stress"]).shape == (3, 3)
    reference = to_tensor(harmonic_moduli(scene))
    assert np.abs(C - reference).max() < MODULI_RTOL * np.abs(reference).max()
    assert data["volume"] == pytest.approx(abs(np.linalg.det(scene.cell)), rel=1e-12)
    assert np.allclose(np.array(data["stress"]), stress(scene), rtol=0, atol=1e-15 * np.abs(stress(scene)).max())
