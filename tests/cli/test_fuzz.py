"""Fuzzing `granstab analyze FILE --json` as a hostile user would (issue 12), with a committed seed corpus.

The contract for ANY file: exit 0 with one strict JSON object on stdout (no NaN/Infinity) and nothing on stderr
(no warnings), or exit 2 with nothing on stdout and ONE line on stderr that starts with the file's name. Never a
traceback, never a hang (every run has --timeout).

- tests/corpus/: files that each broke an earlier version (float dim, JSON nested 5000 deep, duplicate keys, 1e300
  stiffnesses, NaN/Infinity tokens, booleans and nulls in arrays, integers beyond float64, far-away coordinates,
  2^16 branches) and valid seeds (unicode names, sliding contacts, tension, f/k = 1e-13, a rotated frictionless
  pair); expected.json gives each file's exit status and the words its one line must contain.
- hypothesis mutates the valid seeds and the presets: a leaf replaced by a hostile value (strings, booleans,
  null, ±1e±300, NaN, ±inf, huge integers, lists, tables), keys deleted or added, a leaf nested up to 3000 deep,
  a key written twice, the text truncated, every number scaled by 10^±300. The bounded number of examples
  (FUZZ_EXAMPLES, default 120) keeps the suite near 20 s; raise it to fuzz longer.

Runs in-process (cli.main, stdout/stderr captured); one subprocess run checks the console script end to end.
"""
import contextlib
import copy
import io
import json
import math
import os
import subprocess
import sys
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import granstab
from granstab.cli import main
from granstab.model import packings

CORPUS = ROOT / "tests" / "corpus"
EXPECTED = json.loads((CORPUS / "expected.json").read_text(encoding="utf-8"))
TIMEOUT = "20"


def run(path: Path, *args, command=("analyze", "--json")) -> tuple[int, str, str, list]:
    """`granstab analyze PATH --json ARGS` (or another command) in-process: (exit status, stdout, stderr,
    warnings raised)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rc = main([command[0], str(path), *command[1:], *args])
    return rc, out.getvalue(), err.getvalue(), [str(w.message) for w in caught]


def assert_contract(path: Path, rc: int, out: str, err: str, caught: list) -> None:
    assert not caught, caught
    if rc == 0:
        assert err == ""
        data = json.loads(out, parse_constant=lambda token: pytest.fail(f"non-strict JSON token {token}"))
        assert data["summary"]["verdict"] in ("stable", "neutral", "unstable")
    else:
        assert rc == 2, (rc, err)
        assert out == ""
        assert err.count("\n") == 1 and err.endswith("\n") and "Traceback" not in err, err
        assert err.startswith(f"{path}: "), err


@pytest.mark.parametrize("name", sorted(EXPECTED), ids=sorted(EXPECTED))
def test_corpus(name):
    path = CORPUS / name
    expect = EXPECTED[name]
    rc, out, err, caught = run(path, *expect.get("args", ["--timeout", TIMEOUT]))
    assert_contract(path, rc, out, err, caught)
    assert rc == expect["exit"], err
    for word in expect["words"]:
        assert word in err, (word, err)


@pytest.mark.parametrize("name", sorted(EXPECTED), ids=sorted(EXPECTED))
def test_corpus_plan(name):
    """`--plan` on every corpus file (issue 38): the same one line where the file is refused, else the plan and its
    estimate, and where the run takes over 2 s its measured time within 3× of that estimate (either way)."""
    path = CORPUS / name
    expect = EXPECTED[name]
    rc, out, err, caught = run(path, "--plan")
    assert not caught
    if rc == 2:
        assert out == "" and err.count("\n") == 1 and err.startswith(f"{path}: ")
        return
    cost = json.loads(out)["cost"]
    if cost["refusal"] or cost["estimated_s"] > 10:          # refused up front by the run (slow_*)
        rc, out, err, _ = run(path, *expect.get("args", ["--timeout", TIMEOUT]))
        assert rc == 2 and ("refused" in err or "stopped after" in err)
        return
    rc, out, err, _ = run(path, *expect.get("args", ["--timeout", TIMEOUT]))
    if rc == 0:
        measured = json.loads(out)["timings"]["total"]
        if measured > 2.0:
            assert 1 / 3 <= measured / cost["estimated_s"] <= 3, (measured, cost["estimated_s"])


def _seed_dicts() -> list:
    seeds = [json.loads(p.read_text(encoding="utf-8")) for p in sorted(CORPUS.glob("ok_*.json"))]
    seeds += [tomllib.loads(p.read_text()) for p in sorted((ROOT / "presets").glob("*.toml"))]
    return seeds


SEEDS = _seed_dicts()
HOSTILE = st.one_of(
    st.text(max_size=4), st.booleans(), st.none(),
    st.sampled_from([1e300, -1e300, 1e-300, 1e150, 1e51, 0.0, -0.0, math.nan, math.inf, -math.inf, 2, 3, 2.0, -1]),
    st.integers(-(2 ** 80), 2 ** 80).map(lambda v: v * 10 ** 300 if v % 7 == 0 else v),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)


def leaves(obj, path=()):
    """Every (path, value) of a nested dict/list, containers included."""
    yield path, obj
    if isinstance(obj, dict):
        for key, value in obj.items():
            yield from leaves(value, path + (key,))
    elif isinstance(obj, list):
        for i, value in enumerate(obj):
            yield from leaves(value, path + (i,))


def get_parent(obj, path):
    for key in path[:-1]:
        obj = obj[key]
    return obj


def scale_numbers(obj, factor):
    if isinstance(obj, dict):
        return {k: scale_numbers(v, factor) for k, v in obj.items()}
    if isinstance(obj, list):
        return [scale_numbers(v, factor) for v in obj]
    if isinstance(obj, float):
        return obj * factor
    return obj


@st.composite
def hostile_files(draw) -> str:
    """The text of a JSON scene file: a valid seed with one hostile mutation."""
    data = copy.deepcopy(draw(st.sampled_from(SEEDS)))
    kind = draw(st.sampled_from(["replace", "replace", "delete", "add", "nest", "duplicate", "truncate", "scale"]))
    paths = [p for p, _ in leaves(data) if p]
    path = draw(st.sampled_from(paths))
    parent = get_parent(data, path)
    if kind == "replace":
        parent[path[-1]] = draw(HOSTILE)
    elif kind == "delete":
        del parent[path[-1]]
    elif kind == "add":
        target = parent if isinstance(parent, dict) else data
        target[draw(st.sampled_from(["extra", "x", "dim", "k", "força"]))] = draw(HOSTILE)
    elif kind == "nest":                                 # written as text: json.dumps itself would recurse
        depth = draw(st.sampled_from([1, 2, 12, 3000]))
        original = parent[path[-1]]
        parent[path[-1]] = "@@NEST@@"
        return json.dumps(data).replace('"@@NEST@@"', "[" * depth + json.dumps(original) + "]" * depth, 1)
    elif kind == "scale":
        data = scale_numbers(data, 10.0 ** draw(st.integers(-300, 300)))
    if kind == "duplicate" and isinstance(parent, dict):
        original = parent[path[-1]]
        parent[path[-1]] = "@@DUP@@"
        text = json.dumps(data, ensure_ascii=False)
        return text.replace('"@@DUP@@"', f'{json.dumps(original)}, {json.dumps(path[-1])}: '
                                         f'{json.dumps(draw(HOSTILE))}', 1)
    text = json.dumps(data, ensure_ascii=False)
    if kind == "truncate":
        text = text[:draw(st.integers(0, max(len(text) - 1, 0)))]
    return text


@settings(max_examples=int(os.environ.get("FUZZ_EXAMPLES", "120")), deadline=None, database=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])
@given(text=hostile_files())
def test_hostile_files_exit_0_with_strict_json_or_2_with_one_line(tmp_path, text):
    path = tmp_path / "fuzzed.json"
    path.write_text(text, encoding="utf-8")
    rc, out, err, caught = run(path, "--timeout", TIMEOUT)
    assert_contract(path, rc, out, err, caught)
    # `granstab stiffness` reads the same file: the same outcome, its own output
    rc_k, out_k, err_k, caught_k = run(path, command=("stiffness", "--out", str(tmp_path / "K.npz")))
    assert not caught_k and rc_k == rc and (out_k.startswith("wrote ") if rc == 0 else err_k == err)


@st.composite
def extreme_valid_scenes(draw):
    """Valid packings at the ends of the accepted ranges: lengths 1e-20…1e20, f/(kr) 1e-14…0.3, α 1e-6…1e3,
    μ 0…2, contacts at yield, contact moments, rolling stiffness."""
    dim = draw(st.sampled_from([2, 3]))
    radius = 10.0 ** draw(st.integers(-20, 20))
    common = dict(radius=radius, f_over_k=10.0 ** draw(st.floats(-14, math.log10(0.3))),
                  mu=draw(st.sampled_from([0.0, 1e-12, 0.3, 2.0])), alpha=10.0 ** draw(st.floats(-6, 3)),
                  mobilised=draw(st.floats(0.0, 0.99)), moments=draw(st.sampled_from([0.0, 0.3])),
                  rolling=draw(st.sampled_from([0.0, 0.02])), seed=draw(st.integers(0, 2 ** 16)))
    n = draw(st.integers(2, 12) if dim == 2 else st.integers(2, 8))
    sliding = draw(st.integers(0, 3)) if common["mu"] > 0 else 0   # at yield needs friction
    try:
        return packings.random_packing(dim, n, n_sliding=sliding, **common)
    except ValueError:                                  # more sliding contacts asked than the packing has
        return packings.random_packing(dim, n, **common)


@settings(max_examples=int(os.environ.get("FUZZ_EXAMPLES", "120")) // 3, deadline=None, database=None,
          derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(scene=extreme_valid_scenes(), suffix=st.sampled_from([".json", ".npz"]))
def test_valid_scenes_at_the_ends_of_the_ranges_give_strict_json(tmp_path, scene, suffix):
    """Every number within the accepted ranges (README: |v| <= 1e50, k, α, L >= 1e-50, coordinates within 1e9 L):
    exit 0 with strict, finite JSON and no warning, from the text and the binary format alike."""
    path = granstab.save_scene(scene, tmp_path / f"valid{suffix}")
    rc, out, err, caught = run(path, "--timeout", TIMEOUT)
    assert_contract(path, rc, out, err, caught)
    assert rc == 0, err


NPZ_SEEDS = [granstab.io.schema.scene_arrays(granstab.scene_from_dict(seed)) for seed in SEEDS]
HOSTILE_ARRAYS = st.one_of(
    st.sampled_from([np.array(2.5), np.array([1.0, np.nan]), np.array([[1e300, 0.0]]), np.array(["x", "y"]),
                     np.zeros((0,)), np.zeros((2, 3, 4)), np.array([True, False]), np.array([-1, 7]),
                     np.array([2 ** 62, 0]), np.array(["", "p"])]),
    st.integers(0, 3).map(lambda k: np.full((k,), np.inf)),
)


@st.composite
def hostile_arrays(draw) -> dict:
    """An .npz scene with one array replaced, removed, added or scaled by 10^±300."""
    arrays = dict(draw(st.sampled_from(NPZ_SEEDS)))
    key = draw(st.sampled_from(sorted(arrays)))
    kind = draw(st.sampled_from(["replace", "replace", "delete", "add", "scale"]))
    if kind == "replace":
        arrays[key] = draw(HOSTILE_ARRAYS)
    elif kind == "delete":
        del arrays[key]
    elif kind == "add":
        arrays[draw(st.sampled_from(["contacts/extra", "particles/shape", "extra"]))] = draw(HOSTILE_ARRAYS)
    elif arrays[key].dtype.kind == "f":
        arrays[key] = arrays[key] * 10.0 ** draw(st.integers(-300, 300))
    return arrays


@settings(max_examples=int(os.environ.get("FUZZ_EXAMPLES", "120")) // 2, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(arrays=hostile_arrays())
def test_hostile_npz_files_exit_0_with_strict_json_or_2_with_one_line(tmp_path, arrays):
    path = tmp_path / "fuzzed.npz"
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    assert_contract(path, *run(path, "--timeout", TIMEOUT))


def test_console_script_refuses_what_it_cannot_finish_in_one_line():
    """End to end (a real process, its own SIGALRM): 2^16 branches with --timeout 1 end in one line, exit 2."""
    path = CORPUS / "slow_all_at_yield_2d.json"
    proc = subprocess.run([sys.executable, "-m", "granstab", "analyze", str(path), "--timeout", "1"],
                          capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(f"{path}: ")
    assert "refused" in proc.stderr or "stopped after --timeout" in proc.stderr


def chain(dim: int, n: int) -> granstab.Scene:
    """n equal disks/spheres in a straight line, each pressed on the next (a long, floppy chain: the sparse path)."""
    r = 1 if dim == 2 else 3
    x = np.zeros((n, dim))
    x[:, 0] = 2.0 * np.arange(n)
    normal = np.zeros((n - 1, dim))
    normal[:, 0] = 1.0
    K = -(np.eye(dim) - normal[0][:, None] * normal[0][None, :])
    arrays = dict(p=np.arange(n - 1), q=np.arange(1, n), point=x[:-1] + normal, normal=normal,
                  curvature_p=np.broadcast_to(K, (n - 1, dim, dim)).copy(),
                  curvature_q=np.broadcast_to(K, (n - 1, dim, dim)).copy(), force=-0.01 * normal,
                  moment=np.zeros((n - 1, r)), k=np.ones(n - 1), alpha=np.ones(n - 1), mu=np.full(n - 1, 0.5),
                  rolling=np.zeros((n - 1, r, r)), state=("auto",) * (n - 1))
    return granstab.build_scene(dim, [f"b{i}" for i in range(n)], x, arrays, title="chain")


@pytest.mark.serial                     # refused by a time estimate scaled by the machine's speed
def test_a_long_chain_is_refused_before_work_in_one_line(tmp_path):
    """The issue's silent hang (a 3,000-particle chain ran for minutes without a word): a 20,000-sphere chain on the
    sparse path, whose estimate (budget.sparse_estimate: 3 metrics × about 10 s) exceeds --timeout 0.5, is refused
    before any work, in one line that names the path and what to do."""
    path = granstab.save_scene(chain(3, 20_000), tmp_path / "chain.npz")
    rc, out, err, caught = run(path, "--timeout", "0.5")
    assert_contract(path, rc, out, err, caught)
    assert rc == 2 and "refused: 1 branches × 3 metric(s) of 120000 dofs (sparse path) need about" in err
    assert "--metric L alone" in err
