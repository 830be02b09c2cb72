"""`granstab reproduce`: regenerate REPRODUCTION.md, the data and the figures, and compare with the committed ones.

The committed outputs live in docs/reproduction/ (figures, CSV data) and REPRODUCTION.md at the repository root
(links into docs/reproduction/), the one copy. Numbers are compared with tolerances relative to each column's
scale (rtol 1e-9, atol 1e-12 of the column's largest magnitude): round-off can differ between BLAS builds, the
physics cannot. In REPRODUCTION.md the round-off bounds ("< 1e-15") are masked before the texts are compared.
"""
import csv
import re
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT  # noqa: E402

from granstab import paper as report
from granstab.cli import main
from granstab.paper.examples import NAMES

COMMITTED = ROOT / "docs" / "reproduction"
FIGURES = ("two_particle_lambda6", "gear_mode", "four_disk_spectra", "four_disk_path", "sliding_contact")


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory):
    root = tmp_path_factory.mktemp("repo")
    out = root / "docs" / "reproduction"
    results = report.reproduce("all", out, progress=False, root=root)
    return {"root": root, "out": out, "results": results}


def test_no_claim_differs(regenerated):
    claims = [c for name in NAMES for c in regenerated["results"][name]["claims"]]
    assert len(claims) >= 24
    assert not [c["id"] for c in claims if "DIFFERS" in c["verdict"]]
    for c in claims:
        assert c["paper"] and c["ours"] and c["claim"]


def _read(path: Path):
    with path.open(encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def _number(text):
    try:
        return float(text)
    except ValueError:
        return None


def test_committed_data_is_what_the_code_computes(regenerated):
    committed = sorted(p.name for p in COMMITTED.glob("*.csv"))
    assert committed == sorted(p.name for p in regenerated["out"].glob("*.csv")) and len(committed) >= 10
    for name in committed:
        head_a, rows_a = _read(COMMITTED / name)
        head_b, rows_b = _read(regenerated["out"] / name)
        assert head_a == head_b, name
        assert len(rows_a) == len(rows_b), name
        cols = list(zip(*rows_a)), list(zip(*rows_b))
        for j, (ca, cb) in enumerate(zip(*cols)):
            na, nb = [_number(v) for v in ca], [_number(v) for v in cb]
            if any(v is None for v in na + nb):
                assert ca == cb, (name, head_a[j])
                continue
            a, b = np.array(na), np.array(nb)
            finite = np.isfinite(a)
            scale = np.abs(a[finite]).max() if finite.any() else 0.0
            assert np.array_equal(finite, np.isfinite(b)), (name, head_a[j])
            assert np.allclose(a[finite], b[finite], rtol=1e-9, atol=1e-12 * max(scale, 1e-300)), (name, head_a[j])


def _masked(text: str) -> str:
    return re.sub(r"(< 1e-?\d+|= 0\b)", "ROUNDOFF", text)       # round-off bounds, exact zeros


def test_committed_report_is_what_the_code_writes(regenerated):
    """One REPRODUCTION.md, at the root (issue 40: no second copy in docs/reproduction/, in the repository or
    written by `reproduce all --root`)."""
    committed, fresh = ROOT / "REPRODUCTION.md", regenerated["root"] / "REPRODUCTION.md"
    assert _masked(committed.read_text(encoding="utf-8")) == _masked(fresh.read_text(encoding="utf-8"))
    assert not (COMMITTED / "REPRODUCTION.md").exists() and not (regenerated["out"] / "REPRODUCTION.md").exists()
    assert sorted(p.relative_to(ROOT).as_posix() for p in ROOT.rglob("REPRODUCTION.md")
                  if not {".venv", "node_modules", ".git"} & set(p.parts)) == ["REPRODUCTION.md"]


def test_report_links_and_figures_exist(regenerated):
    text = (ROOT / "REPRODUCTION.md").read_text(encoding="utf-8")
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(links) == len(FIGURES)
    for link in links:
        assert link.startswith("docs/reproduction/") and (ROOT / link).is_file(), link
    for stem in FIGURES:
        for out in (COMMITTED, regenerated["out"]):
            png, svg = out / f"{stem}.png", out / f"{stem}.svg"
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
            assert svg.read_text(encoding="utf-8").lstrip().startswith("<?xml")
    # every claim is in the summary table, with the paper's totals for the four-disk cluster
    assert "| 4.2-e | of these, 21 positive and 9 negative | 21 / 9 | 21 / 9;" in text


def test_cli_and_names(tmp_path):
    assert main(["reproduce", "sliding-contact", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "sliding_contact.csv").is_file() and (tmp_path / "sliding_contact.png").is_file()
    assert not (tmp_path / "REPRODUCTION.md").exists()
    with pytest.raises(ValueError, match="unknown example"):
        report.reproduce("three-disk", tmp_path, progress=False)


SIGNS = """
import json, sys
from threadpoolctl import threadpool_info, threadpool_limits
import granstab
from granstab.paper import four_disk as fd
with threadpool_limits(int(sys.argv[1]), user_api="blas"):
    r = granstab.analyze(fd.scene(**fd.PAPER), metric="L")
    st, un = fd.stability_table(r), fd.uniqueness_table(r)
print(json.dumps({"arch": sorted({i.get("architecture") for i in threadpool_info() if i["internal_api"] == "openblas"}),
                  "four_disk_branches.csv": [p["sign"] for row in st for p in row["pairs"]],
                  "four_disk_uniqueness.csv": [e["sign"] for row in un for e in row["entries"]]}))
"""


@pytest.mark.parametrize(("threads", "coretype", "busy"), [(1, None, False), (2, None, False),
                                                             pytest.param(2, None, True, marks=pytest.mark.serial),
                                                             (2, "Haswell", False), (2, "SkylakeX", False)])
def test_committed_signs_do_not_depend_on_blas_threads_kernels_or_load(threads, coretype, busy):
    """The four-disk tables' ±v signs (eigenvectors with entries equal by symmetry; ℍ^i null vectors from an SVD)
    are the committed ones with 1 or 2 BLAS threads, beside a process spinning on a core, and with OpenBLAS's
    Haswell (AVX2) or SkylakeX (AVX-512) kernels, each in a fresh process (main gave the uniqueness table's signs
    one way with Haswell and the other with SkylakeX)."""
    import json
    import os
    import subprocess
    import sys
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    if coretype:
        env["OPENBLAS_CORETYPE"] = coretype
    spin = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        proc = subprocess.run([sys.executable, "-c", SIGNS, str(threads)], capture_output=True, text=True, env=env,
                              timeout=300)
    finally:
        if spin is not None:
            spin.kill()
            spin.wait()
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    if coretype and got["arch"] != [coretype]:    # a build without DYNAMIC_ARCH, or a CPU without those kernels
        pytest.skip(f"this OpenBLAS ran {got['arch']} kernels, not OPENBLAS_CORETYPE={coretype}")
    for name in ("four_disk_branches.csv", "four_disk_uniqueness.csv"):
        head, rows = _read(COMMITTED / name)
        assert got[name] == [row[head.index("consistent")] for row in rows], name
