"""One loader: `granstab.io.load` reads scene files and snapshots alike through the registry of formats (each a
name, a sniff and a read), and returns a `Loaded` whose report lists what the import changed (its warnings)."""
import json
import tomllib

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

import granstab
from granstab.cli import main
from granstab.io import Format, formats, load, registry
from granstab.io.build import Snapshot
from granstab.io.scenes import save_scene, scene_from_dict

PRESETS = ROOT / "presets"
ANNULUS = ROOT / "tests" / "data" / "io" / "annulus"      # two frames cut from RigidLibrary's DataAnnulus
ARRAYS = ("x", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "k", "alpha", "mu", "load")


def test_every_reader_registers_its_formats():
    assert set(formats()) == {"scene-toml", "scene-json", "scene-npz", "rigidlibrary-annulus",
                              "rigidlibrary-datasim", "lammps", "liggghts-superquadric", "mercurydpm", "table", "clumps", "liggghts_multisphere", "lammps_polygons"}


@pytest.mark.parametrize("syntax", ["toml", "json", "npz"])
def test_a_scene_file_is_read_as_written_with_no_warnings(tmp_path, syntax):
    """The scene of load(file) is the scene of the parsed file (scene_from_dict, without the loader); its
    report says it was read as a scene file and warns of nothing."""
    preset = PRESETS / "four_disk.toml"
    expected = scene_from_dict(tomllib.loads(preset.read_text()), source=str(preset))
    path = preset if syntax == "toml" else save_scene(expected, tmp_path / f"four_disk.{syntax}")
    loaded = load(path)
    assert loaded.report == {"source": str(path), "format": f"scene-{syntax}", "read_as": "scene file",
                             "warnings": []}
    assert loaded.warnings == [] and loaded.frames is None
    assert loaded.scene.names == expected.names and loaded.scene.state == expected.state
    for key in ARRAYS:
        assert np.array_equal(getattr(loaded.scene, key), getattr(expected, key)), key
    assert np.array_equal(granstab.load_scene(path).force, loaded.scene.force)      # the facade's convenience


def test_a_named_format_reads_a_file_whatever_its_suffix(tmp_path):
    path = tmp_path / "scene.txt"
    path.write_text(json.dumps(tomllib.loads((PRESETS / "gear_packing.toml").read_text())))
    with pytest.raises(granstab.SceneError, match=r"scene.txt: format: not recognised \(known: .*scene-json"):
        load(path)
    named = load(path, format="scene-json")
    assert named.report["format"] == "scene-json"
    assert np.array_equal(named.scene.force, load(PRESETS / "gear_packing.toml").scene.force)


def test_an_unknown_format_is_one_line_naming_every_registered_one(tmp_path, capsys):
    with pytest.raises(granstab.SceneError) as caught:
        load(PRESETS / "gear_packing.toml", format="xyz")
    message = str(caught.value)
    assert "\n" not in message and "'xyz'" in message and all(name in message for name in formats())
    assert main(["convert", str(ANNULUS), "--format", "xyz", "--out", str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--format: must be auto or one of" in err and "rigidlibrary-annulus" in err


def test_a_scene_file_refuses_the_options_of_snapshots():
    with pytest.raises(granstab.SceneError, match=r"gear_packing.toml: mu: an option of snapshots; a scene file "
                                                  r"\(scene-toml\) is read as written"):
        load(PRESETS / "gear_packing.toml", mu=0.3)
    with pytest.raises(granstab.SceneError, match="gear_packing.toml: frame: an option of snapshots"):
        load(PRESETS / "gear_packing.toml", frame=2)


def two_disks(paths, request, progress):
    """A toy reader: `<gap> <f_n> <f_t>` → two unit disks, the force on the first f = (−f_n, f_t)."""
    gap, fn, ft = np.loadtxt(paths[0])
    return Snapshot(source=str(paths[0]), format="toy-pair", dim=2, ids=np.array([1, 2]),
                    x=np.array([[0.0, 0.0], [2.0 + gap, 0.0]]), radius=np.ones(2), p=np.array([0]),
                    q=np.array([1]), force=np.array([[-fn, ft]]))


def test_a_format_registered_from_outside_is_detected_and_built(tmp_path, monkeypatch):
    """A reader registered by other code is found by its sniff, and its snapshot goes through the shared
    conventions (the cone projection here) and the report's warnings; two formats that both accept an input
    are refused as ambiguous, not picked by their order."""
    monkeypatch.setattr(registry, "_FORMATS", dict(registry._FORMATS))      # registrations undone after the test
    sniff = lambda paths: paths[0].suffix == ".pair"   # noqa: E731
    granstab.io.register(Format("toy-pair", sniff=sniff, read=two_disks))
    path = tmp_path / "x.pair"
    path.write_text("-0.1 0.01 0.005\n")
    loaded = load(path, mu=0.2)
    assert loaded.report["format"] == "toy-pair" and loaded.report["read_as"] == "snapshot"
    assert np.allclose(loaded.scene.force, [[-0.01, 0.2 * 0.01]], rtol=0, atol=1e-17)   # onto |f_t| = μ f_n
    assert loaded.scene.state == ("sliding",)
    (outside,) = [w for w in loaded.warnings if "outside the friction cone" in w]
    assert outside.startswith("1 contact(s) outside the friction cone (100 %, |f_t|/(μ f_n) up to 2.5)")
    assert "(1-2)" in outside
    with pytest.raises(ValueError, match="registered already"):
        granstab.io.register(Format("toy-pair", sniff=sniff, read=two_disks))
    granstab.io.register(Format("toy-pair-2", sniff=sniff, read=two_disks))
    with pytest.raises(granstab.SceneError, match=r"x.pair: format: ambiguous \(toy-pair, toy-pair-2\); name it"):
        load(path)
    assert load(path, format="toy-pair-2", mu=0.2).report["format"] == "toy-pair"   # the named one reads


def raw_frame(frame: int):
    """The frame's particle ids, contact pairs (id1 > id2: one listing per pair) and (f_n, f_t), read from the
    annulus files without granstab."""
    pos = np.loadtxt(ANNULUS / "particle_positions.txt", delimiter=",", ndmin=2)
    adj = np.loadtxt(ANNULUS / "Adjacency_list.txt", delimiter=",", ndmin=2)
    pos, adj = pos[pos[:, 0] == frame], adj[adj[:, 0] == frame]
    adj = adj[adj[:, 1] > adj[:, 2]]
    return pos[:, 1].astype(int), adj[:, 1:3].astype(int), adj[:, 4], adj[:, 3]


def test_the_warnings_count_what_the_import_changed_on_real_frames():
    """RigidLibrary annulus frames (tests/data/io/annulus): the rattlers dropped are the particles no contact
    of the frame touches, and the contacts projected onto the cone at μ = 0.05 are those with |f_t| > μ f_n
    (1 + yield_rtol) in the file; both counted from the raw files."""
    ids, pairs, fn, ft = raw_frame(1)
    rattlers = sorted(set(ids) - set(pairs.ravel()))
    outside = int(np.sum((fn > 0) & (np.abs(ft) > 0.05 * fn * (1 + 1e-4))))
    assert rattlers and outside                                   # the frame has both
    loaded = load(ANNULUS, frame=1, mu=0.05)
    assert loaded.report["particles"]["dropped"] == [str(i) for i in rattlers]
    assert f"{len(rattlers)} particle(s) without contacts (rattlers) dropped ({rattlers[0]}, " in "\n".join(
        loaded.warnings)
    (cone,) = [w for w in loaded.warnings if "outside the friction cone" in w]
    assert cone.startswith(f"{outside} contact(s) outside the friction cone ({100 * outside / len(fn):.1f} %")
    assert "projected onto the cone, marked sliding (at yield)" in cone
    assert "law: k = 1, alpha = 1: not in the file, built-in default" in "\n".join(loaded.warnings)
    assert not any("mu =" in w for w in loaded.warnings)          # μ was given
    kept = load(ANNULUS, frame=1, mu=0.05, keep_rattlers=True, outside_cone="elastic")
    assert not any("rattlers" in w for w in kept.warnings)
    assert any(w.startswith(f"{outside} contact(s) outside") and "kept as in the file" in w for w in kept.warnings)


def test_convert_reads_a_scene_file_too(tmp_path, capsys):
    out = tmp_path / "gear_packing.npz"
    assert main(["convert", str(PRESETS / "gear_packing.toml"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"{PRESETS / 'gear_packing.toml'} (scene-toml): read as a scene file, as written" in printed
    assert "warning" not in printed
    again, direct = load(out).scene, load(PRESETS / "gear_packing.toml").scene
    for key in ARRAYS:
        assert np.array_equal(getattr(again, key), getattr(direct, key)), key
