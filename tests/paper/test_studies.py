"""The studies of granstab.paper against the paper's numbers (Sec. 4), closed forms and the presets.

Tolerances are stated with their scale: round-off checks are relative to the matrix norm or to k (|λ| ≤ c·eps·‖·‖
with c ≤ 100), counts are exact, and the path integration is compared with its quadrature error (Simpson, 61 points).
"""

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

import granstab
from granstab.paper import four_disk, gear, sliding_contact, two_particle

PRESETS = ROOT / "presets"
EPS = np.finfo(float).eps


# ------------------------------------------------------------------------------------------ two-particle

def test_closed_forms_rederived_with_sympy():
    """The characteristic polynomial of ℍ = H P (eq:exampleH2, eq:exampleC) factors into λ³(λ-2k)(λ-λ5)(λ-λ6)."""
    sp = pytest.importorskip("sympy")
    k, a, r, rho, f, lam = sp.symbols("k alpha r rho f lambda", real=True)
    row3 = [0, a * r, a * r ** 2, 0, -a * r, a * r ** 2]
    Hm = k * sp.Matrix([[1, 0, 0, -1, 0, 0], [0, a, a * r, 0, -a, a * r], row3,
                        [-1, 0, 0, 1, 0, 0], [0, -a, -a * r, 0, a, -a * r], row3])
    d = rho - r
    Hg = f / (2 * rho) * sp.Matrix([[0] * 6, [0, -1, d, 0, 1, d], [0, d, d * (rho + r), 0, -d, -d * d],
                                    [0] * 6, [0, 1, -d, 0, -1, -d], [0, d, -d * d, 0, -d, d * (rho + r)]])
    C = sp.Matrix([0, -r, 1, 0, r, 1])
    P = sp.eye(6) - C * C.T / (C.T * C)[0]
    HH = (Hm + Hg) * P
    s = 1 + r ** 2
    lam5 = 2 * a * k * s - f * (s ** 2 - r * rho * (2 + r ** 2)) / (rho * s)
    lam6 = f * (rho - r)
    # ν4 and ν6 are exact eigenvectors (symbolically) ...
    nu4, nu6 = sp.Matrix([1, 0, 0, -1, 0, 0]), sp.Matrix([0, 0, 1, 0, 0, -1])
    assert sp.simplify(HH * nu4 - 2 * k * nu4) == sp.zeros(6, 1)
    assert sp.simplify(HH * nu6 - lam6 * nu6) == sp.zeros(6, 1)
    # ... and the characteristic polynomial is λ³(λ-2k)(λ-λ5)(λ-λ6), checked exactly at random rational points
    # (a rational identity in k, α, r, ρ, f that holds at random points holds everywhere, Schwartz-Zippel)
    expected = lam ** 3 * (lam - 2 * k) * (lam - lam5) * (lam - lam6)
    rng = np.random.default_rng(1)
    for _ in range(4):
        sub = {sym: sp.Rational(int(rng.integers(1, 40)), int(rng.integers(1, 40))) for sym in (k, a, r, rho)}
        sub[f] = sp.Rational(int(rng.integers(-20, 40)), 1000)
        charpoly = (HH.subs(sub) - lam * sp.eye(6)).det()
        assert sp.expand(charpoly - expected.subs(sub)) == 0
    # and the module's formulas are the same expressions
    for vals in ((1.0, 1.0, 1.0, 0.5, 0.01), (2.0, 0.3, 1.7, 2.4, -0.02)):
        sub = dict(zip((k, a, r, rho, f), vals))
        assert float(lam5.subs(sub)) == pytest.approx(float(two_particle.lambda5(*vals)), rel=1e-14)
        assert float(lam6.subs(sub)) == pytest.approx(float(two_particle.lambda6(vals[2], vals[3], vals[4])),
                                                      rel=1e-14, abs=1e-300)


def test_lambda6_field_matches_closed_forms_and_changes_sign_on_the_two_lines():
    field = two_particle.lambda6_field(np.linspace(0.2, 3.0, 57), np.linspace(-0.005, 0.02, 51), verify=True)
    for name in ("lam4", "lam5", "lam6"):
        assert field[f"error_{name}"] <= 100 * EPS                   # relative to ‖𝓗‖₂
    F, R = np.meshgrid(field["f_over_kr"], field["rho_over_r"], indexing="ij")
    off = (np.abs(R - 1) > 1e-9) & (np.abs(F) > 1e-12)
    assert np.array_equal(np.sign(field["lam6"][off]), np.sign(F * (R - 1))[off])
    assert np.all(np.abs(field["lam6"][~off]) <= 100 * EPS * 4.1)       # ‖𝓗‖₂ ≈ 4 k here
    assert field["lam5"].min() > 3.5 and np.allclose(field["lam4"], 2.0, rtol=0, atol=100 * EPS * 4.1)
    assert field["min_overlap6"] >= 1 - 1e-12


@pytest.mark.parametrize("seed", range(6))
def test_core_matches_closed_forms_at_random_points(seed):
    """granstab.analyze (paper's metric) gives 2k, λ5, λ6 of the closed forms for random r, ρ, k, α, f."""
    rng = np.random.default_rng(seed)
    r, rho = rng.uniform(0.3, 3.0, 2)
    k, alpha = rng.uniform(0.5, 3.0), rng.uniform(0.2, 1.5)
    f = k * r * rng.uniform(-0.005, 0.02)
    modes = two_particle.core_modes(r, rho, f, k, alpha)
    scale = np.abs(modes["stability"]).max()
    assert abs(modes["lam4"] - 2 * k) <= 200 * EPS * scale
    assert abs(modes["lam5"] - two_particle.lambda5(k, alpha, r, rho, f)) <= 200 * EPS * scale
    assert abs(modes["lam6"] - two_particle.lambda6(r, rho, f)) <= 200 * EPS * scale


def test_sample_table_rows():
    rows = {(s["rho_over_r"], s["f_over_kr"]): s for s in two_particle.sample_table()}
    assert rows[(0.5, 0.01)]["verdict"] == "unstable" and rows[(0.5, 0.01)]["n_zero"] == 3
    assert rows[(2.0, 0.01)]["verdict"] == "stable"
    assert rows[(1.0, 0.01)]["verdict"] == "neutral" and rows[(1.0, 0.01)]["n_zero"] == 4
    assert rows[(0.5, -0.005)]["verdict"] == "stable" and rows[(2.0, -0.005)]["verdict"] == "unstable"
    for s in rows.values():
        lam4, lam5, lam6 = s["core_modes"]
        assert lam5 == pytest.approx(s["closed"][4], abs=1e-13) and lam6 == pytest.approx(s["closed"][5], abs=1e-13)
        assert sorted([0, 0, 0, 2.0, s["closed"][4], s["closed"][5]]) == pytest.approx(s["core_sorted"], abs=1e-13)
    assert rows[(0.5, 0.01)]["closed"][4] == pytest.approx(3.975, rel=1e-15)   # 4 - 0.01·(4 - 1.5)/1


def test_general_unequal_case_is_eq_exampleH2():
    assert two_particle.general_case_check() <= 1e-14


# ------------------------------------------------------------------------------------------------ presets

def _same_scene(a, b, rtol=1e-14):
    for key in ("x", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "k", "alpha", "mu",
                "rolling", "load", "load_moment"):
        A, B = getattr(a, key), getattr(b, key)
        assert A.shape == B.shape, key
        assert np.allclose(A, B, rtol=rtol, atol=rtol * max(np.abs(B).max(), 1e-300)), key
    assert tuple(a.names) == tuple(b.names) and np.array_equal(a.p, b.p) and np.array_equal(a.q, b.q)


@pytest.mark.parametrize("name, rho, verdict, lam6", [("two_particle.toml", 0.5, "unstable", -0.005),
                                                       ("two_particle_flat.toml", 2.0, "stable", 0.01),
                                                       ("two_disks.toml", 1.0, "neutral", 0.0)])
def test_two_particle_presets(name, rho, verdict, lam6):
    sc = granstab.load_scene(PRESETS / name)
    _same_scene(sc, two_particle.scene(1.0, rho, 0.01, state="auto"))
    res = granstab.analyze(sc, rotation_length=1.0)
    assert res.summary["verdict"] == verdict
    lam = res.branches[0].stability_eigenvalues
    assert np.min(np.abs(lam - lam6)) <= 1e-14
    assert (PRESETS / name).read_text().startswith("# ")


def test_hand_in_glove_preset_geometric_stiffness_dominates():
    sc = granstab.load_scene(PRESETS / "hand_in_glove.toml")
    _same_scene(sc, two_particle.scene(1.0, 1.0, 0.01, rq=2.0, rhoq=-1.002, state="auto"))
    K = granstab.stiffness(sc)
    H = two_particle.paper_stiffness(1.0, 1.0, 1.0, 2.0, 1.0, -1.002, 0.01)
    assert np.abs(K.H - H).max() <= 1e-12 * np.abs(H).max()
    ratio = np.linalg.norm(K.Hg1 + K.Hg2 + K.Hg3, 2) / np.linalg.norm(K.Hm, 2)
    assert ratio > 5                                                  # f/(ρp+ρq) = -5 k dominates k
    assert granstab.analyze(sc).summary["verdict"] == "stable"


def test_gear_presets_are_the_study_packings():
    _same_scene(granstab.load_scene(PRESETS / "gear_packing.toml"), gear.packing())
    _same_scene(granstab.load_scene(PRESETS / "gear_packing_rolling.toml"), gear.packing(rolling=gear.PRESET_ROLLING))


def test_four_disk_preset_is_the_study_scene_with_the_paper_loads():
    sc = granstab.load_scene(PRESETS / "four_disk.toml")
    _same_scene(sc, four_disk.scene())
    assert sc.state == ("sliding",) * 4 and np.all(np.abs(sc.yield_function()) <= 1e-15)
    bv, bh = four_disk.loads(np.pi / 4, 1e-3, 0.5)
    assert bv == pytest.approx(3e-3 / np.sqrt(2), rel=1e-14) and bh == pytest.approx(1e-3 / np.sqrt(2), rel=1e-14)
    expected = np.array([[0, -bv], [bh, 0], [0, bv], [-bh, 0]])
    assert np.allclose(sc.load, expected, rtol=0, atol=1e-15) and np.all(sc.load_moment == 0)


def test_3d_preset_runs_with_moments_and_sliding():
    sc = granstab.load_scene(PRESETS / "spheres_tetrahedron.toml")
    assert sc.dim == 3 and sc.has_moments and sc.has_rolling and np.any(np.linalg.norm(sc.tangential_force(), axis=1))
    res = granstab.analyze(sc)
    assert len(res.branches) == 8 and all(b.n_zero == 6 for b in res.branches)
    assert max(res.errors.values()) <= 1e-12
    assert res.summary["verdict"] == "stable"


MINE = ("two_particle.toml", "two_particle_flat.toml", "two_disks.toml", "hand_in_glove.toml", "gear_packing.toml",
        "gear_packing_rolling.toml", "four_disk.toml", "spheres_tetrahedron.toml")


def test_every_preset_has_a_comment_block_and_loads():
    for path in (PRESETS / name for name in MINE):
        text = path.read_text()
        block = [line for line in text.splitlines() if line.startswith("#")]
        assert text.startswith("#") and any("what it shows" in line.lower() for line in block), path
        granstab.load_scene(path)


# --------------------------------------------------------------------------------------------------- gear

def test_gear_mode_and_its_removal():
    base = {key: gear.DEFAULT[key] for key in ("R", "f_h", "f_v", "k", "alpha", "mu")}
    g0 = gear.analyse(gear.packing(4, 4, **base), 4)
    assert g0["n_zero"] == 4 and g0["verdict"] == "neutral"
    assert g0["overlap"] >= 1 - 1e-12 and g0["translation_share"] <= 1e-12
    assert abs(g0["rayleigh"]) <= 100 * EPS * g0["norm"]
    g1 = gear.analyse(gear.packing(4, 4, rolling=gear.PRESET_ROLLING, **base), 4)
    assert g1["n_zero"] == 3 and g1["verdict"] == "stable"
    assert g1["rayleigh"] == pytest.approx(4 * 0.01 * 24 / 16, rel=1e-12)  # 4 k_r M_c / N
    assert g1["gear_like_eigenvalue"] == pytest.approx(0.0597829197, rel=1e-8)
    assert g1["gear_like_overlap"] > 0.999


def test_gear_zero_needs_r_equal_rho_and_even_parity():
    base = {key: gear.DEFAULT[key] for key in ("R", "f_h", "f_v", "k", "alpha", "mu")}
    lo = gear.analyse(gear.packing(4, 4, rho=0.999, **base), 4)
    hi = gear.analyse(gear.packing(4, 4, rho=1.001, **base), 4)
    # Σ_c f_c (ρ - r) (2/N): 12 contacts at 0.01 and 12 at 0.02, N = 16 → ±4.5e-5
    assert lo["gear_like_eigenvalue"] == pytest.approx(-4.5e-5, rel=1e-3)
    assert hi["gear_like_eigenvalue"] == pytest.approx(4.5e-5, rel=1e-3)
    odd = gear.analyse(gear.packing(3, 3, **base), 3)
    assert odd["n_zero"] == 3 and odd["gear_like_eigenvalue"] < -1e-6 and odd["rigid_part_of_gear"] > 0.01


# ---------------------------------------------------------------------------------------------- four-disk

@pytest.fixture(scope="module")
def fd_result():
    return granstab.analyze(four_disk.scene())


def test_four_disk_totals_are_the_papers(fd_result):
    rows = four_disk.stability_table(fd_result)
    t = four_disk.totals(rows)
    assert len(rows) == 16 and t["zeros"] == [4] * 16
    assert (t["consistent_nonzero"], t["positive"], t["negative"]) == (30, 21, 9)
    assert all(len(r["consistent_zero"]) == 1 and r["consistent_zero"][0]["sign"] == "±v" for r in rows)
    assert fd_result.summary["verdict"] == "unstable"
    assert max(fd_result.errors.values()) <= 1e-12


def test_four_disk_uniqueness_table(fd_result):
    rows = four_disk.uniqueness_table(fd_result)
    t = four_disk.uniqueness_totals(rows)
    assert t["zeros"] == [6, 5, 5, 4, 5, 4, 5, 4, 5, 5, 4, 4, 4, 4, 4, 4]     # erratum 5, docs/errata.md: 4 to 6
    assert (t["consistent"], t["positive"], t["negative"], t["complex"]) == (26, 25, 1, 0)
    assert t["type2_branches"] == 16


def test_four_disk_count_robustness():
    sweep = four_disk.tolerance_sweep(s_rtols=(1e-12, 1e-8, 1e-4, 1e-3), zero_factors=(1.0, 1e8))
    triples = [(r["consistent_nonzero"], r["positive"], r["negative"]) for r in sweep["s_rtol"]]
    assert triples == [(30, 21, 9)] * 3 + [(34, 25, 9)]                # S of one pair is only ~1.2e-4 of its scale
    assert all((r["consistent_nonzero"], r["positive"], r["negative"]) == (30, 21, 9) for r in sweep["zero_factor"])
    for f_over_k in (1e-5, 3e-2):
        t = four_disk.count(**{**four_disk.PAPER, "f_over_k": f_over_k})
        assert (t["consistent_nonzero"], t["positive"], t["negative"]) == (30, 21, 9)
    t = four_disk.count(**{**four_disk.PAPER, "rho": 1.001})
    assert t["zeros_max"] == 3 and t["consistent_nonzero"] == 46
    assert four_disk.mechanical_only()["negative"] == 9
    clusters = {r["gap"]: r["positive"] for r in four_disk.cluster_sweep(gaps=(0.0, 1e-2))}
    assert clusters == {0.0: 21, 1e-2: 24}


def test_four_disk_sliding_path():
    path = four_disk.sliding_path(np.linspace(45.0, 15.0, 61))
    assert path["ratio_closed"][0] == pytest.approx(3.0, rel=1e-14)
    assert np.all(np.diff(path["ratio_closed"]) < 0)                          # softening as β decreases
    assert np.max(np.abs(path["ratio_core"] / path["ratio_closed"] - 1)) <= 1e-8   # Simpson error ~ h⁴
    assert path["rate_residual"].max() <= 1e-10
    assert path["s_min_relative"].min() > 0.99                                # S > 0, all four equal
    f = four_disk.PAPER["f_over_k"]
    w = path["work"]
    assert np.allclose(w["core_total"], -8 * f, rtol=1e-10) and np.allclose(w["Hg2"], -8 * f, rtol=1e-10)
    assert np.max(np.abs(w["core_mechanical"])) <= 1e-10 * 8 * f
    assert np.max(np.abs(w["Hg1"])) <= 1e-12 * f and np.max(np.abs(w["Hg3"])) <= 1e-12 * f
    assert all(m == [1, 1, 1, 1] for m in path["core_masks"])


# ---------------------------------------------------------------------------------------- sliding contact

def test_sliding_contact_eigenvalues():
    data = sliding_contact.study(mu=np.linspace(0.05, 1.5, 7), alphas=(0.25, 1.0, 2.0), k_values=(1.0, 2.5))
    assert data["error_law"] <= 20 * EPS and data["error_scene"] <= 20 * EPS   # relative to k and αk
    assert data["paper_negative"] == pytest.approx(-0.05901699437494742, rel=1e-14)
    three = [c for c in data["cases"] if c["dim"] == 3 and c["k"] == 2.5][0]
    assert np.allclose(np.sort(three["law"][:, 1, :], axis=-1)[:, 1], 2.5, rtol=1e-14)  # α k with α = 1
