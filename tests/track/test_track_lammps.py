"""The shipped quasi-static shear run for `granstab track` (examples/track/in.shear2d_track, Debian's LAMMPS, a few
seconds): on every dumped frame the stress from the contacts, σ = (1/V) Σ f ⊗ b (granstab.mechanics.cell, tension
positive), equals LAMMPS's own pressure tensor from the pair virial (compression positive); the run is quasi-static
(inertial number stated) and shows several stress drops. Marked `dem` like the other LAMMPS runs."""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

from granstab.io import load
from granstab.mechanics.cell import stress

TRACK = ROOT / "examples" / "track"
SCRIPT = TRACK / "in.shear2d_track"
RATE, DT = 0.003, 0.004          # the script's defaults: engineering shear rate, timestep


@pytest.fixture(scope="module")
def sheared(tmp_path_factory):
    out = tmp_path_factory.mktemp("track2d")
    subprocess.run(["lmp", "-in", str(SCRIPT), "-log", "none", "-screen", "none"], cwd=out, check=True, timeout=120)
    return out


def frame_rows(path: Path, step: int) -> tuple[np.ndarray, list[str]]:
    """The rows of one timestep of a dump and its header lines, read independently of granstab (plain split)."""
    block = path.read_text().split(f"ITEM: TIMESTEP\n{step}\n")[1].split("ITEM: TIMESTEP")[0]
    head, body = block.split("\n", 7)[:7], block.split("\n", 7)[7]
    return np.loadtxt(body.splitlines(), ndmin=2), head


@pytest.mark.dem
def test_contact_stress_equals_lammps_pressure_on_every_frame(sheared):
    """LAMMPS: P_ij = (1/A) Σ_pairs del_i f_j with del = x_1 − x_2, f the force on atom 1, A = xprd·yprd in 2D (the
    box's area; the z thickness does not enter), xy stored as Σ delx·fy. granstab: σ_ij = (1/V) Σ f_i b_j with
    b = x_2 − x_1 and V = det(cell) = xprd·yprd. So σ_xx = −P_xx, σ_yy = −P_yy and σ_yx = −P_xy; the first check
    reads the dump's own rows (the convention, to round-off), the second the scene granstab builds from the dumps.
    Tolerance 1e-6 relative to the largest component: the dumps carry 15 digits (the first check holds to 1e-12);
    the reader puts the contacts within yield_rtol = 1e-4 of the friction cone exactly on it (docs/formats.md), which
    moves each such force by less than 1e-4 of itself and σ by at most 3.2e-7 of it on this run's 40 frames."""
    pressure = np.loadtxt(sheared / "pressure_shear2d.txt")
    assert len(pressure) == 40
    files = [sheared / "atoms_shear2d_track.dump", sheared / "contacts_shear2d_track.dump", SCRIPT]
    for step, pxx, pyy, pxy in pressure:
        P = np.array([pxx, pyy, pxy])
        local, _ = frame_rows(files[1], int(step))
        force, delta = local[:, 2:4] + local[:, 5:7], local[:, 8:10]   # normal + tangential part on id1; x_1 − x_2
        scene = load(files, timestep=int(step)).scene
        area = abs(np.linalg.det(scene.cell))
        virial = np.einsum("ci,cj->ij", delta, force) / area
        assert np.abs(virial[[0, 1, 0], [0, 1, 1]] - P).max() <= 1e-12 * np.abs(P).max()
        s = stress(scene)
        assert np.abs(-s[[0, 1, 1], [0, 1, 0]] - P).max() <= 1e-6 * np.abs(P).max(), step


@pytest.mark.dem
def test_3d_contact_stress_equals_lammps_pressure(tmp_path):
    """in.shear3d_track, shortened (6 frames, no pre-shear): the same identity in 3D, P = (1/V) Σ del ⊗ f with
    V = xprd·yprd·zprd and LAMMPS's six components xx yy zz xy xz yz = Σ delx fy, delx fz, dely fz, so
    σ_yx = −P_xy, σ_zx = −P_xz, σ_zy = −P_yz. Tolerance as in 2D (the cone policy; 15 digits)."""
    subprocess.run(["lmp", "-in", str(TRACK / "in.shear3d_track"), "-var", "frames", "6", "-var", "preshear", "0",
                    "-log", "none", "-screen", "none"], cwd=tmp_path, check=True, timeout=120)
    pressure = np.loadtxt(tmp_path / "pressure_shear3d.txt")
    assert pressure.shape == (6, 7)
    files = [tmp_path / "atoms_shear3d_track.dump", tmp_path / "contacts_shear3d_track.dump",
             TRACK / "in.shear3d_track"]
    for step, *P in pressure:
        s = stress(load(files, timestep=int(step)).scene)
        mine = -s[[0, 1, 2, 1, 2, 2], [0, 1, 2, 0, 0, 1]]
        assert np.abs(mine - P).max() <= 1e-6 * np.abs(P).max(), step


@pytest.mark.dem
def test_run_is_quasi_static_with_several_stress_drops(sheared):
    """Inertial number I = γ̇ d̄ √(ρ_s / P) (ρ_s = m / (π R²) the grain's mass per area, P = −tr σ / 2) below 1e-3
    on every frame; at least three drops of the shear stress −P_xy larger than 10 % between consecutive frames."""
    pressure = np.loadtxt(sheared / "pressure_shear2d.txt")
    atoms, _ = frame_rows(sheared / "atoms_shear2d_track.dump", int(pressure[0, 0]))
    radius, mass = atoms[:, 5], atoms[:, 7]
    rho = np.mean(mass / (np.pi * radius**2))
    inertial = RATE * np.mean(2 * radius) * np.sqrt(rho / (0.5 * (pressure[:, 1] + pressure[:, 2])))
    assert inertial.max() < 1e-3, inertial.max()
    shear = -pressure[:, 3]
    drops = (shear[:-1] - shear[1:]) / np.abs(shear[:-1])
    assert (drops > 0.10).sum() >= 3, np.round(drops, 3)
    steps = np.diff(pressure[:, 0])
    assert np.all(steps == 500)                           # dumped every 500 steps: Δγ = 500 · γ̇ · dt per frame
    assert 500 * RATE * DT == pytest.approx(0.006)
