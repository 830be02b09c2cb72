"""Every invalid input exits with status 2 and ONE line on stderr naming the file, the entry and the field."""
import json
import subprocess
import sys
import tomllib

import numpy as np
import pytest
from helpers import TESTS  # noqa: E402

import granstab
from granstab.cli import main
from granstab.io import load_scene
from granstab.io import syntax as fileformat
from granstab.io.scenes import save_scene
from granstab.io.schema import scene_arrays
from granstab.model import packings

GOOD = """dim = 2
[[particles]]
name = "p"
x = [0.0, 0.0]
[[particles]]
name = "q"
x = [2.0, 0.0]
[[contacts]]
p = "p"
q = "q"
point = [1.0, 0.0]
normal = [1.0, 0.0]
curvature_p = -2.0
curvature_q = -2.0
force = [-0.01, 0.0]
"""

GOOD3 = """dim = 3
[[particles]]
name = "p"
x = [0.0, 0.0, 0.0]
[[particles]]
name = "q"
x = [2.0, 0.0, 0.0]
[[contacts]]
p = "p"
q = "q"
point = [1.0, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
curvature_p = [[0.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
curvature_q = [[0.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
force = [-0.01, 0.0, 0.0]
"""

# (name, text, words the one line must contain)
CASES = [
    ("malformed_toml", GOOD.replace("x = [0.0, 0.0]", "x = [0.0, 0.0"), ["malformed TOML"]),
    ("unknown_top_key", GOOD.replace("dim = 2", "dim = 2\ntitel = 'x'"), ["scene", "titel", "unknown key"]),
    ("unknown_contact_key", GOOD.replace("force =", "forse = [0.0, 0.0]\nforce ="), ["contacts[0]", "forse"]),
    ("unknown_particle_key", GOOD.replace('name = "p"', 'name = "p"\nradius = 1.0'), ["particles[0]", "radius"]),
    ("unknown_default", GOOD.replace("dim = 2", "dim = 2\n[defaults]\nmu_ = 0.3"), ["defaults", "mu_"]),
    ("missing_dim", GOOD.replace("dim = 2", ""), ["dim", "missing"]),
    ("bad_dim", GOOD.replace("dim = 2", "dim = 4"), ["dim", "2 or 3"]),
    ("missing_point", GOOD.replace("point = [1.0, 0.0]\n", ""), ["contacts[0] (p-q)", "point", "missing"]),
    ("missing_x", GOOD.replace('x = [2.0, 0.0]\n', ""), ["particles[1] ('q')", "x", "missing"]),
    ("wrong_length", GOOD.replace("force = [-0.01, 0.0]", "force = [-0.01, 0.0, 0.0]"), ["contacts[0]", "force", "2 numbers"]),
    ("non_finite", GOOD.replace("point = [1.0, 0.0]", "point = [nan, 0.0]"), ["contacts[0]", "point", "finite"]),
    ("infinite", GOOD.replace("curvature_p = -2.0", "curvature_p = -inf"), ["contacts[0]", "curvature_p", "finite"]),
    ("string_number", GOOD.replace("curvature_q = -2.0", 'curvature_q = "-2"'), ["contacts[0]", "curvature_q"]),
    ("not_unit", GOOD.replace("normal = [1.0, 0.0]", "normal = [0.9, 0.0]"), ["contacts[0]", "normal", "unit"]),
    ("p_equals_q", GOOD.replace('q = "q"', 'q = "p"'), ["contacts[0]", "q", "p = q"]),
    ("unknown_particle", GOOD.replace('q = "q"', 'q = "r"'), ["contacts[0]", "q", "unknown particle 'r'"]),
    ("duplicate_contact", GOOD + GOOD[GOOD.index("[[contacts]]"):].replace('p = "p"\nq = "q"', 'p = "q"\nq = "p"'),
     ["contacts[1] (q-p)", "duplicate contact"]),
    ("duplicate_name", GOOD.replace('name = "q"', 'name = "p"'), ["particles[1]", "name", "duplicate"]),
    ("outside_cone", GOOD.replace("force = [-0.01, 0.0]", "force = [-0.01, 0.006]"), ["contacts[0] (p-q)", "force", "friction cone"]),
    ("sliding_not_at_yield", GOOD.replace("force = [-0.01, 0.0]", "force = [-0.01, 0.001]\nstate = \"sliding\""),
     ["contacts[0]", "state", "not at yield"]),
    ("bad_state", GOOD.replace("force = [-0.01, 0.0]", "force = [-0.01, 0.0]\nstate = \"stuck\""), ["contacts[0]", "state"]),
    ("unbalanced_load", GOOD.replace('x = [0.0, 0.0]', 'x = [0.0, 0.0]\nload = [0.02, 0.0]'),
     ["particles[0] ('p')", "load", "does not balance", "residual"]),
    ("unbalanced_moment", GOOD.replace('x = [0.0, 0.0]', 'x = [0.0, 0.0]\nmoment = 0.5'),
     ["particles[0] ('p')", "moment", "residual"]),
    ("negative_k", GOOD.replace("force = [-0.01, 0.0]", "force = [-0.01, 0.0]\nk = -1.0"), ["contacts[0]", "k", "> 0"]),
    ("not_symmetric", GOOD3.replace("[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]\ncurvature_q", "[0.0, -1.0, 0.5], [0.0, 0.0, -1.0]]\ncurvature_q"),
     ["contacts[0]", "curvature_p", "symmetric"]),
    ("not_tangent", GOOD3.replace("curvature_q = [[0.0, 0.0, 0.0]", "curvature_q = [[-1.0, 0.0, 0.0]"),
     ["contacts[0]", "curvature_q", "tangent"]),
    ("no_particles", "dim = 2\n", ["particles"]),
]


@pytest.mark.parametrize("name,text,words", CASES, ids=[c[0] for c in CASES])
def test_invalid_scene_one_line(tmp_path, capsys, name, text, words):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    for argv in (["analyze", str(path)], ["stiffness", str(path), "--out", str(tmp_path / "o.npz")]):
        assert main(argv) == 2
        out, err = capsys.readouterr()
        assert out == ""
        assert err.count("\n") == 1 and "Traceback" not in err
        assert err.startswith(str(path) + ": ")
        for word in words:
            assert word in err, (word, err)


def test_malformed_json_and_json_equivalence(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"dim": 2, "particles": [}')
    assert main(["analyze", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{bad}: malformed JSON") and err.count("\n") == 1
    # the same scene as JSON gives the same analysis as TOML
    good_json = tmp_path / "good.json"
    good_json.write_text(json.dumps(tomllib.loads(GOOD)))
    good_toml = tmp_path / "good.toml"
    good_toml.write_text(GOOD)
    assert main(["analyze", str(good_json), "--json"]) == 0
    a = json.loads(capsys.readouterr().out)
    assert main(["analyze", str(good_toml), "--json"]) == 0
    b = json.loads(capsys.readouterr().out)
    assert a["branches"] == b["branches"]


def test_bad_mask_and_missing_file(tmp_path, capsys):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    assert main(["stiffness", str(path), "--out", str(tmp_path / "o.npz"), "--mask", "1,1"]) == 2
    assert "--mask" in capsys.readouterr().err
    assert main(["stiffness", str(path), "--out", str(tmp_path / "o.npz"), "--mask", "1"]) == 2
    assert "not at yield" in capsys.readouterr().err
    assert main(["analyze", str(tmp_path / "absent.toml")]) == 2
    err = capsys.readouterr().err
    assert "absent.toml: cannot read file" in err and err.count("\n") == 1


def test_console_script_prints_no_traceback(tmp_path):
    path = tmp_path / "cone.toml"
    path.write_text(CASES[18][1])
    proc = subprocess.run([sys.executable, "-m", "granstab", "analyze", str(path)], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stdout == "" and proc.stderr.count("\n") == 1 and "friction cone" in proc.stderr


def test_cohesive_elastic_contact_may_carry_tension(tmp_path, capsys):
    path = tmp_path / "tension.toml"
    path.write_text(GOOD.replace("force = [-0.01, 0.0]", 'force = [0.004, 0.0]\nstate = "elastic"'))
    assert main(["analyze", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_sliding"] == 0


def test_unwritable_output_is_one_line(tmp_path, capsys):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    target = tmp_path / "no" / "such" / "dir" / "k.npz"
    assert main(["stiffness", str(path), "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot write" in err and "no/such/dir" in err


# ------------------------------------------------------------------ file formats: NPZ, strict JSON, the scanner
FIELDS = ("x", "p", "q", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "k", "alpha", "mu",
          "rolling", "load", "load_moment")


def assert_same_scene(a, b):
    """Equal arrays; 2D curvature tensors are stored as κ = tᵀKt and rebuilt as κ t⊗t: equal to 2 ulp of |K|."""
    assert a.names == b.names and a.state == b.state and a.title == b.title and a.dim == b.dim
    for key in FIELDS:
        x, y = getattr(a, key), getattr(b, key)
        if key.startswith("curvature") and a.dim == 2:
            assert np.abs(x - y).max(initial=0.0) <= 4 * np.finfo(float).eps * np.abs(x).max(initial=0.0), key
        else:
            assert np.array_equal(x, y), key


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("suffix", [".npz", ".json"])
def test_save_scene_round_trip(tmp_path, dim, suffix):
    """save_scene → load_scene gives the same arrays: sliding and elastic states, contact moments, rolling
    stiffness (3D: full matrices), per-contact laws and explicit balanced loads; an empty title too."""
    scene = packings.random_packing(dim, 9, n_sliding=2, moments=0.3, rolling=0.02, seed=11, alpha=0.7, mu=0.4)
    scene = granstab.build_scene(dim, scene.names, scene.x, {**{k: getattr(scene, k) for k in FIELDS[1:13]},
                                                              "state": ("elastic",) + scene.state[1:]},
                                 title="")
    back = load_scene(save_scene(scene, tmp_path / f"s{suffix}"))
    assert_same_scene(scene, back)
    assert back.source == str(tmp_path / f"s{suffix}")


def test_mixed_optional_fields_read_column_wise(tmp_path, capsys):
    """Optional fields given for some contacts only, 3D rolling stiffness as a scalar in one contact and a matrix
    in another, defaults elsewhere: each contact gets its own value."""
    data = tomllib.loads(GOOD3)
    c0 = data["contacts"][0]
    data["particles"].append({"name": "r", "x": [0.0, 2.0, 0.0]})
    c1 = {**c0, "q": "r", "point": [0.0, 1.0, 0.0], "normal": [0.0, 1.0, 0.0], "force": [0.0, -0.01, 0.0],
          "curvature_p": [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -1.0]],
          "curvature_q": [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -1.0]],
          "rolling_stiffness": [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]], "k": 5.0}
    c0["rolling_stiffness"] = 0.25
    data["contacts"].append(c1)
    data["defaults"] = {"k": 2.0, "mu": 0.3}
    s = granstab.scene_from_dict(data)
    assert s.k.tolist() == [2.0, 5.0] and s.mu.tolist() == [0.3, 0.3] and s.alpha.tolist() == [1.0, 1.0]
    assert np.array_equal(s.rolling[0], 0.25 * np.eye(3)) and np.array_equal(s.rolling[1], np.diag([1.0, 2.0, 3.0]))


def _npz(tmp_path, arrays, name="bad.npz"):
    path = tmp_path / name
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    return path


def test_npz_errors_name_file_array_and_entry(tmp_path, capsys):
    good = scene_arrays(granstab.scene_from_dict(tomllib.loads(GOOD)))
    cases = [
        ({**good, "contacts/forse": good["contacts/force"]}, ["contacts/forse", "unknown array"]),
        ({k: v for k, v in good.items() if k != "contacts/normal"}, ["contacts: normal", "missing array"]),
        ({**good, "contacts/force": good["contacts/force"][:, :1]}, ["contacts: force", "shape (1, 2)"]),
        ({**good, "contacts/k": np.array([1.0, 2.0])}, ["contacts/k", "2 rows, expected 1"]),
        ({**good, "contacts/point": np.array([[np.nan, 0.0]])}, ["contacts[0] (p-q): point", "finite"]),
        ({**good, "contacts/q": np.array(["z"])}, ["contacts[0]: q", "unknown particle 'z'"]),
        ({**good, "contacts/q": np.array([2])}, ["contacts[0]: q", "particle index 2 is not in 0..1"]),
        ({**good, "dim": np.array(2.0)}, ["scene: dim", "integer"]),
    ]
    for arrays, words in cases:
        path = _npz(tmp_path, arrays)
        assert main(["analyze", str(path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"{path}: ")
        for word in words:
            assert word in err, (word, err)
    objects = tmp_path / "objects.npz"
    with open(objects, "wb") as fh:
        np.savez(fh, **{**good, "particles/name": np.array(["p", "q"], dtype=object)})
    garbled = tmp_path / "garbled.npz"
    garbled.write_bytes(b"PK\x03\x04 not really a zip archive")
    for path, word in ((objects, "Object arrays cannot be loaded"), (garbled, "not a readable .npz")):
        assert main(["analyze", str(path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"{path}: ") and word in err, err


def test_save_scene_refuses_other_suffixes_and_non_finite_json(tmp_path):
    scene = granstab.scene_from_dict(tomllib.loads(GOOD))
    with pytest.raises(granstab.SceneError, match="writes .json or .npz"):
        save_scene(scene, tmp_path / "s.toml")
    with pytest.raises(granstab.SceneError, match="non-finite"):
        fileformat.write_json({"x": float("nan")}, tmp_path / "n.json")


def test_structure_scan_ignores_brackets_and_colons_inside_strings():
    raw = b'{"a:[": [1, {"b": "x\\"]}{:true"}], "t": [true]}'
    depth, pos, keys = fileformat.structure(raw)
    assert (depth, keys) == (3, 3)
    assert raw[pos:pos + 1] == b"{"


def test_duplicate_key_inside_a_shape_is_named(tmp_path, capsys):
    text = ('{"dim": 2, "particles": [{"name": "a", "x": [0, 0], "shape": {"kind": "disk", "radius": 1, '
            '"radius": 2}}, {"name": "b", "x": [1.9, 0], "shape": {"kind": "disk", "radius": 1}}]}')
    path = tmp_path / "shape.json"
    path.write_text(text)
    assert main(["analyze", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "particles[0] ('a'): shape: radius: duplicate key" in err, err


def test_reading_progress_on_stderr(tmp_path, capsys, monkeypatch):
    """Files above PROGRESS_BYTES show a bar (bytes read, then the stages) when asked; nothing otherwise."""
    path = tmp_path / "s.json"
    path.write_text(json.dumps(tomllib.loads(GOOD)))
    monkeypatch.setattr(granstab.io.progress, "PROGRESS_BYTES", 10)
    load_scene(path, progress=True)
    err = capsys.readouterr().err
    assert "checks s.json" in err and f"{path.stat().st_size}" in err
    load_scene(path)
    assert capsys.readouterr().err == ""


def test_coordinates_far_from_the_origin_and_tiny_scales_are_refused(tmp_path, capsys):
    scene = granstab.scene_from_dict(tomllib.loads(GOOD))
    arrays = {k: getattr(scene, k) for k in FIELDS[1:13]} | {"state": scene.state}
    with pytest.raises(granstab.SceneError, match=r"particles\[0\] \('p'\): x: 1e\+10 is more than 1e\+09 mean "):
        granstab.build_scene(2, scene.names, scene.x + [1e10, 0.0], {**arrays, "point": scene.point + [1e10, 0.0]})
    granstab.build_scene(2, scene.names, scene.x + [1e8, 0.0], {**arrays, "point": scene.point + [1e8, 0.0]})
    tiny = {**arrays, "point": scene.point * 1e-60, "curvature_p": 0 * scene.curvature_p,   # flat: no 1/length
            "curvature_q": 0 * scene.curvature_q}
    with pytest.raises(granstab.SceneError, match=r"mean contact radius 1e-60 is outside \[1e-50, 1e\+50\]"):
        granstab.build_scene(2, scene.names, scene.x * 1e-60, tiny)


def test_more_sliding_contacts_than_allowed_is_refused_with_what_to_do(capsys):
    path = str(TESTS / "corpus" / "slow_all_at_yield_2d.json")
    assert main(["analyze", path, "--max-sliding", "12"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"{path}: 16 potentially sliding contacts give 2^16 branches")
    assert "--max-sliding 12" in err and 'state = "elastic"' in err
