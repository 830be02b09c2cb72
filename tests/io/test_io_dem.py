"""The shipped DEM run (examples/dem, Debian's LAMMPS): compress, shear, dump; then convert and analyse its
output. Needs the `lmp` executable (.ci/run installs it); marked `dem`."""
import json
import subprocess

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402
from io_checks import check_contact_geometry

import granstab
from granstab.cli import main
from granstab.io import load

DEM = ROOT / "examples" / "dem"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("dem")
    subprocess.run(["bash", str(DEM / "run.sh"), str(out)], check=True, timeout=300)
    return out


def radii(run, dim, step, names, tag=""):
    text = (run / f"atoms{dim}d{tag}.dump").read_text().split(f"ITEM: TIMESTEP\n{step}\n")[1].split("ITEM: TIMESTEP")[0]
    atoms = np.loadtxt(text.split("\n", 7)[7].splitlines())
    radius_of = dict(zip(atoms[:, 0].astype(int), atoms[:, 5]))
    return np.array([radius_of[int(n)] for n in names])


@pytest.mark.dem
def test_sheared_disks_convert_with_sliding_contacts(run, tmp_path, capsys):
    out = tmp_path / "disks.json"
    rc = main(["convert", str(run / "atoms2d.dump"), str(run / "contacts2d.dump"), str(DEM / "in.disks2d"),
               "--timestep", "18000", "--out", str(out), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["dimension"] == 2 and report["particles"]["in_file"] == 1000
    assert report["cone"]["at_yield"] >= 10                    # the shear mobilised contacts
    assert report["non_touching_pairs"]["with_force"] == 0    # pair/local's extra neighbour pairs carry no force
    assert report["imbalance"]["moment"]["median"] < 1e-3     # tangential forces on the right particle
    scene = granstab.load_scene(out)
    check_contact_geometry(scene, radii(run, 2, 18000, scene.names))
    assert scene.state.count("sliding") >= 10


@pytest.mark.dem
def test_settled_disks_cluster_dense_and_spheres_sparse(run):
    imp = load([run / "atoms2d.dump", run / "contacts2d.dump", DEM / "in.disks2d"], region="box:10,22,10,22")
    s = imp.scene
    assert imp.report["frame"] == 21000 and 40 <= s.n_particles <= 120
    result = granstab.analyze(s, method="dense", max_sliding=4)
    assert max(result.errors.values()) <= 1e-10
    assert result.branches[0].n_zero >= 3                      # two translations and a rotation at least
    # the dump's mass column (LAMMPS `set density 1.0` gives spheres 4/3 π R³ even in 2D; dumped to 6 digits)
    R = radii(run, 2, 21000, s.names)
    assert np.allclose(s.mass, 4 / 3 * np.pi * R**3, rtol=1e-5) and np.allclose(s.inertia[:, 0, 0], 0.5 * s.mass * R**2)
    inertial = granstab.analyze(s, method="dense", max_sliding=4, metric="inertia")
    assert max(inertial.errors.values()) <= 1e-10 and inertial.branches[0].n_zero >= 3
    s3 = load([run / "atoms3d.dump", run / "contacts3d.dump", DEM / "in.spheres3d"], periodic=False).scene  # the cut
    assert s3.dim == 3 and s3.n_particles > 900
    check_contact_geometry(s3, radii(run, 3, 14000, s3.names))
    r3 = granstab.analyze(s3, method="sparse", k=4, max_sliding=4)
    assert any(w.startswith("sparse path") for w in r3.to_dict()["warnings"])
    assert max(r3.errors.values()) <= 1e-10


@pytest.mark.dem
def test_rolling_resistance_closes_the_moment_balance(run):
    """in.spheres3d_rolling (pair granular `rolling sds`): the rolling resistance force of each contact (pair/local
    p5 p6 p7) becomes its contact moment; with it the settled packing's moment imbalance is as small as its force
    imbalance, without it (the same dump, those columns ignored) it is not."""
    files = [run / "atoms3d_rolling.dump", run / "contacts3d_rolling.dump"]
    rolled = load(files + [DEM / "in.spheres3d_rolling"], timestep=14000)
    plain = load(files, timestep=14000, columns="id1,id2,fnx,fny,fnz,ftx,fty,ftz,delx,dely,delz,-,-,-",
                 k=1000, alpha=0.5, mu=0.5)
    with_m, without = rolled.report["imbalance"], plain.report["imbalance"]
    assert with_m["force"]["median"] < 1e-6 and with_m["moment"]["median"] < 1e-6
    assert without["moment"]["median"] > 1e-3 and without["moment"]["median"] > 1e4 * with_m["moment"]["median"]
    s = rolled.scene
    assert s.has_moments and not plain.scene.has_moments
    check_contact_geometry(s, radii(run, "3", 14000, s.names, "_rolling"))
    cluster = load(files + [DEM / "in.spheres3d_rolling"], timestep=14000, region="box:4,8,4,8,4,8").scene
    assert cluster.n_particles >= 20 and cluster.has_moments
    r = granstab.analyze(cluster, method="dense", max_sliding=8)
    assert max(r.errors.values()) <= 1e-10
