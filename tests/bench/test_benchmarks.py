"""`granstab bench`: the topics honour the benchmarks contract, the CLI runs one topic end to end and rejects an
unknown one with a one-line error (exit 2); the writer of BENCHMARKS.md (fed fake results: nothing is timed here)
writes the whole file, rewrites one topic's section alone and gives headings GitHub's anchors. Speed itself is
measured by the benchmarks, never asserted here."""
import importlib
import json
import re
import sys
import types
from pathlib import Path

import pytest

from granstab.cli import main
from granstab_bench import TOPICS, runner
from granstab_bench.document import MARKER_LINE, Document, NotGenerated, Slugger, headings, slug


@pytest.mark.parametrize("topic", TOPICS)
def test_topic_has_run_and_markdown(topic):
    module = importlib.import_module(f"granstab_bench.{topic}")
    assert callable(module.run) and callable(module.markdown)
    assert "quick" in module.run.__code__.co_varnames[:module.run.__code__.co_argcount]


def test_unknown_topic_is_one_line_exit_2(capsys):
    assert main(["bench", "--quick", "--only", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nope" in err and "app_latency" in err


def test_quick_run_of_one_topic_writes_its_section_and_results(tmp_path, monkeypatch):
    from granstab_bench import timing
    monkeypatch.setattr(timing, "ONCE", True)                   # one call a timing: the code runs, no measuring
    assert main(["bench", "--quick", "--only", "app_latency", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "BENCHMARKS.md").read_text(encoding="utf-8")
    assert "QUICK (small sizes)" in text and "## App latency" in text and "(#app-latency)" in text
    results = json.loads((tmp_path / "docs" / "bench" / "results.json").read_text())
    assert results["app_latency"]["run"]["command"] == "granstab bench --quick --only app_latency"
    scenes = results["app_latency"]["results"]["scenes"]
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


# The smallest sizes at which each topic still runs every one of its paths (its plumbing: the core functions it
# calls, its tables, figures and results), replacing attributes of the topic's module in test_quick_run_of_every_topic;
# a dict names only the entries it changes. The --quick sizes took 5 minutes of CI on a 2-core machine; the sizes
# themselves are the benchmarks' business. No busy processes (estimates, app_load): a load is a measuring condition.
SMALLEST = {
    "assembly": {"QUICK": {"sizes_2d": (300, 1000), "sizes_3d": (300, 1000), "loop_contacts": 50}},
    "sparse_vs_dense": {"QUICK": {"sizes_2d": (40, 80), "sizes_3d": (32,)}},
    "scaling": {"QUICK": {"sizes_2d": (300, 600), "dense_reference": 100}},
    "field": {"QUICK": {"loop_points": 100}},
    "branches": {"QUICK": {"ms": (4, 6), "full_max": 16, "loop_max": 8, "memory_ms": (4, 5), "worst_ms": 3,
                           "sparse": (500, 2), "arpack_max": 2}},
    "leave_out": {"QUICK": {"particles": 200}},
    "scan": {"QUICK": {"sizes": {2: 300}, "sample": 16, "memory": (300, 600)}},   # 3 Dask clusters a size
    "attribution": {"QUICK": {"random": 60}, "DATASIM": Path("no DataSim")},        # 1,024 disks scanned 4 times
    "reading": {"QUICK_SIZES": (300, 1000)},
    "converting": {"QUICK_SIZES": (300, 1000)},       # its quick sizes: test_converting_checks_what_it_converts
    "superquadrics": {"QUICK_SIZES": (500,)},
    "periodic": {"QUICK": {"moduli": (60,)}},         # analyze (700,): its one size, above the dense limit
    "jamming": {"QUICK": {"sizes": {32: 1}}, "BOOTSTRAP": 20},
    "app_load": {"BUSY": 0},
    "sessions": {"SESSIONS": {True: 3}, "WARM": 2, "CLASS": 2},
    "classroom": {"PAGES": {True: 3}, "ANNULUS": {True: 1}, "QUIET_MOVES": {True: 2}, "MOVES": {True: 2}},
    "rigidity": {"QUICK": {"sizes": (200,)}},
    "track": {"QUICK": {"particles": 200, "frames": 2}},
    "frames": {"QUICK": {"frames": 4, "particles": 100}},
    "uncertainty": {"QUICK": {"random": 50}},
}


def smallest(monkeypatch) -> None:
    """Every topic of SMALLEST at those sizes; the browser latency on the pair's page alone; the estimates topic on its
    first three quick cases (the annulus frame in µm, the floppy full path, the low-rank 3D cluster:
    tests/solve/test_plan.py checks all of them as a ratio), its busy processes none."""
    for topic, names in SMALLEST.items():
        module = importlib.import_module(f"granstab_bench.{topic}")
        for name, value in names.items():
            old = getattr(module, name)                     # AttributeError: the topic renamed what is shrunk here
            if isinstance(old, dict):
                assert set(value) <= set(old), (topic, name, sorted(set(value) - set(old)))
                value = {**old, **value}
            monkeypatch.setattr(module, name, value)
    from granstab_bench import browser_latency, estimates
    pair = browser_latency.SCENES["two_particle"]              # the 143-disk page in Chromium: tests/app
    monkeypatch.setattr(browser_latency, "SCENES", {"two_particle": pair})
    quick_cases = estimates.cases(quick=True)[:3]
    monkeypatch.setattr(estimates, "cases", lambda quick=False: quick_cases)
    monkeypatch.setattr(estimates, "busy", lambda n=2: (lambda: None))


@pytest.mark.slow
def test_quick_run_of_every_topic(tmp_path, monkeypatch):
    """Every topic runs against the current core (a renamed core function breaks here, not in a release run) and
    lands in BENCHMARKS.md, its table of contents and results.json; no topic's subprocess failed (a failed size is a
    row saying so, not an error). Each timing is one call (timing.ONCE) at the sizes of SMALLEST: this tests the
    benchmark code, it does not measure."""
    from granstab_bench import timing
    monkeypatch.setattr(timing, "ONCE", True)
    smallest(monkeypatch)
    assert main(["bench", "--quick", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "BENCHMARKS.md").read_text(encoding="utf-8")
    results = json.loads((tmp_path / "docs" / "bench" / "results.json").read_text())
    assert list(results) == list(TOPICS)
    headings = [line[3:] for line in text.splitlines() if line.startswith("## ")]
    assert len(headings) == len(TOPICS) + 1 and headings[-1] == "Using the fast paths"
    assert all(f"- [{h}](#" in text for h in headings)
    children = results["scaling"]["results"]["sizes"] + results["periodic"]["results"]["cases"]
    assert len(children) == 4 and not [d for d in children if "failed" in d]


def test_smallest_sizes_start_no_busy_process(monkeypatch):
    """With SMALLEST (attributes the topics have: a renamed one fails here) the estimates topic starts no process:
    its busy() is a no-op, its cases are three small ones."""
    import subprocess
    smallest(monkeypatch)
    from granstab_bench import branches, estimates
    assert branches.QUICK["ms"] == (4, 6) and branches.QUICK["full_max"] == 16
    monkeypatch.setattr(subprocess, "Popen", lambda *a, **k: pytest.fail("a process was started"))
    estimates.busy()()
    assert [name[:7] for name, _, _ in estimates.cases(quick=True)] == ["annulus", "150 dis", "3D clus"]


# ----------------------------------------------------------------------------------------------- the writer
# GitHub's own anchors, as github.com/Flet/github-slugger recorded them from a gist GitHub rendered (test/fixtures.json
# there), and the brief's example; the last two apply the per-category rules recorded the same way (Other_Number
# "²³¹…⁶…" and Math_Symbol are dropped, Open/Close_Punctuation too).
GITHUB_ANCHORS = [
    ("Scan: 1 → 2 workers", "scan-1--2-workers"),
    ("heading with a period.txt", "heading-with-a-periodtxt"),
    ("exchange.bind_headers(exchange, routing [, bindCallback])", "exchangebind_headersexchange-routing--bindcallback"),
    ("heading with an _ underscore", "heading-with-an-_-underscore"),
    ("I ♥ unicode", "i--unicode"),
    ("en–dash", "endash"),
    ("😄 - an emoji", "---an-emoji"),
    ("Привет non-latin 你好", "привет-non-latin-你好"),
    ("apostrophe’s should be trimmed", "apostrophes-should-be-trimmed"),
    (" a ", "-a-"),
    ("λ⁽⁶⁾ field over a 200×200 grid", "λ-field-over-a-200200-grid"),
    ("The metric family: cost and robustness (issue 11)", "the-metric-family-cost-and-robustness-issue-11"),
]


@pytest.mark.parametrize(("heading", "anchor"), GITHUB_ANCHORS)
def test_slug_is_githubs_anchor(heading, anchor):
    assert slug(heading) == anchor


def test_repeated_anchors_are_numbered_as_on_github():
    """github-slugger's fixture sequence: a repeat gets -1, -2, …, also where a heading's own anchor ends so."""
    anchor = Slugger()
    assert [anchor(h) for h in ("echo", "echo", "echo 1", "echo-1", "echo")] == [
        "echo", "echo-1", "echo-1-1", "echo-1-2", "echo-2"]


def fake_meta(topic: str, stamp: str) -> dict:
    """A run's metadata as runner.run_topic makes it, with values that could not come from a real run."""
    machine = {"cpu": "Test CPU", "cores": 3, "memory": "1 GiB", "os": "TestOS", "python": "3.x", "numpy": "n",
               "scipy": "s", "blas": "b", "gpu": "none"}
    return {"date": stamp, "quick": False, "machine": machine, "cpus": 3, "load_start": 1.25, "load_end": 2.5,
            "blas_threads": "BLAS threads: the library default", "seconds": 7.0}


def fake_topics(monkeypatch, stamp: str, titles: dict | None = None) -> None:
    """runner.run_topic replaced by fake results: each topic's section says `stamp` (nothing is timed)."""
    titles = titles or {}

    def run_topic(topic, quick, device, figdir):
        title = titles.get(topic, f"Topic {topic}: 1 → 2")
        text = f"## {title}\n\nResult of {topic} at {stamp}.\n\n| way | time | error |\n|---|---|---|\n| a | 1 s | 1e-16 |"
        return {"value": stamp}, text, fake_meta(topic, stamp)
    monkeypatch.setattr(runner, "run_topic", run_topic)


def blocks_of(text: str) -> dict:
    """Each topic's block as the file holds it, marker to marker."""
    starts = list(MARKER_LINE.finditer(text))
    return {m.group(1): text[m.start():end] for m, end in zip(starts, [s.start() for s in starts[1:]] + [len(text)])}


def test_every_topic_writes_the_whole_file(tmp_path, monkeypatch):
    fake_topics(monkeypatch, "T1")
    path = runner.run(out=tmp_path)
    text = path.read_text(encoding="utf-8")
    blocks = blocks_of(text)
    assert list(blocks) == [*TOPICS, "usage"]
    for topic in TOPICS:
        assert f"Result of {topic} at T1." in blocks[topic]
        assert ("Run T1 by `granstab bench` in 7 s on Test CPU, 3 CPUs, 1 GiB" in blocks[topic]
                and "1-minute load average 1.25 at the start and 2.50 at the end, on 3 CPUs." in blocks[topic])
    assert "Run " not in blocks["usage"] and "```python" in blocks["usage"]
    stored = json.loads((tmp_path / "docs" / "bench" / "results.json").read_text())
    assert list(stored) == list(TOPICS) and stored["scan"] == {"run": {**fake_meta("scan", "T1"),
                                                                        "command": "granstab bench"},
                                                               "results": {"value": "T1"}}


def test_a_rerun_rewrites_only_its_section(tmp_path, monkeypatch):
    """`--only scan --only field` after a whole run: those two sections carry the new run (its date and command),
    every other section and the head stay byte for byte, and results.json keeps the other topics."""
    fake_topics(monkeypatch, "T1")
    path = runner.run(out=tmp_path)
    before = path.read_text(encoding="utf-8")
    stored_before = json.loads((tmp_path / "docs" / "bench" / "results.json").read_text())
    fake_topics(monkeypatch, "T2")
    runner.run(out=tmp_path, only=["scan", "field"])
    after = path.read_text(encoding="utf-8")
    old, new = blocks_of(before), blocks_of(after)
    assert list(new) == list(old)
    for topic in old:
        if topic in ("scan", "field"):
            assert f"Result of {topic} at T2." in new[topic] and "at T1" not in new[topic]
            assert "Run T2 by `granstab bench --only scan --only field`" in new[topic]
        else:
            assert new[topic] == old[topic]
    assert after[:after.index("<!-- section:")] == before[:before.index("<!-- section:")]
    stored = json.loads((tmp_path / "docs" / "bench" / "results.json").read_text())
    assert {t: stored[t] == stored_before[t] for t in TOPICS} == {t: t not in ("scan", "field") for t in TOPICS}


def test_the_gpu_file_is_written_and_rerun_the_same_way(tmp_path, monkeypatch):
    fake_topics(monkeypatch, "G1")
    path = runner.run(out=tmp_path, device="gpu")
    assert path.name == "BENCHMARKS-gpu.md" and not (tmp_path / "BENCHMARKS.md").exists()
    before = blocks_of(path.read_text(encoding="utf-8"))
    assert list(before) == list(runner.GPU_TOPICS)
    assert all("by `granstab bench --device gpu`" in b for b in before.values())
    fake_topics(monkeypatch, "G2")
    runner.run(out=tmp_path, device="gpu", only=["scan"])
    after = blocks_of(path.read_text(encoding="utf-8"))
    assert after["branches"] == before["branches"] and "Result of scan at G2." in after["scan"]
    assert "--device gpu --only scan" in after["scan"]
    stored = json.loads((tmp_path / "docs" / "bench" / "results-gpu.json").read_text())
    assert stored["branches"]["results"] == {"value": "G1"} and stored["scan"]["results"] == {"value": "G2"}


def test_table_of_contents_links_resolve_to_their_headings(tmp_path, monkeypatch):
    """Every entry of the table of contents links to the anchor GitHub gives the heading of the same text,
    numbered over every heading of the file (two sections of one title, a third heading inside a section)."""
    titles = {"scan": "Scan: 1 → 2 workers", "field": "λ⁽⁶⁾ field over a 200×200 grid", "reading": "Same title",
              "converting": "Same title"}
    fake_topics(monkeypatch, "T", titles)
    text = runner.run(out=tmp_path).read_text(encoding="utf-8")
    anchor = Slugger()
    targets = {anchor(title): title for _, title in headings(text)}
    links = re.findall(r"^- \[(.+)\]\(#([^)]*)\)", text, re.M)
    assert len(links) == len(TOPICS) + 1
    assert all(targets.get(target) == title for title, target in links)
    assert ("Scan: 1 → 2 workers", "scan-1--2-workers") in links and ("Same title", "same-title-1") in links


def test_a_rerun_refuses_a_file_it_did_not_write(tmp_path, monkeypatch, capsys):
    """A BENCHMARKS.md without section markers (written by hand or by an older writer) is not partly rewritten:
    one line, exit 2, the file unchanged, before any topic runs."""
    old = "# granstab benchmarks\n\n## Assembly\n\nhand-patched\n"
    (tmp_path / "BENCHMARKS.md").write_text(old)
    monkeypatch.setattr(runner, "run_topic", lambda *a: pytest.fail("a topic ran"))
    with pytest.raises(NotGenerated):
        runner.run(out=tmp_path, only=["assembly"])
    assert main(["bench", "--only", "assembly", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no section markers" in err and "BENCHMARKS.md" in err
    assert (tmp_path / "BENCHMARKS.md").read_text() == old


def test_a_topics_run_line_is_measured(monkeypatch, tmp_path):
    """run_topic measures the load (os.getloadavg at the start and the end) and the run time around the topic."""
    topic = types.ModuleType("granstab_bench.fake_topic")
    topic.run = lambda quick=False: {"quick": quick}
    topic.markdown = lambda results: "## Fake\n\nbody"
    monkeypatch.setitem(sys.modules, "granstab_bench.fake_topic", topic)
    loads = iter([(0.5, 0.0, 0.0), (4.0, 0.0, 0.0)])
    monkeypatch.setattr("os.getloadavg", lambda: next(loads))
    results, text, meta = runner.run_topic("fake_topic", True, "cpu", tmp_path)
    assert results == {"quick": True} and text == "## Fake\n\nbody"
    assert (meta["load_start"], meta["load_end"], meta["quick"]) == (0.5, 4.0, True) and meta["seconds"] >= 0
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", meta["date"])


def test_usage_names_exist():
    """The code closing BENCHMARKS.md names modules and functions that exist."""
    code = runner.USAGE.split("```python")[1].split("```")[0]
    namespace: dict = {}
    exec("\n".join(line for line in code.splitlines() if line.startswith(("import", "from"))), namespace)
    for name in ("packings.random_packing", "packings.lattice", "sparse.lowest_modes", "sparse.sparse_problem",
                 "sparse.DENSE_MAX_DOF", "granstab.analyze"):
        module, attr = name.split(".")
        assert hasattr(namespace[module], attr), name


def test_document_reads_back_what_it_wrote(tmp_path):
    doc = Document("cpu", static="## Static\n\ncode")
    doc.put("scan", "## Scan\n\nbody", {**fake_meta("scan", "D"), "command": "granstab bench"})
    text = doc.render(TOPICS)
    (tmp_path / "B.md").write_text(text)
    again = Document.read(tmp_path / "B.md", "cpu", static="## Static\n\ncode")
    assert again.blocks == doc.blocks and again.render(TOPICS) == text


def test_run_line_without_a_recorded_run_time():
    """Sections carried over from a run that recorded only its total time (the GPU run of 2026-11-24) say no time."""
    from granstab_bench.document import run_line
    meta = {**fake_meta("scan", "D"), "command": "granstab bench --device gpu"}
    assert "by `granstab bench --device gpu` in 7 s on" in run_line(meta)
    assert "by `granstab bench --device gpu` on Test CPU" in run_line({**meta, "seconds": None})


def test_periodic_goal_says_by_how_much_it_was_missed():
    """The periodic section's goal column (fed fake numbers, nothing timed): a case at the goal's size that is too
    slow and too large says by what factor and by how many MB; a met one says met; another size is not judged."""
    from granstab_bench.periodic import _goal
    case = {"kind": "analyze", "particles": 99_960, "t_scene": 2.0, "t_run": 58.0, "peak_mb": 3072.0}
    assert _goal(case) == "missed (≤ 20 s, ≤ 2.5 GB): time 60 s, 3.0× the goal; memory 3072 MB, 512 MB (20%) over"
    assert _goal({**case, "t_run": 10.0, "peak_mb": 2000.0}) == "met (≤ 20 s, ≤ 2.5 GB)"
    assert _goal({**case, "t_run": 10.0}).endswith("memory 3072 MB, 512 MB (20%) over")
    assert _goal({**case, "particles": 10_044}) == "—"
