"""Rigidity (issue 28): exact counts on hand-made frames, the two models on generic data, RigidLibrary's pebble game
on the annulus frame, the periodic frame's differences, and the command's JSON contract."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

from granstab.cli import main
from granstab.io import load
from granstab.model import packings
from granstab.model.packings import random_packing
from granstab.model.scene import build_scene
from granstab.rigidity import largest_cluster, largest_rigid_cluster, partition, rigidity
from granstab.rigidity.bodybar import BodyBar, from_scene
from granstab.rigidity.pebble import pebble_game
from granstab.rigidity.physical import physical

DATA = ROOT.parent / "shared" / "data" / "rigidlibrary"
REFERENCE = ROOT / "tests" / "data" / "rigidlibrary_annulus10_frame1_pebbles.json"
HELD_OUT = ROOT / "tests" / "data" / "rigidlibrary_annulus10_heldout_pebbles.json"
ZERO = 1e-10   # a null vector's residual: the SVD's ε·κ on these O(1) frames is ~1e-15; 1e-10 leaves a wide margin


def disks(x, pairs, sliding=(), radius=1.0, mu=0.5):
    """Equal disks touching along their centre lines, contacts sticking unless listed in `sliding`."""
    x, pairs = np.asarray(x, float), np.asarray(pairs)
    p, q = pairs[:, 0], pairs[:, 1]
    b = x[q] - x[p]
    n = b / np.linalg.norm(b, axis=1)[:, None]
    t = np.c_[-n[:, 1], n[:, 0]]
    K = -(1 / radius) * t[:, :, None] * t[:, None, :]
    slide = np.isin(np.arange(len(p)), list(sliding))
    force = -1e-3 * n + np.where(slide, mu * 1e-3, 0.0)[:, None] * t
    M = len(p)
    arrays = dict(p=p, q=q, point=x[p] + 0.5 * b, normal=n, curvature_p=K, curvature_q=K.copy(), force=force,
                  moment=np.zeros((M, 1)), k=np.ones(M), alpha=np.ones(M), mu=np.full(M, mu),
                  rolling=np.zeros((M, 1, 1)), state=tuple("sliding" if s else "elastic" for s in slide))
    return build_scene(2, [str(i) for i in range(len(x))], x, arrays)


def null_space(frame: BodyBar, length: float = 1.0) -> np.ndarray:
    """All null vectors of the physical model as one (n, f) matrix."""
    ph = physical(frame, length)
    N = np.zeros((frame.n_bodies * frame.per, ph.nullity))
    col = 0
    for where, V in ph.null:
        N[where, col:col + V.shape[1]] = V
        col += V.shape[1]
    return N


def in_span(N: np.ndarray, v: np.ndarray) -> float:
    """|v - N Nᵀ v| / |v|: 0 when v is an allowed velocity (N orthonormal)."""
    return float(np.linalg.norm(v - N @ (N.T @ v)) / np.linalg.norm(v))


def test_triangle_of_three_sticking_disks_is_one_rigid_cluster():
    s = disks([[0, 0], [2, 0], [1, np.sqrt(3)]], [[0, 1], [1, 2], [0, 2]])
    r = rigidity(s, "both")
    for model in ("physical", "generic"):
        assert [c[2] for c in r[model]["contacts"]] == [0, 0, 0]
        assert r[model]["clusters"][0]["particles"] == ["0", "1", "2"]
        # 9 dofs - 6 independent constraints = 3 rigid motions, none internal, no self-stress
        assert r[model]["floppy_modes"]["count"] == 0 and r[model]["trivial_modes"]["count"] == 3
        assert r[model]["self_stresses"] == 0
    assert r["differ"]["same_partition"]


def test_square_of_four_sliding_disks_has_its_shear_mode_and_free_spins():
    """4 bodies (12 dofs), 4 sliding contacts (normal rows only, independent): 8 floppy = 3 rigid motions + 4
    free spins (every normal passes through the centres) + 1 shear: the top pair slides sideways along x."""
    s = disks([[0, 0], [2, 0], [2, 2], [0, 2]], [[0, 1], [1, 2], [2, 3], [3, 0]], sliding=range(4))
    r = rigidity(s, "both")
    assert r["physical"]["floppy_modes"]["count"] == 5 == r["generic"]["floppy_modes"]["count"]
    assert all(c[2] == -1 for c in r["physical"]["contacts"])
    N = null_space(from_scene(s))
    shear = np.zeros((4, 3))
    shear[2:, 0] = 1.0                     # particles 2 and 3 (the top) move by +x
    assert in_span(N, shear.ravel()) < ZERO
    for i in range(4):
        spin = np.zeros((4, 3))
        spin[i, 2] = 1.0
        assert in_span(N, spin.ravel()) < ZERO
    stretch = np.zeros((4, 3))
    stretch[1:3, 0] = 1.0                  # pulling the right pair away stretches the normals of 0-1 and 3-2
    assert in_span(N, stretch.ravel()) > 0.1


def chain_with_wall() -> BodyBar:
    """Two unit disks A (x = -1) and B (x = +1) between the two faces of one wall body W (reference point 0):
    contacts W-A at x = -2, A-B at 0, B-W at +2, all sticking and all on the x axis."""
    x = np.array([[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0]])          # W, A, B
    p, q = np.array([0, 1, 2]), np.array([1, 2, 0])
    point = np.array([[-2.0, 0.0], [0.0, 0.0], [2.0, 0.0]])
    normal = np.tile([1.0, 0.0], (3, 1))
    return BodyBar(dim=2, names=("W", "A", "B"), x=x, p=p, q=q, r_pq=point - x[p], r_qp=point - x[q],
                 branch=x[q] - x[p], normal=normal, sliding=np.zeros(3, bool), rolling=np.zeros(3, bool),
                 periodic=False, n_particles=3, n_contacts=3)


def test_collinear_chain_where_the_models_differ():
    """Generic: 6 bars on 3 bodies = 3·3 - 3, rigid. Physical: every contact point on one line, so the chain
    buckles sideways at first order. Derivation (W fixed, R = 1): A moves up by v and turns by ω_A; its point at
    W (x = -2) moves v - ω_A R = 0, so ω_A = v/R; its point at B moves v + ω_A R = 2v. B moves up w, turns ω_B:
    at A, w - ω_B R = 2v; at W (x = 2), w + ω_B R = 0; so w = v, ω_B = -v/R. One internal floppy mode."""
    frame = chain_with_wall()
    game = pebble_game(3, np.repeat(frame.p, 2), np.repeat(frame.q, 2), 3)
    assert game.free == 3 and list(game.component) == [0, 0, 0]
    N = null_space(frame)
    assert N.shape[1] == 4                 # 3 rigid motions + the buckling mode
    mode = np.array([0, 0, 0, 0, 1, 1, 0, 1, -1], float)     # W; A: u = (0, v), θ = v/R; B: (0, v), -v/R
    assert in_span(N, mode) < ZERO
    ph = physical(frame, 1.0)
    assert not ph.rigid_contact.any() and (ph.component == -1).all()


def generic_frame(seed: int) -> tuple:
    """A random packing's contact graph thinned to z ≈ 3.3 with random contact points and normals: no bar through
    a centre, no two parallel, so the geometry is generic and the physical rank is the pebble game's. Returns the
    scene and the frame."""
    s = random_packing(2, 64, seed=seed, mobilised=1.0, n_sliding=60, jitter=0.3)
    frame = from_scene(s)
    rng = np.random.default_rng(seed)
    keep = np.sort(rng.choice(len(frame.p), size=105, replace=False))
    p, q, branch = frame.p[keep], frame.q[keep], frame.branch[keep]
    point = frame.x[p] + 0.5 * branch + rng.normal(scale=0.3, size=branch.shape)
    angle = rng.uniform(0, 2 * np.pi, len(p))
    return s, dataclasses.replace(frame, p=p, q=q, branch=branch, r_pq=point - frame.x[p], r_qp=point - frame.x[q],
                                  normal=np.c_[np.cos(angle), np.sin(angle)], sliding=frame.sliding[keep],
                                  rolling=frame.rolling[keep], n_contacts=len(p))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_two_models_agree_on_generic_data(seed):
    from granstab.rigidity import analyse_generic, analyse_physical
    s, frame = generic_frame(seed)
    ph, ge = analyse_physical(s, frame), analyse_generic(s, frame)
    assert ph["floppy_modes"] == ge["floppy_modes"] and ph["self_stresses"] == ge["self_stresses"]
    assert partition(ph) == partition(ge)
    assert ph["floppy_modes"]["count"] > 0 and ph["clusters"]     # a case with floppy parts and rigid clusters
    gap = ph["rank_tolerance"]["gap"]
    assert gap is None or gap > 1e6                          # dense SVD: the rank is clearly resolved


def annulus(frame=1, **options):
    return load(DATA / "DataAnnulus" / "10", frame=frame, mu=0.3, keep_rattlers=True, **options)


def reference(frame: int) -> dict:
    """RigidLibrary's own game on an annulus frame (tests/data/rigidlibrary_reference.py made both files): free
    pebbles, failed bars, contact count and the partition of contacts (as unordered name pairs) into clusters."""
    if frame == 1:
        full = json.loads(REFERENCE.read_text())
        clusters = {}
        for a, b, label, _ in full["contacts"]:
            if label >= 0:
                clusters.setdefault(label, []).append(f"{a} {b}")
        ref = {"free_pebbles": full["free_pebbles"], "failed_bars": full["failed_bars"],
               "contacts": len(full["contacts"]), "clusters": list(clusters.values())}
    else:
        ref = json.loads(HELD_OUT.read_text())["frames"][str(frame)]
    ref["partition"] = {frozenset(frozenset(c.split()) for c in cluster) for cluster in ref["clusters"]}
    return ref


def named_partition(result):
    contacts = result["contacts"]
    return {frozenset(frozenset(contacts[i][:2]) for i in c["contacts"]) for c in result["clusters"]}


@pytest.mark.slow
@pytest.mark.parametrize("frame", [1, 5, 12, 20])
def test_annulus_frames_match_rigidlibrarys_pebble_game(frame):
    """RigidLibrary's own game on the same frames (1, and 5, 12, 20 computed after the code was written), μ = 0.3
    as its run script, rattlers kept (it keeps every particle), walls as bodies: both models give the same
    partition of contacts into clusters, the same floppy count (free pebbles, trivial included) and, generic,
    the same failed bars; the physical rank is resolved (gap) and so is each contact's strain."""
    loaded = annulus(frame)
    r = rigidity(loaded.scene, "both", "bodies", loaded.wall_flags, second_order=False)
    ref = reference(frame)
    for model in ("generic", "physical"):
        assert named_partition(r[model]) == ref["partition"], model
        assert len(r[model]["contacts"]) == ref["contacts"]
        assert r[model]["floppy_modes"]["total_with_trivial"] == ref["free_pebbles"], model
    assert r["generic"]["self_stresses"] == ref["failed_bars"]
    # resolved: the smallest non-zero σ is >= 1e5 times the largest zero one (measured 3e5 to 3e10 on these
    # frames), and the strains counted rigid are >= 1e5 below those counted moving (measured 1e-12 vs 1e-3)
    assert r["physical"]["rank_tolerance"]["gap"] > 1e5
    strain = r["physical"]["rigid_contact_strain"]
    assert strain["smallest_counted_moving"] > 1e5 * strain["largest_counted_rigid"]
    if frame == 1:
        assert largest_rigid_cluster(r, "generic")["size_particles"] == 1141      # 1143 bodies less the two walls
        # the per-frame API of track: the same cluster, its share of the 1,781 disks
        one = largest_cluster(loaded.scene, "generic", "bodies", loaded.wall_flags)
        assert (one["size_particles"], one["size_contacts"]) == (1141, len(r["generic"]["clusters"][0]["contacts"]))
        assert one["fraction"] == pytest.approx(1141 / 1781, rel=1e-12)


def test_periodic_cell_has_only_translations_as_trivial_modes():
    """A jammed frictionless packing in a fixed periodic cell (normal constraints only): the physical model counts
    d = 2 trivial modes (translations; the cell forbids rotating the whole), the cell-ignoring game 3, and each
    count's Maxwell identity holds: dofs - constraints + self-stresses = nullity."""
    s = packings.jammed(2, 32, seed=0)
    assert s.periodic
    r = rigidity(s, "both")
    ph, ge = r["physical"], r["generic"]
    assert ph["trivial_modes"]["count"] == 2 and ge["trivial_modes"]["count"] == 3
    for model in (ph, ge):
        assert model["counts"]["maxwell"]["floppy"] == model["floppy_modes"]["total_with_trivial"]
    assert ph["floppy_modes"]["total_with_trivial"] >= ge["floppy_modes"]["total_with_trivial"]


def test_cli_json_contract_and_walls_error(tmp_path, capsys):
    s = disks([[0, 0], [2, 0], [1, np.sqrt(3)]], [[0, 1], [1, 2], [0, 2]])
    from granstab.io.scenes import save_scene
    path = tmp_path / "tri.npz"
    save_scene(s, path)
    assert main(["rigidity", str(path), "--json", "--kind", "both", "--figure", str(tmp_path / "f.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    for model in ("physical", "generic"):
        assert {"contacts", "clusters", "floppy_modes", "trivial_modes", "rattlers", "self_stresses",
                "counts"} <= set(out[model])
        assert out[model]["counts"]["z_iso"] == pytest.approx(3.0)    # all sticking: 2·3/2
    assert (tmp_path / "f.png").stat().st_size > 1000
    assert main(["rigidity", str(path), "--walls", "bodies"]) == 2
    err = capsys.readouterr().err
    assert "--walls bodies" in err and len(err.strip().splitlines()) == 1


def spin_residual(frame: BodyBar, body: int, length: float) -> float:
    """|C e| / σ̄ for e the unit spin (L dθ) of one body: how much its contacts resist it turning in place."""
    from granstab.mechanics.compatibility import compatibility_matrix
    from granstab.rigidity.physical import norm_bound
    C, _ = compatibility_matrix(frame.p, frame.q, frame.r_pq, frame.r_qp, frame.normal, frame.sliding,
                                frame.rolling, frame.n_bodies, length)
    e = np.zeros(C.shape[1])
    e[body * frame.per + 2] = 1.0
    return float(np.linalg.norm(C @ e) / norm_bound(C))


def test_datasim_with_its_cell_against_a_cell_ignoring_game():
    """DataSim step 5000 read with its Lees–Edwards cell (seam contacts through q's image). The fixed cell forbids
    turning the whole: the physical model has d = 2 trivial modes, the game 3, so the physical rank is one more
    and it has one self-stress fewer; both find every disk in one rigid cluster. Three disks have all 3 contacts
    sliding: on the true geometry they would spin freely (normals through the centre), but the file's normals are
    ~3e-7 rad off the centre lines, so the spin is resisted at |C e| ~ 1e-7 σ̄: counted non-zero (far above the
    ε-level tolerance) and reported nearly floppy. Made exactly radial, the three spins are floppy modes the game
    cannot see."""
    from granstab.model.scene import mean_contact_radius
    from granstab.rigidity import analyse_generic, analyse_physical
    s = load(DATA / "DataSim").scene
    assert s.periodic and np.any(s.image != 0)
    r = rigidity(s, "both", second_order=False)
    ph, ge = r["physical"], r["generic"]
    assert (ph["trivial_modes"]["count"], ge["trivial_modes"]["count"]) == (2, 3)
    assert ph["counts"]["maxwell"]["rank"] == ge["counts"]["maxwell"]["rank"] + 1
    assert ph["self_stresses"] == ge["self_stresses"] - 1
    assert ph["floppy_modes"]["count"] == ge["floppy_modes"]["count"] == 0
    assert r["differ"]["same_partition"] and ph["counts"]["largest_cluster_particles"] == s.n_particles
    frame, length = from_scene(s), mean_contact_radius(s)
    N = s.n_particles
    sliding = s.at_yield()
    every = np.bincount(np.r_[s.p, s.q], minlength=N)
    slide = np.bincount(np.r_[s.p[sliding], s.q[sliding]], minlength=N)
    spinners = np.flatnonzero((every >= 2) & (slide == every))
    assert len(spinners) == 3
    for body in spinners:
        # resisted only at the file's rounding: above the rank tolerance (~1e-11 of σ̄), below NEAR_RTOL
        assert ph["rank_tolerance"]["largest"] / ph["rank_tolerance"]["sigma_max_bound"] < spin_residual(frame, body, length) < 1e-6
    assert ph["nearly_floppy"]["count"] >= 3
    b = frame.branch / np.linalg.norm(frame.branch, axis=1)[:, None]
    radial = dataclasses.replace(frame, normal=b, r_pq=np.sum(frame.r_pq * b, 1)[:, None] * b,
                                 r_qp=np.sum(frame.r_qp * b, 1)[:, None] * b)
    exact, game = analyse_physical(s, radial, second_order=False), analyse_generic(s, radial)
    # 4 internal floppy modes, none generic: the 3 spins and one gear train (below)
    assert (exact["floppy_modes"]["count"], game["floppy_modes"]["count"]) == (4, 0)
    N_exact = null_space(radial, length)
    for body in spinners:
        spin = np.zeros(N_exact.shape[0])
        spin[body * 3 + 2] = 1.0
        assert in_span(N_exact, spin) < ZERO
    # the gear train: disks 361 - 607 - 895 (file ids) joined by sticking contacts, their other contacts sliding; turning in
    # place they roll without slip when ω_q R_q = -ω_p R_p at each sticking contact (R: centre to contact point)
    gear = np.zeros(N_exact.shape[0])
    chain = [s.names.index(n) for n in ("361", "607", "895")]
    omega = 1.0
    for a_, b_ in zip(chain, chain[1:]):
        c = np.flatnonzero(((s.p == a_) & (s.q == b_)) | ((s.p == b_) & (s.q == a_)))
        assert len(c) == 1 and not sliding[c[0]]
        Ra, Rb = (np.linalg.norm(frame.r_pq[c[0]]), np.linalg.norm(frame.r_qp[c[0]]))[:: 1 if s.p[c[0]] == a_ else -1]
        gear[a_ * 3 + 2], omega = omega, -omega * Ra / Rb
    gear[chain[-1] * 3 + 2] = omega
    assert in_span(N_exact, gear) < ZERO


def test_prestress_on_floppy_modes_matches_the_exact_geometry():
    """Second order: the all-unloading (all sticking) eigenvalues of Fᵀ sym(H̃) F on the floppy space F of a chain
    of 4 ellipses/disks pressed to f/k = 1e-2 (4 bodies, 3 sticking contacts: 12 - 6 - 3 = 3 internal floppy
    modes) equal those of the same F with H_exact, the complex-step derivative of the exact nonlinear statics
    (tests/exact_geometry.py, independent of granstab's stiffness). A floppy mode deforms no contact, so Hm adds
    nothing: the eigenvalues are geometric, O(f), and not all neutral. Tolerance: H and H_exact agree to
    1e-12 ‖H‖ (test_fd_exact), the eigenvalues to 1e-9 of the largest."""
    from exact_geometry import cluster_from_scene, press, stiffness_exact
    from test_fd_exact import CLUSTERS, LAW

    from granstab.mechanics.rigid import dof_scale
    from granstab.model import shapes
    from granstab.model.scene import mean_contact_radius
    from granstab.rigidity.prestress import floppy_space
    parts, pairs, _ = CLUSTERS["chain2d"]
    parts = press(parts, pairs, 1e-2)
    scene = shapes.scene_from_shapes(2, parts, **LAW)
    r = rigidity(scene, "physical")["physical"]
    assert r["floppy_modes"]["count"] == 3 and not scene.at_yield().any()
    length = mean_contact_radius(scene)
    F = floppy_space(scene, physical(from_scene(scene), length).null, length)
    D = dof_scale(scene.n_particles, 2, length)
    Ht = D[:, None] * stiffness_exact(cluster_from_scene(scene, parts)) * D[None, :]
    exact = np.linalg.eigvalsh(F.T @ (0.5 * (Ht + Ht.T)) @ F)
    ours = r["prestress"]["all_unloading"]
    assert np.allclose(ours["lowest"], exact, rtol=0, atol=1e-9 * np.abs(exact).max())
    assert np.abs(exact).max() < 1.0                                          # O(f), f = 1e-2: geometric only
    # the verdict by sign (measured: one floppy direction stabilised, two destabilised)
    assert (ours["stabilised"], ours["destabilised"]) == (int(np.sum(exact > ours["tolerance"])),
                                                          int(np.sum(exact < -ours["tolerance"]))) == (1, 2)
