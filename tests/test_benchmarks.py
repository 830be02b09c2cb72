"""`granstab bench`: the topics honour the benchmarks contract, the CLI runs one topic end to end and rejects an
unknown one with a one-line error (exit 2). Speed itself is measured by the benchmarks, never asserted here."""
import importlib
import json

import pytest

from granstab.cli import main
from granstab_bench import TOPICS


@pytest.mark.parametrize("topic", TOPICS)
def test_topic_has_run_and_markdown(topic):
    module = importlib.import_module(f"granstab_bench.{topic}")
    assert callable(module.run) and callable(module.markdown)
    assert "quick" in module.run.__code__.co_varnames[:module.run.__code__.co_argcount]


def test_unknown_topic_is_one_line_exit_2(capsys):
    assert main(["bench", "--quick", "--only", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nope" in err and "app_latency" in err


def test_quick_run_of_one_topic_writes_its_section_and_results(tmp_path):
    assert main(["bench", "--quick", "--only", "app_latency", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "BENCHMARKS.md").read_text(encoding="utf-8")
    assert "QUICK run" in text and "## App latency" in text and "(#app-latency)" in text
    results = json.loads((tmp_path / "docs" / "bench" / "results.json").read_text())
    scenes = results["app_latency"]["scenes"]
    # one contact for the pair; the 5 × 10 triangular patch: 5·9 in rows + 4·(10 + 9) between rows = 121
    assert {name: d["contacts"] for name, d in scenes.items()} == {"two-particle pair (6 dofs)": 1,
                                                                   "50 disks, 2D (150 dofs)": 121}
    assert all(d[key] > 0 for d in scenes.values() for key in ("t_build", "t_analyze", "t_total"))


def test_converting_checks_what_it_converts():
    """The converting topic asserts that every converted scene reproduces its packing (contacts, forces, centres,
    law); in quick mode at 10³ and 10⁴ contacts, 2D and 3D, LAMMPS dumps and tables."""
    from granstab_bench import converting
    results = converting.run(quick=True)
    assert {(r["dim"], r["format"]) for r in results["rows"]} == {(d, f) for d in (2, 3) for f in ("lammps", "table")}
    assert all(r["check"]["ok"] and r["dropped_non_touching"] == (r["contact_rows"] - r["check"]["contacts"])
               for r in results["rows"])
    assert "## Converting DEM output" in converting.markdown(results)


@pytest.mark.slow
def test_quick_run_of_every_topic(tmp_path):
    """Every topic runs against the current core (a renamed core function breaks here, not in a release run) and
    lands in BENCHMARKS.md, its table of contents and results.json; 20-60 s on a shared 2-core machine."""
    assert main(["bench", "--quick", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "BENCHMARKS.md").read_text(encoding="utf-8")
    results = json.loads((tmp_path / "docs" / "bench" / "results.json").read_text())
    assert list(results) == list(TOPICS)
    headings = [line[3:] for line in text.splitlines() if line.startswith("## ")]
    assert len(headings) == len(TOPICS) + 1 and headings[-1] == "Using the fast paths"
    assert all(f"- [{h}](#" in text for h in headings)
