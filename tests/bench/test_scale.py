"""The held-out check `scale` (issue 41, benchmarks/scale.py) at a small size: its own periodic packing written as a
JSON scene, `granstab analyze --json` run on it in a fresh process, the answer checked against scipy's own
shift-invert solve (the exact rigid zero count, λ_min to 1e-8 relative, every eigenvalue within its reported bound).
The check itself can fail: an answer moved by more than its bound is caught."""
import copy

import numpy as np

from granstab.solve.sparse import DENSE_MAX_DOF
from granstab_bench import scale


def test_small_scale_check_passes_and_catches_a_wrong_answer(tmp_path):
    pk = scale.packing(800)
    n = len(pk["x"])
    assert 3 * n > DENSE_MAX_DOF                          # the sparse path, as at 2·10⁵ disks
    path = tmp_path / "scale.json"
    scale.write_json(path, pk)
    answer = scale.run_cli(path)
    ref = scale.reference(path)
    verdict = scale.verdicts(answer, ref)
    assert answer["rc"] == 0 and answer["result"]["n_particles"] == n
    assert verdict["rigid_zeros"] and verdict["counts"] and verdict["bounds_ok"]
    assert verdict["rel_error"] <= scale.REL_TOL and verdict["ok"]
    wrong = copy.deepcopy(answer)
    branch = wrong["result"]["branches"][0]
    lam, bound = np.array(branch["stability_eigenvalues"]), np.array(branch["accuracy"])
    branch["stability_eigenvalues"][2] = float(lam[2] + 3 * bound[2] + 1e-7 * abs(lam[2]))
    bad = scale.verdicts(wrong, ref)
    assert not bad["ok"] and not bad["bounds_ok"] and not bad["rel_ok"]
    branch["n_zero"] = 3
    assert not scale.verdicts(wrong, ref)["rigid_zeros"]
