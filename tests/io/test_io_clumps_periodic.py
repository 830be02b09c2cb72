"""Clumps in periodic cells (issue 37): YADE in a fully periodic cell (examples/yade/make_periodic_clumps.py: 27
dimers and bent trimers compressed to 10 kPa by the cell, without gravity, ~20 s) and LIGGGHTS multisphere periodic
along x and y on a floor (examples/liggghts_multisphere/in.periodic, 100 dimers under gravity, ~15 s). The engine
runs are marked `yade` / `liggghts` (they fail without the executables, they do not skip);
tests/data/io/yade_clumps_periodic and tests/data/io/liggghts_multisphere_periodic are their output.

Checked from the raw files with numpy alone: every member contact kept (the fully periodic cell keeps them all with
q's image; the cell open along z cuts those closing a loop around the cell, as for spheres, their forces becoming
loads); each contact's normal between the member centres (minimum image), its arm from the clump's centre of mass
to the point midway in the members' overlap (minimum image: the engines wrap members and centres of mass into the
cell separately, or not at all), its branch vector to the image of q's clump that the contact touches; each clump's
balance; the stress of `granstab moduli` equal to the virial of the dumped forces; analyze, scan, moduli, rigidity
and export exit 0 (on the fixtures; the engine runs check the conversion only, to keep CI short)."""
import json
import re

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402
from test_io_clumps import _engine, check_commands, dump_rows

import granstab
from granstab.cli import main

DATA = DATA / "io"
EXAMPLES = ROOT / "examples"
PERIODIC = EXAMPLES / "liggghts_multisphere" / "in.periodic"


@pytest.fixture(scope="module")
def yade_run(tmp_path_factory):
    return _engine("yade", ["yade", "-n", "-x", str(EXAMPLES / "yade" / "make_periodic_clumps.py")],
                   tmp_path_factory)


@pytest.fixture(scope="module")
def liggghts_run(tmp_path_factory):
    run = EXAMPLES / "liggghts_multisphere" / "run.sh"          # run.sh DIR in.periodic (_engine appends DIR: $0)
    return _engine("liggghts", ["bash", "-c", f'exec bash "{run}" "$0" in.periodic'], tmp_path_factory)


def image(d, periods):
    """The minimum image of separations d (M, 3) in an orthogonal cell of sides `periods` (inf: an open axis)."""
    finite = np.isfinite(periods)
    shift = np.zeros_like(d)
    shift[:, finite] = periods[finite] * np.round(d[:, finite] / periods[finite])
    return d - shift


def raw_contacts(members, bodies, pairs, periods):
    """Per member contact from the raw tables: clump rows of both sides, normal, ρ of both members, the point midway
    in the overlap, the arms from both centres of mass (each the minimum image) and the branch p → q's copy."""
    row = {i: k for k, i in enumerate(members["id"])}
    brow = {i: k for k, i in enumerate(bodies["id"])}
    a = np.array([row[i] for i in pairs["id1"]])
    b = np.array([row[i] for i in pairs["id2"]])
    bp = np.array([brow[i] for i in members["body"][a]])
    bq = np.array([brow[i] for i in members["body"][b]])
    gap = image(members["x"][b] - members["x"][a], periods)
    d = np.linalg.norm(gap, axis=1)
    n = gap / d[:, None]
    Ra, Rb = members["radius"][a], members["radius"][b]
    delta = Ra + Rb - d
    rho_p, rho_q = Ra - delta / 2, Rb - delta / 2
    point = members["x"][a] + rho_p[:, None] * n
    arm_p = image(point - bodies["x"][bp], periods)
    arm_q = image(point - bodies["x"][bq], periods)
    return {"p": bodies["id"][bp], "q": bodies["id"][bq], "normal": n, "rho_p": rho_p, "rho_q": rho_q,
            "arm_p": arm_p, "branch": arm_p - arm_q, "force": pairs["force"]}


def check_periodic(loaded, raw, seam_least):
    """The scene's contacts against the raw ones (module docstring): returns the raw rows the scene kept."""
    scene, report = loaded.scene, loaded.report
    names = np.array(scene.names)
    kept = []
    for c in range(scene.n_contacts):     # each scene contact is one raw row: its clumps and its normal
        rows = np.flatnonzero((raw["p"].astype(str) == names[scene.p[c]]) & (raw["q"].astype(str) == names[scene.q[c]]))
        kept.append(rows[np.argmin(np.linalg.norm(raw["normal"][rows] - scene.normal[c], axis=1))])
    kept = np.array(kept)
    assert len(np.unique(kept)) == len(kept)
    cut = report["periodic"]["contacts_cut"]
    assert len(kept) + cut == len(raw["p"]) == report["contacts"]["in_file"]     # every contact: kept, or cut
    assert report["periodic"]["seam_contacts"] >= seam_least
    scale = raw["rho_p"].max()
    assert np.abs(scene.normal - raw["normal"][kept]).max() <= 1e-12
    assert np.abs(scene.r_pq - raw["arm_p"][kept]).max() <= 1e-12 * scale            # arm from the centre of mass
    assert np.abs(scene.branch - raw["branch"][kept]).max() <= 1e-12 * scale         # to q's copy it touches
    tangent = np.eye(3)[None] - scene.normal[:, :, None] * scene.normal[:, None, :]
    for K, rho in ((scene.curvature_p, raw["rho_p"][kept]), (scene.curvature_q, raw["rho_q"][kept])):
        assert np.abs(K + tangent / rho[:, None, None]).max() <= 1e-12 / rho.min()
    # the arms matter: a clump's centre of mass is not its member's centre (an arm along the normal would be wrong)
    assert np.median(np.linalg.norm(np.cross(raw["arm_p"][kept], scene.normal), axis=1) / raw["rho_p"][kept]) > 0.3
    return kept


# ------------------------------------------------------------------------------------------------ YADE

def yade_tables(folder):
    """(bodies, members, member contacts, cell) from the tables with numpy alone."""
    text = (folder / "bodies.csv").read_text().splitlines()
    comments = [t for t in text if t.startswith("#")]
    cell = np.array([float(v) for v in next(t for t in comments if "cell:" in t).split(":")[1].split()]).reshape(3, 3)
    B = np.genfromtxt(folder / "bodies.csv", delimiter=",", names=True, skip_header=len(comments))
    M = np.genfromtxt(folder / "members.csv", delimiter=",", names=True)
    C = np.genfromtxt(folder / "contacts.csv", delimiter=",", names=True)
    assert np.all(C["id2"] >= 0)                                  # no walls in the periodic cell
    bodies = {"id": B["body"].astype(int), "x": np.column_stack([B["x"], B["y"], B["z"]]), "mass": B["mass"]}
    members = {"id": M["id"].astype(int), "body": M["body"].astype(int),
               "x": np.column_stack([M["x"], M["y"], M["z"]]), "radius": M["radius"]}
    pairs = {"id1": C["id1"].astype(int), "id2": C["id2"].astype(int),
             "force": np.column_stack([C["fx"], C["fy"], C["fz"]]),
             "point": np.column_stack([C["cx"], C["cy"], C["cz"]])}
    return bodies, members, pairs, cell


def check_yade(folder, tmp_path, capsys, commands=True):
    bodies, members, pairs, cell = yade_tables(folder)
    assert np.count_nonzero(cell - np.diag(np.diag(cell))) == 0   # PeriTriaxController keeps the cell orthogonal
    periods = np.diag(cell)
    loaded = granstab.io.load(folder)
    scene, report = loaded.scene, loaded.report
    assert scene.periodic and np.array_equal(scene.cell, cell)
    raw = raw_contacts(members, bodies, pairs, periods)
    kept = check_periodic(loaded, raw, seam_least=10)
    assert np.array_equal(kept, np.arange(len(kept))) and report["periodic"]["contacts_cut"] == 0   # all, in order
    # ScGeom's contactPoint is the midpoint of the overlap, in the first member's image (1e-12 of a radius)
    assert report["geometry"]["engine_point_offset_over_radius"]["max"] <= 1e-12
    # at rest (YADE's unbalanced force < 1e-6; one step with the integrator off): each clump's residual, of its
    # summed |f| and |r||f|, measured ≤ 1.6e-7 over four runs (the fixture: 5e-11); an arm through a wrong image
    # or from a member's centre gives O(1)
    imb = report["imbalance"]
    assert imb["particles"] == len(np.unique(np.concatenate([raw["p"], raw["q"]]))) >= 20       # rattlers aside
    assert imb["force"]["max"] <= 1e-5 and imb["moment"]["max"] <= 1e-5
    # the stress: the virial (1/V) Σ f ⊗ b of the file's forces with b = arm_p − arm_q through YADE's own contact
    # point (each arm the minimum image from a centre of mass); the reader builds b from the members instead.
    # Round-off (1e-10 of |σ| allowed) plus what the reader's cone projection moves: each force by at most the
    # report's largest change × |f| (sliding contacts put exactly on the cone), so σ by ≤ that × Σ|f||b| / V
    brow = {i: k for k, i in enumerate(bodies["id"])}
    mrow = {i: k for k, i in enumerate(members["id"])}
    xp = bodies["x"][[brow[members["body"][mrow[i]]] for i in pairs["id1"]]]
    xq = bodies["x"][[brow[members["body"][mrow[i]]] for i in pairs["id2"]]]
    b = image(pairs["point"] - xp, periods) - image(pairs["point"] - xq, periods)
    sigma = np.einsum("ci,cj->ij", pairs["force"], b) / np.prod(periods)
    m = granstab.moduli(scene)
    moved = report["cone"]["largest_change_over_force"] * np.sum(np.linalg.norm(pairs["force"], axis=1)
                                                                 * np.linalg.norm(b, axis=1)) / np.prod(periods)
    assert np.abs(m.stress - sigma).max() <= 1e-10 * np.abs(sigma).max() + moved
    assert np.all(np.diag(sigma) < 0) and abs(np.trace(sigma) / 3 + 1e4) <= 500     # ~10 kPa, compressive
    assert m.bulk > 0 and m.errors["residual"] <= 1e-12 and m.zero_modes["translations"] == 3
    out = tmp_path / "clumps.json"
    assert main(["convert", str(folder), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["moduli", str(out), "--json"]) == 0
    moduli = json.loads(capsys.readouterr().out)
    assert abs(moduli["bulk"] - m.bulk) <= 1e-9 * m.bulk
    if commands:                  # analyze, scan, rigidity, export: on the fixture (the engine run's are the same)
        check_commands(out, tmp_path, capsys)


@pytest.mark.yade
def test_yade_periodic_clump_packing_converts_and_balances(yade_run, tmp_path, capsys):
    check_yade(yade_run, tmp_path, capsys, commands=False)


def test_yade_periodic_clump_fixture_converts_and_balances(tmp_path, capsys):
    check_yade(DATA / "yade_clumps_periodic", tmp_path, capsys)


# ------------------------------------------------------------------------------------------------ LIGGGHTS

def check_liggghts(folder, tmp_path, capsys, commands=True):
    files = [folder / f"{n}.dump" for n in ("atoms", "contacts", "walls", "bodies")]
    A, C, B = (dump_rows(f) for f in (files[0], files[1], files[3]))
    bodies = {"id": B[:, 0].astype(int), "x": B[:, 1:4]}
    members = {"id": A[:, 0].astype(int), "body": A[:, 1].astype(int), "x": A[:, 3:6], "radius": A[:, 6]}
    pairs = {"id1": C[:, 0].astype(int), "id2": C[:, 1].astype(int), "force": C[:, 3:6]}
    periods = np.array([0.06, 0.06, np.inf])                     # in.periodic: boundary p p f, 60 x 60 mm
    loaded = granstab.io.load(files + [PERIODIC])
    scene, report = loaded.scene, loaded.report
    # open along z: not a periodic scene; unwrapped along the contacts, those closing a loop around the cell cut
    assert not scene.periodic and report["periodic"]["lattice"][:2] == [[0.06, 0, 0], [0, 0.06, 0]]
    raw = raw_contacts(members, bodies, pairs, periods)
    check_periodic(loaded, raw, seam_least=30)
    assert 0 < report["periodic"]["contacts_cut"] < report["periodic"]["seam_contacts"]
    # LIGGGHTS wraps members and centres of mass separately: clumps straddle the faces
    off = members["x"] - bodies["x"][np.searchsorted(bodies["id"], members["body"])]
    assert np.sum(np.abs(off[:, :2]).max(axis=1) > 0.03) >= 5
    # quasi-static under gravity (kinetic energy ~4e-8 J): each clump balances to a few per cent of its summed |f|,
    # cut contacts counted (measured: force median 8e-3, max 0.043; moment median 6e-3, max 0.044); an arm through
    # the wrong image is O(1)
    imb = report["imbalance"]
    assert imb["particles"] == 100
    assert imb["force"]["median"] <= 0.02 and imb["force"]["max"] <= 0.1
    assert imb["moment"]["median"] <= 0.02 and imb["moment"]["max"] <= 0.1
    assert report["geometry"]["engine_point_offset_over_radius"]["max"] <= 1e-3       # contactPoint, any image
    out = tmp_path / "clumps.json"
    assert main(["convert", *map(str, files), str(PERIODIC), "--out", str(out)]) == 0
    if commands:        # 6 sliding contacts: 64 branches would take a minute; two sampled branches, one metric
        check_commands(out, tmp_path, capsys, analyze=("--metric", "L", "--max-sliding", "0", "--sample-branches", "2"))


@pytest.mark.liggghts
def test_liggghts_periodic_multisphere_packing_converts_and_balances(liggghts_run, tmp_path, capsys):
    check_liggghts(liggghts_run, tmp_path, capsys, commands=False)


def test_liggghts_periodic_multisphere_fixture_converts_and_balances(tmp_path, capsys):
    check_liggghts(DATA / "liggghts_multisphere_periodic", tmp_path, capsys)


def test_a_member_half_a_cell_from_its_centre_of_mass_is_refused(tmp_path):
    """In a cell too small for the clumps (0.06 for members 0.035-0.054 from their centre of mass) the minimum
    images of the members cannot be the clump's: a member found at half the cell's width or more is refused in one
    line naming the member table's line (nearer ones cannot be told from their images: docs/formats.md)."""
    folder = DATA / "yade_clumps_periodic"
    for name in ("members.csv", "contacts.csv"):
        (tmp_path / name).write_text((folder / name).read_text())
    lines = (folder / "bodies.csv").read_text().splitlines()
    lines = [("# cell: 0.06 0 0 0 0.06 0 0 0 0.06" if t.startswith("# cell:") else t) for t in lines]
    (tmp_path / "bodies.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(granstab.SceneError) as err:
        granstab.io.load(tmp_path)
    message = str(err.value)
    assert re.fullmatch(rf"{re.escape(str(tmp_path / 'members.csv'))}: line \d+: member \d+: x: 0\.0[3-5]\d* from its "
                        r"clump's centre of mass, not less than half the periodic cell's width \(0\.03\): which image "
                        r"belongs to the clump is ambiguous", message), message
