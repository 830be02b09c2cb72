"""LAMMPS rounded polygons (Debian's lammps 29Sep2021, atom_style body rounded/polygon): examples/lammps_body makes
64 squares, pentagons and hexagons compressed in a periodic box (~10 s; marked `dem`, needs `lmp`: without it the
test fails, it does not skip); tests/data/io/lammps_polygons is that run's output, read without the engine.

LAMMPS dumps no contact of these bodies. The check is independent of the reader: a plain-loop transcription of
pair body/rounded/polygon (29Sep2021, as LAMMPS's src/BODY/pair_body_rounded_polygon.cpp computes it: each vertex
against each side, vertex–side contacts applied one or two per body pair, vertex–vertex pushes once per side that
reports them, and a side touched by two vertices pushed back twice with the last one's force) reproduces LAMMPS's
dumped per-body forces and torques to round-off (at rest: no damping); its applied contacts are then the reader's,
one by one: point, force, arm from the centre of mass and the curvature of the vertex's parallel curve."""
import json
import shutil
import subprocess

import numpy as np
import pytest
from helpers import DATA, ROOT  # noqa: E402

import granstab
from granstab.cli import main
from granstab.model.errors import SceneError

EXAMPLE = ROOT / "examples" / "lammps_body"
FIXTURE = DATA / "io" / "lammps_polygons"
DATA, SCRIPT = EXAMPLE / "data.polygons", EXAMPLE / "in.polygons2d"
R, KN, EPS, CUT = 0.2, 1000.0, 1e-3, 0.1          # the example's rounding radius, k_n, LAMMPS's EPSILON, cut_inner


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    if shutil.which("lmp") is None:
        pytest.fail("lmp: executable not found (apt-get install -y lammps, as .ci/run does)", pytrace=False)
    out = tmp_path_factory.mktemp("polygons")
    done = subprocess.run(["bash", str(EXAMPLE / "run.sh"), str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return out


def rows(path):
    return np.loadtxt(path.read_text().split("\n")[9:], ndmin=2)


def lammps_model(folder):
    """The transcription (module docstring): per-body force and torque, and the applied contacts as (vertex body,
    other body, vertex position, force on the vertex's body, kind)."""
    A, V = rows(folder / "atoms.dump"), rows(folder / "vertices.dump")
    box = float((folder / "atoms.dump").read_text().split("\n")[5].split()[1])
    ids = A[:, 0].astype(int)
    X = {i: A[k, 3:5] for k, i in enumerate(ids)}
    verts = {i: V[V[:, 0] == i, 1:3] for i in ids}
    F, T, applied = {i: np.zeros(2) for i in ids}, {i: 0.0 for i in ids}, []

    def torque(arm, f):
        return arm[0] * f[1] - arm[1] * f[0]

    def vertices_on_sides(i, j, shift, found, stored):
        other = verts[j] + shift
        for xp in verts[i]:
            for nj in range(len(other)):
                a, b = other[nj], other[(nj + 1) % len(other)]
                t = (xp - a) @ (b - a) / ((b - a) @ (b - a))
                h = a + t * (b - a)
                d = np.linalg.norm(xp - h)
                if d > 2 * R + CUT:
                    continue
                if 0 <= t <= 1:
                    if d < 2 * R + EPS:
                        f = (xp - h) * max(2 * R - d, 0.0) * KN / d
                        found.append((i, j, xp, h, f, nj))
                        stored[(i, j, nj)] = f
                    continue
                w = a if t < 0 else b
                dvw = np.linalg.norm(xp - w)
                if dvw <= 2 * R + CUT and i < j and dvw < 2 * R:
                    f = (xp - w) * (2 * R - dvw) * KN / dvw
                    F[i] += f
                    F[j] -= f
                    T[i] += torque(xp - X[i], f)
                    T[j] += torque(w - X[j] - shift, -f)
                    applied.append((i, j, xp, f, "vertex"))

    def apply(c, stored, ja):
        i, j, xv, xe, f, nj = c
        F[i] += f * ja
        T[i] += torque(xv - X[i], f * ja)
        back = -stored[(i, j, nj)] * ja            # the side's stored force: the last vertex's on that side
        shift = -np.round((X[j] - X[i]) / box) * box
        F[j] += back
        T[j] += torque(xe - X[j] - shift, back)
        if f @ f > 0:
            applied.append((i, j, xv, f * ja, "side"))

    for a in ids:
        for b in ids[ids > a]:
            shift = -np.round((X[b] - X[a]) / box) * box
            if np.linalg.norm(X[b] + shift - X[a]) > 2 * (1.0 + R) + CUT:     # circumradius 1: out of reach
                continue
            found, stored = [], {}
            vertices_on_sides(a, b, shift, found, stored)
            vertices_on_sides(b, a, -shift, found, stored)
            if len(found) == 1:
                apply(found[0], stored, 1.0)
            elif len(found) >= 2:                  # the first two at different places (j_a = 1: delta_ua = 1000)
                apply(found[0], stored, 1.0)
                apply(found[1], stored, 1.0)
    return ids, A, np.array([F[i] for i in ids]), np.array([T[i] for i in ids]), applied


def check_polygons(folder, tmp_path, capsys):
    ids, A, F, T, applied = lammps_model(folder)
    scale = np.abs(A[:, 9:11]).max()
    assert np.abs(F - A[:, 9:11]).max() <= 1e-9 * scale                  # the transcription is LAMMPS's model
    assert np.abs(T - A[:, 11]).max() <= 1e-9 * scale * 2
    out = tmp_path / "polygons.json"
    files = [str(folder / "atoms.dump"), str(folder / "vertices.dump"), str(DATA), str(SCRIPT)]
    rc = main(["convert", *files, "--out", str(out), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["format"] == "lammps_polygons" and report["periodic"]["periodic"]
    scene = granstab.load_scene(out)
    merged = {}                                                          # a vertex pair pushed twice: one contact
    for i, j, xv, f, kind in applied:
        key = (i, j, tuple(np.round(xv, 9)), kind)
        force, times = merged.get(key, (np.zeros(2), 0))
        merged[key] = (force + f, times + 1)
    assert scene.dim == 2 and scene.n_contacts == len(merged)            # every contact LAMMPS applies, once
    index = {n: k for k, n in enumerate(scene.names)}
    for (i, j, xv, kind), (f, times) in merged.items():                  # each the reader's: point, force, curvature
        p, q = index[str(i)], index[str(j)]
        n = -f / np.linalg.norm(f)
        delta = np.linalg.norm(f) / (KN * times)
        point = np.array(xv) + (R - delta / 2) * n
        match = np.flatnonzero((scene.p == p) & (scene.q == q) & (np.linalg.norm(scene.point - point, axis=1) < 1e-6))
        assert len(match) == 1, (i, j, kind)
        k = match[0]
        # δ = 2r − d is a difference of lengths ~100 times δ: forces agree to round-off of the lengths, 1e-10 of
        # the largest contact force (measured ~1e-12)
        assert np.abs(scene.force[k] - f).max() <= 1e-10 * np.abs(scene.force).max()
        assert np.abs(scene.r_pq[k] - (scene.point[k] - scene.x[p])).max() <= 1e-12     # arm from the centre of mass
        t = np.array([-n[1], n[0]])
        rho = R - delta / 2
        assert np.abs(scene.curvature_p[k] + np.outer(t, t) / rho).max() <= 1e-9 / rho      # the vertex's disk
        expected_q = 0.0 if kind == "side" else -1 / rho                                        # flat side: 0
        assert np.abs(scene.curvature_q[k] - expected_q * np.outer(t, t)).max() <= 1e-9 / rho
    model = report["lammps_contact_model"]
    assert model["vertex_side"] + model["vertex_vertex"] == scene.n_contacts
    assert report["bodies"]["conforming_contacts"] == 0 and report["bodies"]["flat_sides_in_contact"] > 100
    for argv in (["analyze", str(out), "--method", "sparse", "--k", "3"], ["scan", str(out), "--out", str(tmp_path / "scan")],
                 ["rigidity", str(out), "--out", str(tmp_path / "rigid")],
                 ["export", str(out), "--scan-dir", str(tmp_path / "scan"), "--out", str(tmp_path / "vtp")]):
        assert main(argv) == 0, argv
        capsys.readouterr()
    assert json.loads((tmp_path / "scan" / "summary.json").read_text())["clusters"] == 64
    return report


@pytest.mark.dem
def test_lammps_polygon_packing_converts_with_the_engines_forces(run, tmp_path, capsys):
    check_polygons(run, tmp_path, capsys)


def test_lammps_polygon_fixture_converts_with_the_engines_forces(tmp_path, capsys):
    check_polygons(FIXTURE, tmp_path, capsys)


# ------------------------------------------------------------------------------------------------ refusals

def test_a_polygon_without_rounding_is_refused(tmp_path):
    text = DATA.read_text().splitlines()
    first = text.index("Bodies") + 2                     # the first body's header line
    n = int(text[first + 1])
    text[first + 3 + n] = "0"                            # its rounding diameter
    (tmp_path / "data.polygons").write_text("\n".join(text) + "\n")
    with pytest.raises(SceneError) as err:
        granstab.io.load([FIXTURE / "atoms.dump", FIXTURE / "vertices.dump", tmp_path / "data.polygons", SCRIPT])
    assert str(err.value) == (f"{tmp_path / 'data.polygons'}: line {first + 1}: body 1: diameter: rounding diameter "
                              "0: a polygon without rounding has no curvature at a sharp vertex or edge")


@pytest.mark.parametrize("style, what", [("tri", "triangles (a mesh)"),
                                         ("body nparticle 1 6", "rigid bodies of point sub-particles"),
                                         ("body rounded/polyhedron 1 8", "3D rounded polyhedra: not read yet")])
def test_shapes_without_curvature_are_refused_in_one_line(tmp_path, style, what):
    """Meshes and point bodies have no curvature at a sharp vertex or edge; rounded polyhedra have one (1/r on edges
    and vertices) but LAMMPS dumps none of their contacts: the line says so, not that a curvature is missing."""
    script = tmp_path / "in.script"
    script.write_text(f"atom_style {style}\n")
    dumps = FIXTURE.parent / "lammps"              # tests/data/io/lammps (DATA here names the example data file)
    with pytest.raises(SceneError) as err:
        granstab.io.load(sorted(dumps.glob("*.dump")) + [script])
    message = str(err.value)
    assert message.startswith(f"{script}: line 1: atom_style: {style}: {what}") and "\n" not in message
    rounded = "polyhedron" in style
    assert ("no curvature at a sharp vertex or edge" in message) != rounded
    assert ("no single(), so no pair/local" in message) == rounded


def test_cohesion_is_refused(tmp_path):
    script = tmp_path / "in.polygons2d"
    script.write_text(SCRIPT.read_text().replace("pair_coeff   * * 1000.0 0.0", "pair_coeff   * * 1000.0 2.0"))
    with pytest.raises(SceneError, match=r"k_na: 2: cohesion is not converted"):
        granstab.io.load([FIXTURE / "atoms.dump", FIXTURE / "vertices.dump", DATA, script])
