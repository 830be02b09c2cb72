"""The explorer's session state without a browser: every change produces the right scene and numbers.

Reference values are independent of the app: λ⁽⁶⁾ = f (ρ - r) and λ⁽⁴⁾ = 2k for the symmetric pair (docs/errata.md,
Sec. 4.1), the sign pattern of the λ⁽⁶⁾ contour (it changes sign exactly on ρ/r = 1 and on f = 0), and the
paper's own 6×6 matrices (granstab.paper.two_particle) for the field. Tolerances are relative to the scale of
the numbers compared (k for eigenvalues, the field's max |λ|), at a few hundred eps.
"""
from __future__ import annotations

import itertools
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import (
    FLAT_PAIR,
    ROOT,  # noqa: E402
)

from granstab_app.field import lambda6_field
from granstab_app.modes import label_mode
from granstab_app.scenes import ContactModel, ShapeModel, TwoParticleModel, load_model
from granstab_app.state import Session

REPO = ROOT
EPS = np.finfo(float).eps


THREE_3D = """\
dim = 3
title = "ellipsoid, sphere, ellipsoid"
[defaults]
k = 2.0
alpha = 0.8
mu = 0.4
[[particles]]
name = "a"
x = [0.0, 0.0, 0.0]
shape = { kind = "ellipsoid", a = 1.0, b = 0.7, c = 0.6 }
[[particles]]
name = "b"
x = [1.99, 0.0, 0.0]
shape = { kind = "sphere", radius = 1.0 }
[[particles]]
name = "c"
x = [3.98, 0.0, 0.0]
shape = { kind = "ellipsoid", a = 1.0, b = 1.3, c = 0.8 }
"""

CHAIN = """\
dim = 2
title = "three disks in a chain, contact level"
[defaults]
k = 1.0
alpha = 0.5
mu = 0.3
[[particles]]
name = "a"
x = [0.0, 0.0]
[[particles]]
name = "b"
x = [2.0, 0.0]
[[particles]]
name = "c"
x = [4.0, 0.0]
[[contacts]]
p = "a"
q = "b"
point = [1.0, 0.0]
normal = [1.0, 0.0]
curvature_p = -1.0
curvature_q = -1.0
force = [-0.01, 0.0]
[[contacts]]
p = "b"
q = "c"
point = [3.0, 0.0]
normal = [1.0, 0.0]
curvature_p = -1.0
curvature_q = -1.0
force = [-0.01, 0.0]
"""


@pytest.fixture()
def presets(tmp_path):
    folder = tmp_path / "presets"
    folder.mkdir()
    (folder / "two_particle.toml").write_text((REPO / "presets" / "two_particle.toml").read_text())
    (folder / "flat_pair.toml").write_text(FLAT_PAIR)
    (folder / "three_3d.toml").write_text(THREE_3D)
    (folder / "chain.toml").write_text(CHAIN)
    (folder / "broken.toml").write_text("dim = 2\n[[particles]]\nname = 'a'\nx = [0.0]\n")
    (folder / "malformed.toml").write_text("dim = = 2\n")
    return folder


@pytest.fixture()
def pair(presets):
    return Session(presets_dir=presets)


def eig(session, label, branch=0):
    return [m.eigenvalue for m in session.modes() if m.label == label and m.branch == branch]


# ------------------------------------------------------------------------------------------ the pair

def test_opens_on_the_two_particle_preset(pair):
    assert (pair.preset, pair.kind, pair.error) == ("two_particle", "two_particle", None)
    assert pair.params["rho_r"] == 0.5 and pair.params["f_kr"] == 0.01
    assert set(pair.used_params) == {"rho_r", "f_kr", "mu", "mobilised", "alpha", "k", "rolling"}
    assert pair.verdict == "unstable"
    # λ⁽⁶⁾ = f (ρ - r) = 0.01 (0.5 - 1), λ⁽⁴⁾ = 2k (Sec. 4.1), in units of k = 1
    assert pair.rolling_eigenvalue() == pytest.approx(-0.005, abs=100 * EPS)
    assert eig(pair, "indentation") == [pytest.approx(2.0, abs=100 * EPS)]
    assert len(eig(pair, "shearing")) == 1 and len(eig(pair, "rigid")) == 3


@pytest.mark.parametrize("rho_r, verdict", [(0.3, "unstable"), (0.99, "unstable"), (1.0, "neutral"),
                                            (1.01, "stable"), (2.5, "stable")])
def test_verdict_changes_sign_on_rho_equal_r(pair, rho_r, verdict):
    assert pair.set_params(rho_r=rho_r) or rho_r == 0.5
    assert pair.verdict == verdict and pair.error is None
    f, k = pair.params["f_kr"], pair.params["k"]
    assert pair.rolling_eigenvalue() == pytest.approx(f * (rho_r - 1.0), abs=100 * EPS * k)


@pytest.mark.parametrize("f_kr, rho_r, verdict", [(0.0, 0.5, "neutral"), (0.0, 2.0, "neutral"),
                                                  (-0.004, 0.5, "stable"), (-0.004, 1.5, "unstable")])
def test_zero_and_cohesive_forces(pair, f_kr, rho_r, verdict):
    pair.set_params(f_kr=f_kr, rho_r=rho_r)
    assert pair.error is None and pair.verdict == verdict
    assert pair.rolling_eigenvalue() == pytest.approx(f_kr * (rho_r - 1.0), abs=100 * EPS)


def test_k_scales_eigenvalues_not_the_verdict(pair):
    pair.set_params(k=4.0)
    assert pair.verdict == "unstable"
    assert pair.rolling_eigenvalue() == pytest.approx(-0.005, rel=1e-12)       # λ⁽⁶⁾/k
    assert eig(pair, "indentation") == [pytest.approx(8.0, rel=1e-12)]          # 2k


def test_slider_values_are_cleaned_and_unchanged_values_do_nothing(pair):
    revision = pair.revision
    assert pair.set_params(rho_r=0.5) is False and pair.revision == revision
    assert pair.set_params(rho_r=0.30000000000000004) and pair.params["rho_r"] == 0.3
    pair.set_params(rho_r=99.0, mu=-1.0)
    assert pair.params["rho_r"] == 3.0 and pair.params["mu"] == 0.0
    with pytest.raises(KeyError):
        pair.set_params(nonsense=1.0)


def test_full_mobilisation_gives_two_branches_and_a_sliding_mode(pair):
    pair.set_params(mobilised=1.0)
    report = pair.report()
    assert report["n_sliding"] == 1 and report["n_branches"] == 2
    assert pair.scene.at_yield().tolist() == [True]
    labels = {m.label for m in pair.modes() if m.consistent}
    assert "sliding" in labels
    assert report["type1"].startswith(("yes", "no", "not evaluated"))
    assert pair.verdict == "unstable"


def test_rolling_stiffness_lifts_the_rolling_mode(pair):
    pair.set_params(rolling=0.01)                      # M = 0.01 k r²: νᵀMν = 0.01·(1 - (-1))²/2 = 0.02
    assert pair.rolling_eigenvalue() == pytest.approx(-0.005 + 0.02, abs=100 * EPS)
    assert pair.verdict == "stable"


# ------------------------------------------------------------------------------------------ presets

def test_switching_presets(pair):
    assert pair.presets()[0] == "two_particle"
    assert pair.load_preset("flat_pair") and pair.error is None
    assert pair.kind == "shapes" and "rho_r" not in pair.used_params and "mobilised" in pair.used_params
    assert pair.verdict == "stable" and pair.scene.n_contacts == 1
    assert pair.field() is None                         # no contour work for a scene without it
    assert pair.load_preset("two_particle") and pair.kind == "two_particle" and pair.verdict == "unstable"
    assert pair.field() is not None


@pytest.mark.parametrize("name, needle", [("broken", "broken.toml"), ("malformed", "malformed TOML"),
                                          ("no_such_preset", "cannot read file")])
def test_bad_preset_is_a_message_not_an_exception(pair, name, needle):
    assert pair.load_preset(name) is False
    assert needle in pair.error and "\n" not in pair.error
    assert pair.kind == "two_particle" and pair.analysis is not None     # the previous scene stays


def test_a_bad_preset_at_start_falls_back_to_the_pair(presets):
    s = Session("broken", presets_dir=presets)
    assert s.kind == "two_particle" and s.verdict == "unstable" and "broken.toml" in s.error


def test_contact_level_scene_overrides_law_parameters(presets):
    s = Session("chain", presets_dir=presets)
    assert isinstance(s.model, ContactModel) and not s.draggable
    assert set(s.used_params) == {"mu", "alpha", "k", "rolling"}
    assert s.params["alpha"] == 0.5 and s.params["mu"] == 0.3
    s.set_params(alpha=1.5, mu=0.7)
    assert np.all(s.scene.alpha == 1.5) and np.all(s.scene.mu == 0.7) and s.error is None
    s.move("b", [2.0, 0.1], 0.0)                        # not draggable: a message, no change
    assert "cannot be dragged" in s.error and np.allclose(s.scene.x[1], [2.0, 0.0])


def test_3d_shape_scene(presets):
    s = Session("three_3d", presets_dir=presets)
    assert s.error is None and s.scene.dim == 3 and s.scene.n_contacts == 2
    assert s.params["k"] == 2.0 and s.params["alpha"] == 0.8
    assert len(s.modes()) == 18 and sum(m.label == "rigid" for m in s.modes()) >= 6
    assert all(b.R.shape == (3, 3) for b in s.bodies())


# ------------------------------------------------------------------------------------------ dragging

def test_drag_turns_the_pair_into_shapes_and_follows_the_geometry(pair):
    pair.move("q", [1.995, 0.0], 0.0)                  # the slider state: overlap f/k = 0.005
    assert pair.kind == "shapes" and pair.notice and pair.error is None
    assert pair.scene.n_contacts == 1 and pair.verdict == "unstable"
    assert -pair.scene.force[0] @ pair.scene.normal[0] == pytest.approx(0.005, rel=1e-9)   # f = kδ
    pair.move("q", [1.98, 0.05], 0.1)                   # off axis, rotated: still touching, new normal
    assert pair.scene.n_contacts == 1 and abs(pair.scene.normal[0][1]) > 1e-5 and pair.error is None
    pair.move("q", [5.0, 0.0], 0.0)                     # pulled apart: the contact vanishes
    assert pair.scene.n_contacts == 0 and pair.error is None
    pair.reset_poses()
    assert pair.scene.n_contacts == 1


# ------------------------------------------------------------------------------------------ modes

def test_mode_labels_of_the_pair(pair):
    labels = {m.label for m in pair.modes()}
    assert labels == {"rigid", "rolling", "indentation", "shearing"}
    rolling = next(m for m in pair.modes() if m.label == "rolling")
    assert rolling.consistent and rolling.shares["rolling"] == pytest.approx(1.0)


def test_label_of_hand_made_motions(pair):
    scene, L = pair.scene, pair.analysis.length
    assert label_mode(scene, np.array([1.0, 0, 0, 1.0, 0, 0]), None, L).label == "rigid"      # translation
    assert label_mode(scene, np.array([0, 0, 1.0, 0, 0, -1.0]), None, L).label == "rolling"
    assert label_mode(scene, np.array([1.0, 0, 0, -1.0, 0, 0]), None, L).label == "indentation"
    assert label_mode(scene, np.array([0, 1.0, 0, 0, -1.0, 0]), None, L).label == "shearing"
    assert label_mode(scene, np.array([0, 1.0, 0, 0, -1.0, 0]), np.array([1]), L).label == "sliding"


def test_mode_animation_poses(pair):
    mode = next(m for m in pair.modes() if m.label == "rolling")
    still = pair.mode_bodies(mode, 0.3, 0.0)
    for a, b in zip(still, pair.bodies()):
        assert np.allclose(a.x, b.x) and np.allclose(a.R, b.R)
    moved = pair.mode_bodies(mode, 0.3, np.pi / 2)
    angles = [np.arctan2(b.R[1, 0], b.R[0, 0]) for b in moved]
    # rolling: equal and opposite turns, the largest motion = amplitude × particle size
    assert angles[0] == pytest.approx(-angles[1], abs=1e-12)
    assert max(abs(a) for a in angles) * pair.size == pytest.approx(0.3 * pair.size, rel=1e-9)


# ------------------------------------------------------------------------------------------ field

def test_field_changes_sign_exactly_on_rho_r_1_and_f_0(pair):
    field = pair.field()
    scale = 4.0                                          # ‖H‖/k: the round-off scale of every eigenvalue
    i = np.flatnonzero(np.isclose(field.rho_r, 1.0))[0]
    j = np.flatnonzero(np.isclose(field.f_kr, 0.0))[0]
    assert np.abs(field.lam[:, i]).max() <= 100 * EPS * scale
    assert np.abs(field.lam[j, :]).max() <= 100 * EPS * scale
    R, F = np.meshgrid(field.rho_r, field.f_kr)
    assert np.all(np.sign(field.lam[np.abs(field.lam) > 1e-9 * scale]) ==
                  np.sign((F * (R - 1))[np.abs(field.lam) > 1e-9 * scale]))


@pytest.mark.parametrize("alpha", [1.0, 0.3])
def test_field_from_the_core_agrees_with_the_papers_matrices(alpha):
    studies = lambda6_field(alpha, 0.0)
    core = lambda6_field(alpha, 0.0, use_studies=False)
    assert "granstab.paper.two_particle" in studies.source and "contact_blocks" in core.source
    # round-off of an eigenvalue is relative to ‖H‖ ≈ 2k + 2αk(1 + r²) (λ⁽⁴⁾, λ⁽⁵⁾), not to |λ⁽⁶⁾| ≤ 0.04k
    norm_H = 2.0 + 2.0 * alpha * 2.0
    assert np.abs(studies.lam - core.lam).max() <= 100 * EPS * norm_H


def test_current_state_matches_the_field(pair):
    pair.set_params(rho_r=1.5, f_kr=0.015)
    field = pair.field()
    i = np.flatnonzero(np.isclose(field.rho_r, 1.5))[0]
    j = np.flatnonzero(np.isclose(field.f_kr, 0.015))[0]
    assert pair.rolling_eigenvalue() == pytest.approx(field.lam[j, i], abs=100 * EPS)


def test_a_click_on_the_surface_finds_its_grid_point(pair):
    from granstab_app.fieldview import ray_heightfield
    from granstab_app.views import SceneView
    field = pair.field()
    place, _ = SceneView(None).field_frame(field, pair.size)
    Z = field.lam / np.abs(field.lam).max() * 0.8 * pair.size
    X, Y = place(1.5, 0.01)
    lam = field.lam[np.isclose(field.f_kr, 0.01), np.isclose(field.rho_r, 1.5)][0]
    z = lam / np.abs(field.lam).max() * 0.8 * pair.size
    ray = np.array([-0.3, 0.4, -1.0])                    # an oblique view that hits the surface at (1.5, 0.01)
    hit = ray_heightfield(np.array([X, Y, z]) - 5.0 * ray, ray, field, place, Z)
    # within 1% of a slider step (ρ/r step 0.01, f/(kr) step 0.0005): the click lands on the right slider value
    assert hit[0] == pytest.approx(1.5, abs=1e-4) and hit[1] == pytest.approx(0.01, abs=5e-6)
    assert ray_heightfield(np.array([X + 50.0, Y, 5.0]), np.array([0, 0, -1.0]), field, place, Z) is None


# ------------------------------------------------------------------------------------------ exports

@pytest.mark.parametrize("preset, change", [("two_particle", {"rho_r": 1.7, "mobilised": 0.4}),
                                            ("flat_pair", {"mu": 0.8, "alpha": 0.6}),
                                            ("chain", {"alpha": 0.9}), ("three_3d", {"rolling": 0.05})])
def test_exported_scene_reloads_to_the_same_analysis(presets, tmp_path, preset, change):
    s = Session(preset, presets_dir=presets)
    s.set_params(**change)
    if preset == "flat_pair":
        s.move("b", [1.985, 0.1], 0.2)
    name, content = s.export_scene()
    path = tmp_path / name
    path.write_bytes(content)
    again = Session(str(path), presets_dir=presets)
    assert again.error is None and again.verdict == s.verdict
    a = np.concatenate([b.stability_eigenvalues for b in s.analysis.branches])
    b = np.concatenate([b.stability_eigenvalues for b in again.analysis.branches])
    assert np.abs(a - b).max() <= 1e-12 * np.abs(a).max()


def test_export_analysis_and_contour(pair):
    name, content = pair.export_analysis()
    data = json.loads(content)
    assert name.endswith(".json") and data["summary"]["verdict"] == "unstable"
    assert data["app"]["params"]["rho_r"] == 0.5 and {m["label"] for m in data["app"]["modes"]} >= {"rolling"}
    name, png = pair.export_contour()
    assert name.endswith(".png") and png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    pair.load_preset("flat_pair")
    with pytest.raises(ValueError):
        pair.export_contour()


def test_failed_analysis_is_kept_as_a_message(pair, monkeypatch):
    from granstab_app import pools

    def boom(scene, **options):
        raise RuntimeError("eigensolver exploded")
    monkeypatch.setattr(pools, "analyze", boom)
    pair.set_params(rho_r=0.7)
    assert pair.analysis is None and pair.verdict is None and "eigensolver exploded" in pair.error
    assert pair.report()["verdict"] is None and pair.modes() == []
    with pytest.raises(ValueError):
        pair.export_analysis()


def test_models_from_files():
    assert isinstance(load_model(REPO / "presets" / "two_particle.toml"), TwoParticleModel)
    pair = TwoParticleModel()
    assert isinstance(pair.to_shapes(pair.initial_params()), ShapeModel)


# ------------------------------------------------------------------------------------------ issue 13 defects

class RecordingScene:
    """A stand-in for viser's scene API that keeps what the λ⁽⁶⁾ surface view sends (mesh, marker position): each
    node's arguments and its handle (whose properties the view then writes, as on viser's handles)."""

    def __init__(self):
        self.sent = {}

    def __getattr__(self, name):
        def add(node, *args, **kwargs):
            handle = SimpleNamespace(on_click=lambda fn: None, **kwargs)
            self.sent[node] = (args, kwargs, handle)
            return handle
        return add


def test_current_state_ball_sits_on_the_cached_surface_for_every_rho(pair):
    from scipy.interpolate import RegularGridInterpolator
    """The surface is built once per field (cached) and the ball is placed on every update: both must use the
    same scale, or the ball drifts off the surface as ρ/r (hence the drawn particle size) grows past 1."""
    from granstab_app.views import SceneView
    view = SceneView(RecordingScene())
    field = pair.field()
    view.draw_field(pair, field, (pair.params["rho_r"], pair.params["f_kr"], pair.rolling_eigenvalue()))
    mesh = view.api.sent["/field/surface"][0][0]
    V = np.asarray(mesh.vertices).reshape(len(field.f_kr), len(field.rho_r), 3)
    xs, ys, Z = V[0, :, 0], V[:, 0, 1], V[:, :, 2]
    for rho_r, f_kr in ((1.5, 0.01), (2.59, 0.015), (3.0, 0.02), (0.3, -0.004)):
        pair.set_params(rho_r=rho_r, f_kr=f_kr)
        assert pair.field() is field                                        # the cached surface is kept
        view.draw_field(pair, pair.field(), (rho_r, f_kr, pair.rolling_eigenvalue()))
        assert view.api.sent["/field/surface"][0][0] is mesh
        cx, cy, cz = view.api.sent["/field/current"][2].position
        # the ball is over its (ρ/r, f/(kr)) on the surface (λ⁽⁶⁾ = f(ρ - r) is bilinear, so is the grid's
        # interpolation: exact) and lifted by 0.05 r; tolerance 1e-9 r
        assert (cx, cy) == (pytest.approx(np.interp(rho_r, field.rho_r, xs), abs=1e-9),
                            pytest.approx(np.interp(f_kr, field.f_kr, ys), abs=1e-9))
        surface_z = RegularGridInterpolator((ys, xs), Z)([[cy, cx]])[0]
        assert cz - 0.05 * pair.field_scale == pytest.approx(surface_z, abs=1e-9)


@pytest.mark.parametrize("rho_r, word", [(0.5, "sharp"), (1.0, "circular"), (1.5, "flat"), (3.0, "flat")])
def test_the_pairs_title_follows_rho(pair, rho_r, word):
    pair.set_params(rho_r=rho_r)
    assert f", {word} contact (ρ/r = {rho_r:g}" in pair.scene.title
    assert "sharp" not in pair.scene.title or word == "sharp"


def test_rolling_eigenvalue_is_zero_within_the_tolerance_at_rho_equal_r(pair):
    pair.set_params(rho_r=1.0, f_kr=0.01)
    tol = pair.zero_tolerance()
    assert 0 < tol < 1e-6                                  # relative to k = 1: a round-off scale, not a physics one
    assert pair.rolling_eigenvalue() == 0.0
    pair.set_params(rho_r=1.01)
    assert pair.rolling_eigenvalue() == pytest.approx(0.01 * 0.01, rel=1e-9)    # f (ρ - r) just off the line


def test_reset_returns_a_dragged_pair_to_its_sliders(pair):
    pair.set_params(rho_r=1.5, f_kr=0.015)
    pair.move("q", [2.0, 0.3], 0.0)
    assert pair.kind == "shapes" and pair.resettable
    pair.reset_poses()
    assert pair.kind == "two_particle" and pair.notice is None and not pair.resettable
    assert (pair.params["rho_r"], pair.params["f_kr"]) == (1.5, 0.015)
    assert pair.verdict == "stable" and pair.rolling_eigenvalue() == pytest.approx(0.015 * 0.5, rel=1e-9)


def test_particle_shares_locate_the_mode(pair, presets):
    # the pair's rolling mode turns both particles equally: each carries the whole motion (share 1, to round-off)
    rolling = next(m for m in pair.modes() if m.branch == 0 and m.label == "rolling")
    assert pair.particle_shares(rolling) == pytest.approx([1.0, 1.0], abs=1e-9)
    # the 143-disk frame: the lowest consistent negative mode is picked and lives on a few particles
    frame = Session(str(REPO / "presets" / "annulus_frame.json"))
    lowest = min((m for m in frame.modes() if m.consistent), key=lambda m: m.eigenvalue)
    assert lowest.eigenvalue < 0 and frame.verdict == "unstable"
    shares = frame.particle_shares(lowest)
    assert shares.shape == (143,) and shares.max() == 1.0 and shares.min() >= 0
    assert np.sum(shares > 0.5) < 143 // 2           # localised: fewer than half the disks carry half the motion


def test_inertia_metric_where_the_scene_has_masses():
    """The metric dropdown offers the inertia metric only with masses; its frequencies scale as 1/√m."""
    import dataclasses

    import granstab
    s = Session("four_disk", presets_dir=REPO / "presets")
    assert s.preset == "four_disk" and s.metric_choices == ("L",) and not s.set_metric("inertia") and "not available" in s.error
    s = Session("ellipses_sharp", presets_dir=REPO / "presets")
    assert s.metric_choices == ("L", "inertia") and s.report()["dynamics"] is None
    assert s.set_metric("inertia") and s.analysis.metric.name == "inertia"
    d = s.report()["dynamics"]
    heavy = dataclasses.replace(s.scene, mass=4 * s.scene.mass, inertia=4 * s.scene.inertia)
    b = min(granstab.analyze(heavy, metric="inertia").branches, key=lambda b: b.stability_eigenvalues.min())
    lam = np.sort(b.stability_eigenvalues)
    w4 = np.sqrt(lam[lam > b.accuracy.max()])[:len(d["frequencies"])]
    # four times the mass: half the frequencies (relative to the largest, at the eigenvalues' accuracy)
    assert len(d["frequencies"]) > 0 and np.allclose(w4, d["frequencies"] / 2, rtol=1e-8)
    assert s.load_preset("four_disk") and s.metric == "L" and "no masses" in s.notice


def test_scan_map_opens_a_cluster_and_returns(tmp_path):
    """A scan folder opens as the map (no analysis of the packing); a click ray over the planted sharp particle
    opens its cluster, whose verdict and size are the scan row's; *Back to the map* returns."""
    from test_scan import planted_lattice

    import granstab
    from granstab.scan import read_map, scan
    from granstab_app.scanmap import fraction_colours
    scene, _ = planted_lattice(40, 0.4)
    packing = tmp_path / "lattice.json"
    packing.write_text(json.dumps(granstab.scene_to_dict(scene)))
    scan(granstab.load_scene(packing), tmp_path / "scan", boundary="loads", workers=1, figures=False)
    clusters = read_map(tmp_path / "scan")["clusters"]
    row = {k: v[list(clusters["center"]).index(scene.names.index("p40"))] for k, v in clusters.items()}
    s = Session(str(tmp_path / "scan"))
    assert s.error is None and s.kind == "scan_map" and s.analysis is None and not s.deferred
    colours = s.map_colours
    around = [m for v, m, ms in zip(clusters["verdict"], clusters["mechanism"], clusters["members"]) if 40 in ms]
    # its own cluster geometric, its six neighbours' boundary (the planted particle on their rim, dead loads there)
    assert sorted(around) == ["boundary"] * 6 + ["geometric"]
    assert tuple(colours[40]) == tuple(fraction_colours(np.array([1 / 7]))[0]) and tuple(colours[0]) == (250, 250, 250)
    top = [*scene.x[40] + [0.3, -0.2], 50.0]                 # straight down onto particle 40, off its centre
    assert s.pick(top, [0.0, 0.0, -1.0]) == "p40"
    gap = scene.x[40] + [1.0, 1.0 / np.sqrt(3)]       # the centroid of a triangle of neighbours (spacing 2, r = 1)
    assert s.pick([*gap, 50.0], [0.0, 0.0, -1.0]) is None
    assert s.open_cluster("p40") and s.kind == "contacts" and s.map is not None
    assert s.verdict == row["verdict"] == "unstable" and s.scene.n_particles == row["n_particles"]
    assert s.analysis.summary["consistent_negative"] == row["consistent_negative"]
    assert s.back_to_map() and s.kind == "scan_map" and s.map is None
    assert not s.open_cluster("nope") and "no centre" in s.error


def test_scan_map_shows_instability_by_the_packing_and_greys_the_cut_alone(tmp_path):
    """issue 25's default map: three disks in a line (their end disks carry the dead loads of cut contacts) and,
    apart, a sliding pair, scanned with boundary loads. Every chain particle is unstable only through `boundary`
    clusters (light grey, not the pink of its unstable_fraction 1/3 or 1/2); the sliding pair's clusters are
    `frictional` (dark red: all its clusters unstable by the packing)."""
    from test_attribution import chain, pair

    import granstab
    from granstab.model.scene import CONTACT_FIELDS
    from granstab.scan import read_map, scan
    from granstab_app.scanmap import CUT_GREY, RED
    line, slide = chain(3), pair([-0.01, 0.005], "sliding", -0.5, "sliding pair")
    shift = {"p": 3, "q": 3, "point": [0.0, 10.0]}                  # the pair 10 radii above the line
    arrays = {f: np.concatenate([getattr(line, f), getattr(slide, f) + shift.get(f, 0)])
              for f in CONTACT_FIELDS if f != "image"}          # no cell: no images
    arrays["state"] = tuple(line.state) + tuple(slide.state)
    scene = granstab.build_scene(2, [*line.names, *slide.names], np.r_[line.x, slide.x + [0.0, 10.0]], arrays)
    scan(scene, tmp_path / "scan", boundary="loads", workers=1, figures=False)
    rows = read_map(tmp_path / "scan")["clusters"]
    by_centre = dict(zip(rows["center"], zip(rows["verdict"], rows["mechanism"])))
    assert {by_centre[c] for c in (3, 4)} == {("unstable", "frictional")} and ("unstable", "boundary") in \
        {by_centre[c] for c in (0, 1, 2)} and {m for _, m in (by_centre[c] for c in (0, 1, 2))} <= {"boundary", ""}
    colours = Session(str(tmp_path / "scan")).map_colours
    assert [tuple(c) for c in colours] == [CUT_GREY] * 3 + [tuple(RED)] * 2


def test_a_concave_side_is_drawn_as_a_socket():
    """hand_in_glove: q's outline near the contact follows its concave circle of curvature (radius 1.002 about
    (-0.002, 0)) on both sides of the contact, as drawn (q's mesh); it was a plain convex disk (radius 2 about (3, 0))
    that touched p at one point. Tolerance 1e-12 r."""
    from granstab_app.views import SceneView
    s = Session("hand_in_glove")
    view = SceneView(RecordingScene())
    view.draw_particles(s)
    (V, _), _, _ = view.api.sent["/particles/q/body/mesh"]
    q = s.bodies()[1]
    ring = V[(V[:, 2] > 0) & (np.abs(V[:, :2]).max(axis=1) > 0), :2] + q.x   # the top outline (not the centre), world
    point, r = s.scene.point[0], 1.0
    near = ring[np.linalg.norm(ring - point, axis=1) < 0.5 * r]
    assert len(near) >= 10 and near[:, 1].min() < -0.3 * r and near[:, 1].max() > 0.3 * r
    assert np.abs(np.linalg.norm(near - [-0.002, 0.0], axis=1) - 1.002).max() < 1e-12 * r


def test_a_periodic_packing_is_drawn_with_its_cell_outline(tmp_path):
    """A periodic scene (a converted LAMMPS lattice in a sheared box) has a cell outline: 4 edges along ±a_1, ±a_2,
    every particle inside it; the view draws it once as /cell, again only when it changes, and removes it for a
    scene without a cell."""
    from test_io_periodic import lattice_dumps

    from granstab.io import load
    from granstab_app.scenes import cell_edges, periodic_images
    from granstab_app.views import SceneView
    paths, _, cell = lattice_dumps(tmp_path, gamma=0.1)
    scene = load(paths, columns="id1,id2,fx,fy,fz").scene
    edges = cell_edges(scene)
    assert edges.shape == (4, 2, 2)
    sides = np.sort(np.abs(edges[:, 1] - edges[:, 0]).round(12), axis=0)
    assert np.allclose(sides, np.sort(np.abs(np.r_[cell, cell]).round(12), axis=0), rtol=0, atol=1e-12)
    frac = (scene.x - edges[0, 0]) @ np.linalg.inv(scene.cell)     # edges[0, 0]: the corner at fractional (0, 0)
    assert np.all((frac > 0) & (frac < 1))                   # the lattice fills one period: inside the outline
    assert cell_edges(granstab_scene_without_cell()) is None
    calls = []
    api = SimpleNamespace(remove_by_name=lambda name: calls.append(("remove", name)),
                          add_line_segments=lambda name, points, *a, **k: calls.append(("add", name, points.shape)))
    api.add_point_cloud = lambda name, points, **k: calls.append(("add", name, points.shape)) or SimpleNamespace()
    view = SceneView(api)
    session = SimpleNamespace(scene=scene, on_map=False, size=1.0)
    view.draw_cell(session)
    view.draw_cell(session)                                  # unchanged: not re-sent
    ghosts = len(periodic_images(scene, 2.0)[0])
    assert ghosts > 0
    assert calls == [("remove", "/cell"), ("add", "/cell", (4, 2, 3)), ("add", "/cell/images", (ghosts, 3))]
    view.draw_cell(SimpleNamespace(scene=granstab_scene_without_cell(), on_map=False, size=1.0))
    assert calls[-1] == ("remove", "/cell")


def granstab_scene_without_cell():
    import granstab
    return granstab.load_scene(REPO / "presets" / "two_particle.toml")


def test_periodic_images_sit_across_the_faces_and_move_with_their_particles(tmp_path):
    """A jammed frictionless packing in a sheared cell (granstab.model.packings.jammed): the ghosts drawn beside the
    cell are the particles within `reach` of a face, shifted by n @ cell (n in {-1, 0, 1}², not 0). Checked against a
    brute force over every particle and every shift in the copy's frame (the copy lies outside the outline, within
    reach of it along every lattice direction it was shifted along, and inside the outline's slab along the others),
    and against the seam contacts: q's ghost across a seam contact is q's copy x^q + image @ cell. Played along a
    mode, every ghost moves by its particle's displacement (a periodic mode moves every copy alike)."""
    import granstab
    from granstab.model import packings
    from granstab_app.scenes import cell_edges, ghost_positions, periodic_images
    scene = packings.jammed(2, 64, shear=0.5, seed=3)
    reach = 1.0                                                  # the small disks' diameter
    index, shift = periodic_images(scene, reach)
    inv = np.linalg.inv(scene.cell)
    n = shift @ inv
    assert np.allclose(n, n.round(), rtol=0, atol=1e-12) and np.all(np.abs(n.round()).sum(axis=1) > 0)
    assert np.allclose(ghost_positions(scene.x, (index, shift)), scene.x[index] + n.round() @ scene.cell, atol=1e-12)
    corner = cell_edges(scene)[0, 0]                             # the outline's corner at fractional (0, 0)
    width = 1.0 / np.linalg.norm(inv, axis=0)                    # the distance between opposite faces
    expected = set()
    for i, x in enumerate(scene.x):
        for m in itertools.product((-1, 0, 1), repeat=2):
            if not any(m):
                continue
            f = (x + np.array(m) @ scene.cell - corner) @ inv    # the copy, in fractions of the outline
            out_by = np.where(np.array(m) > 0, f - 1, np.where(np.array(m) < 0, -f, 0.0)) * width
            if all((out_by[a] > 0 and out_by[a] < reach) if m[a] else 0 <= f[a] <= 1 for a in range(2)):
                expected.add((i, m))
    got = {(int(i), tuple(int(v) for v in m)) for i, m in zip(index, n.round())}
    assert got == expected and len(got) == len(index)           # complete and each ghost once
    seam = np.flatnonzero(np.any(scene.image != 0, axis=1))
    assert len(seam) > 0
    found = 0
    for c in seam:
        hit = [g for g in np.flatnonzero(index == scene.q[c]) if np.allclose(n[g], scene.image[c], atol=1e-12)]
        found += len(hit)
        for g in hit:                                            # q's ghost is where p touches q's copy
            assert np.allclose(scene.x[index[g]] + shift[g], scene.q_copy[c], rtol=0, atol=1e-12)
    assert found >= len(seam) // 2          # most seam partners lie within a diameter of the face they cross
    path = tmp_path / "jammed.json"
    granstab.io.scenes.save_scene(scene, path)
    session = Session(str(path))
    assert session.error is None and session.scene.cell is not None
    mode = next(m for m in session.modes() if m.label != "rigid")
    moved = session.mode_bodies(mode, 1.0, 0.7)
    at = {b.name: b.x for b in moved}
    x1 = np.array([at[name] for name in session.scene.names])
    images = periodic_images(session.scene, reach)
    step = ghost_positions(x1, images) - ghost_positions(session.scene.x, images)
    assert np.abs(x1 - session.scene.x).max() > 0.1 * session.size       # the mode moves the packing visibly
    # round-off of positions of size ~ the cell (a few units): 1e-12 absolute
    assert np.allclose(step, (x1 - session.scene.x)[images[0]], rtol=0, atol=1e-12)
    from granstab_app.views import SceneView  # the view plays the same: /cell/images follows
    clouds = {}
    api = SimpleNamespace(remove_by_name=lambda name: None, add_line_segments=lambda *a, **k: None,
                          add_point_cloud=lambda name, points, **k: clouds.setdefault(name, SimpleNamespace(points=points)))
    view = SceneView(api)
    view.draw_cell(SimpleNamespace(scene=session.scene, on_map=False, size=reach / 2))
    view.base = {b.name: b for b in session.bodies()}
    view.animate(moved)
    assert np.allclose(clouds["/cell/images"].points[:, :2], ghost_positions(x1, images), rtol=0, atol=1e-12)
    view.stop_animation()
    assert np.allclose(clouds["/cell/images"].points[:, :2], ghost_positions(session.scene.x, images), atol=1e-12)


def test_too_many_sliding_contacts_are_sampled_and_said(monkeypatch):
    """Issue 36: a whole packing with more contacts at the friction limit than can be enumerated (the 1,617-disk
    annulus: 2^85 cases) is analysed on the sampled path and the page says so, in one line with what to change.
    Here four_disk's 4 sliding contacts against a limit of 2: the all-loading, all-unloading and sampled branches."""
    from granstab_app import pools
    from granstab_app.state import Session
    monkeypatch.setattr(pools, "MAX_SLIDING", 2)
    s = Session("four_disk")
    assert s.error is None and s.verdict == "unstable" and s.analysis.summary["branches"] == "partial"
    assert "2^4 cases" in s.caveat and "sampled" in s.caveat and s.caveat.count("\n") == 0
    monkeypatch.setattr(pools, "MAX_SLIDING", 16)
    assert s.set_params(alpha=0.9) and s.caveat is None and s.analysis.summary["branches"] != "partial"


def test_a_played_mode_shows_its_rest_ghost_and_motion_arrows(pair):
    """Issue 36: while the pair's rolling mode plays, the rest position stays drawn (both outlines, grey) and an arrow
    goes from each particle's axis tip at rest to the tip at the mode's largest displacement: the pair turns in
    place, so arrows of the centres would be empty. At the default amplitude 0.35 the tips move 0.35 r (θ = 0.35)."""
    from types import SimpleNamespace

    from granstab_app.text import lowest_mode
    from granstab_app.views import SceneView
    calls = {}
    api = SimpleNamespace(remove_by_name=lambda name: calls.pop(name, None),
                          add_line_segments=lambda name, points, *a, **k: calls.setdefault(name, points),
                          add_arrows=lambda name, points, **k: calls.setdefault(name, points))
    m = lowest_mode(pair.modes())
    assert m.label == "rolling"
    SceneView(api).show_rest(pair.bodies(), pair.mode_bodies(m, 0.35, 0.5 * np.pi), pair.size)
    assert calls["/rest/outline"].shape == (2 * 64, 2, 3)
    arrows = calls["/rest/motion"]
    assert arrows.shape == (2, 2, 3)
    length = np.linalg.norm(arrows[:, 1] - arrows[:, 0], axis=1)
    assert np.allclose(length, 2 * np.sin(0.35 / 2) * pair.bodies()[0].axes[0], rtol=1e-9)   # a chord of angle 0.35


def test_the_attribution_comes_after_the_verdict(pair):
    """Issue 36's latency: the pair's analysis is made without its attribution (half its time), the page sends the
    verdict, then Session.attribute adds why it is unstable; the report (cached per revision) follows. A stable
    scene has none to add."""
    assert pair.verdict == "unstable" and pair.report()["attribution"] is None
    assert pair.attribute() and pair.report()["attribution"].startswith("mechanism: geometric")
    assert not pair.attribute()
    pair.set_params(rho_r=1.5)
    assert pair.verdict == "stable" and not pair.attribute() and pair.report()["attribution"] is None


def test_a_turned_ellipse_renames_its_contact():
    """Issue 36: the headline follows the geometry — ellipses_sharp (tips: ρ/r = 0.25) turned by 90° onto its flat
    sides says "flat sides touching (ρ/r = 4)" (ρ = a²/b = 2, r = b = 0.5), not "sharp tips"; and is stable."""
    s = Session("ellipses_sharp")
    assert "sharp tips" in s.scene.title and "ρ/r = 0.25" in s.scene.title and s.verdict == "unstable"
    s.move("left", [0.0, 0.0], np.pi / 2)
    s.move("right", [0.99, 0.0], np.pi / 2)
    assert s.error is None and s.scene.n_contacts == 1
    assert "flat sides touching (ρ/r = 4)" in s.scene.title and "sharp" not in s.scene.title
    assert s.verdict == "stable"


def test_the_whole_annulus_is_analysed_on_a_few_sampled_branches():
    """Issue 36: *Analyse the whole packing* on RigidLibrary's 1,617-disk annulus (85 contacts at the friction limit:
    2^85 cases; 4,851 dofs, the sparse path) answers: the all-sliding, all-sticking and pools.SAMPLED_LARGE = 2
    random branches, each one eigensolve (34 of them took minutes, and the page never answered), with the caveat in
    one line saying what to change."""
    from granstab_app import pools
    root = ROOT.parent / "shared" / "data" / "rigidlibrary" / "DataAnnulus" / "10"
    folder = root if root.is_dir() else Path("/work/shared/data/rigidlibrary/DataAnnulus/10")
    assert folder.is_dir(), f"the photoelastic annulus data are needed: {folder}"
    s = Session()
    assert s.open_typed(str(folder)) and s.error is None and s.deferred and s.scene.n_particles == 1617
    s.analyse()
    assert s.error is None and s.analysis is not None and not s.deferred
    assert s.analysis.summary["branches"] == "partial" and len(s.analysis.branches) == 2 + pools.SAMPLED_LARGE
    assert "2^85 cases" in s.caveat and f"{pools.SAMPLED_LARGE} random cases" in s.caveat
    assert "larger μ" in s.caveat and s.caveat.count("\n") == 0


def test_on_a_phone_the_pair_is_fitted_above_the_panel(pair):
    """Issue 36: on a 390×844 canvas viser's panel covers all below y ≈ 337 px (40 %), and the pair, fitted to the
    whole canvas and centred, lay under it. Top-down, each body's drawn reach (1.2 × its size, camera_pose) now
    projects (pinhole, the camera's vertical field of view) inside the canvas's top PHONE_BAND; a 1400×900 page's
    canvas between both docked columns (570×900: portrait too, and it was taken for a phone) keeps the centred pose."""
    from granstab_app.camera import PHONE_BAND, above_sheet, camera_pose, fit_distance
    camera = SimpleNamespace(fov=np.radians(75.0), image_width=390, image_height=844)
    pose = above_sheet(camera_pose(pair, False, False, lambda w, h: fit_distance(w, h, camera)), camera)
    position, target = np.array(pose["position"]), np.array(pose["look_at"])
    assert np.allclose(position[:2], target[:2]) and pose["up_direction"] == (0.0, 1.0, 0.0)
    px = camera.image_height / (2 * position[2] * np.tan(0.5 * camera.fov))      # px per unit on the plane z = 0
    for b in pair.bodies():
        reach = 1.2 * max(b.axes)
        top = 0.5 * camera.image_height - (b.x[1] + reach - position[1]) * px
        bottom = 0.5 * camera.image_height - (b.x[1] - reach - position[1]) * px
        side = 0.5 * camera.image_width + (np.array([-reach, reach]) + b.x[0] - position[0]) * px
        assert 0 <= top and bottom <= PHONE_BAND * camera.image_height and 0 <= side[0] and side[1] <= 390
    for width in (1400, 570):
        wide = SimpleNamespace(fov=np.radians(75.0), image_width=width, image_height=900)
        centred = camera_pose(pair, False, False, lambda w, h, c=wide: fit_distance(w, h, c))
        assert above_sheet(centred, wide) == centred
