"""Every invalid input exits with status 2 and ONE line on stderr naming the file, the entry and the field."""
import json
import subprocess
import sys

import pytest

from granstab.cli import main

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
    import tomllib
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
