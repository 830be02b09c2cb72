"""The house's structure (docs/design.md): rooms as subpackages, short functions, installed names of our own, no
tracked build artefacts. Import arrows between rooms are checked in test_imports.py."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from helpers import ROOT  # noqa: E402

MAX_TOP_MODULES = 10        # modules directly in granstab/: the facade, the CLI, the pipeline; the rest lives in rooms
MAX_FUNCTION_LINES = 100    # a function longer than this does more than one thing (benchmarks, tests)
#: the core and the explorer (granstab/, app/): a function, a class and a module longer than this do more than one job
CORE_LIMITS = {"function": 80, "class": 300, "module": 600}
MAX_TRACKED_BYTES = 2**20   # a larger tracked file is data or a build artefact (figures and test data stay below)
MAX_PAGE_BYTES = 5 * 2**20  # a published teaching page (examples/pages/*.html: viser's client + a recording), issue 29
PAGES = Path("examples") / "pages"
ARTEFACTS = (".whl", ".egg", ".so", ".pyc", ".tar.gz", ".zip")


def test_few_modules_directly_in_the_package():
    top = sorted(p.name for p in (ROOT / "granstab").glob("*.py"))
    assert len(top) <= MAX_TOP_MODULES, top


def long_functions(paths) -> list[str]:
    """`file:line name (n lines)` for every function or method over MAX_FUNCTION_LINES lines."""
    out = []
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    out.append(f"{path}:{node.lineno} {node.name} ({n} lines)")
    return out


def test_no_function_longer_than_the_limit():
    sources = [p for d in ("granstab", "app", "benchmarks", "tests") for p in sorted((ROOT / d).rglob("*.py"))]
    assert len(sources) > 50
    assert not long_functions(sources)


def test_the_length_check_sees_a_long_function(tmp_path):
    path = tmp_path / "long.py"
    for extra, found in ((0, 0), (1, 1)):        # MAX_FUNCTION_LINES lines pass, one more is reported
        body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES - 2 + extra))
        path.write_text(f"def f():\n    \"\"\"Doc.\"\"\"\n{body}\n", encoding="utf-8")
        assert len(long_functions([path])) == found


def oversized(paths, limits=CORE_LIMITS) -> list[str]:
    """`file:line kind name (n lines)` for every module, class, function or method longer than its limit."""
    out = []
    for path in paths:
        text = path.read_text(encoding="utf-8")
        if len(text.splitlines()) > limits["module"]:
            out.append(f"{path} module ({len(text.splitlines())} lines)")
        for node in ast.walk(ast.parse(text)):
            kind = ("function" if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else
                    "class" if isinstance(node, ast.ClassDef) else None)
            n = kind and node.end_lineno - node.lineno + 1
            if kind and n > limits[kind]:
                out.append(f"{path}:{node.lineno} {kind} {node.name} ({n} lines)")
    return out


def test_no_module_function_or_class_over_the_limits_in_the_core_and_the_explorer():
    sources = [p for d in ("granstab", "app") for p in sorted((ROOT / d).rglob("*.py"))]
    assert len(sources) > 100
    assert not oversized(sources)


def test_the_size_check_sees_a_long_module_class_and_function(tmp_path):
    path = tmp_path / "big.py"
    limits = {"function": 4, "class": 6, "module": 9}
    path.write_text("class A:\n    def f(self):\n        a = 1\n        b = 2\n        return a + b\n", encoding="utf-8")
    assert oversized([path], limits) == []                               # 5 lines: every limit kept
    path.write_text("class A:\n    def f(self):\n        a = 1\n        b = 2\n        c = 3\n        return a\n"
                    "\n    x = 1\n", encoding="utf-8")
    assert [line.split(" ", 1)[1] for line in oversized([path], limits)] == ["class A (8 lines)", "function f (5 lines)"]
    path.write_text("x = 1\n" * 10, encoding="utf-8")
    assert oversized([path], limits) == [f"{path} module (10 lines)"]


def test_tests_live_in_folders_per_room():
    """tests/<room>/test_*.py, a folder a room of docs/design.md (and the explorer, the benchmarks, the house);
    tests/ itself holds only the shared helpers, conftest.py and the data."""
    tests = ROOT / "tests"
    assert not sorted(p.name for p in tests.glob("test_*.py"))
    rooms = {p.parent.name for p in tests.glob("*/test_*.py")}
    assert rooms == {"model", "io", "mechanics", "solve", "analysis", "scan", "rigidity", "track", "export", "paper",
                     "cli", "app", "bench", "house"}, rooms


def tracked_files() -> list[str]:
    proc = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=False)
    if proc.returncode:
        pytest.fail(f"git ls-files failed in {ROOT}: {proc.stderr.decode().strip()}")
    return [name for name in proc.stdout.decode().split("\0") if name]


def test_no_tracked_build_artefacts_or_large_files():
    names = tracked_files()
    assert "pyproject.toml" in names and len(names) > 100
    assert not [n for n in names if n.endswith(ARTEFACTS)]
    limit = {n: MAX_PAGE_BYTES if Path(n).parent == PAGES and n.endswith(".html") else MAX_TRACKED_BYTES for n in names}
    large = [n for n in names if (ROOT / n).is_file() and (ROOT / n).stat().st_size > limit[n]]
    assert not large


def test_every_tour_page_is_shipped_and_self_contained():
    """build.sh's presets are the tour's pages: each one tracked, linked from the README, and self-contained (no
    script, style or image fetched from the network: it opens offline)."""
    presets = re.search(r"for preset in (.*?); do", (ROOT / PAGES / "build.sh").read_text(), re.S).group(1).split()
    presets = [p for p in presets if p != "\\"]
    names, readme = tracked_files(), (ROOT / "README.md").read_text()
    assert len(presets) == 7
    for preset in presets:
        page = f"{PAGES.as_posix()}/{preset}.html"
        assert page in names and f"]({page})" in readme, page
        text = (ROOT / page).read_text()
        assert text.lstrip().lower().startswith("<!doctype html") and "viser" in text.lower(), page
        assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", text), page


@pytest.mark.slow
def test_the_wheel_claims_no_generic_top_level_names(tmp_path):
    """Installed, the explorer and the benchmarks take names of their own: a user's own `app` or `benchmarks`
    module must not collide with ours."""
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                           "-w", str(tmp_path), str(ROOT)], capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    (wheel,) = tmp_path.glob("granstab-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        tops = {name.split("/")[0] for name in zf.namelist() if not name.split("/")[0].endswith(".dist-info")}
        entry_points = next(zf.read(n).decode() for n in zf.namelist() if n.endswith("entry_points.txt"))
    assert tops == {"granstab", "granstab_app", "granstab_bench"}, tops
    assert "granstab-app = granstab_app.server:main" in entry_points
    assert "granstab = granstab.cli:main" in entry_points
    assert "[granstab.commands]" in entry_points                 # publish and bench: the core imports neither
    assert "bench = granstab_bench.command:add" in entry_points and "publish = granstab_app.command:add" in entry_points
