"""The rooms of the house (docs/design.md): arrows between rooms only go down, no import cycles in the core (lazy
imports counted), the core never imports the explorer (`granstab_app`, viser) nor the benchmarks, and only the
CLI's reproduce command imports the report writers."""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

from helpers import ROOT  # noqa: E402

PACKAGE = ROOT / "granstab"
FORBIDDEN = ("app", "granstab_app", "viser", "benchmarks", "granstab_bench")   # top-level packages the core never loads
#: the rooms from the bottom up: a module may import its own room and the rooms before it, never one after it
ROOMS = (("model",), ("io", "mechanics"), ("solve",), ("analysis", "moduli", "uncertainty", "vertices", "moves"), ("__init__",),
         ("scan", "paper", "rigidity"), ("track",), ("export",), ("cli", "cli_text", "cli_options"),
         ("__main__",))
REPORT_WRITERS = ("granstab.paper.examples", "granstab.paper.markdown", "granstab.paper.figures")


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def module_level(tree: ast.Module):
    """The statements run at import time: the module's body and its if/try blocks, not function bodies."""
    todo = list(tree.body)
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, (ast.If, ast.Try)):
            todo += node.body + node.orelse + getattr(node, "finalbody", []) + [
                s for h in getattr(node, "handlers", []) for s in h.body]


def imported_modules(name: str, path: Path, lazy: bool = True) -> set[str]:
    """Every module `name` imports at module level, and with `lazy` inside functions too."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    for node in (ast.walk(tree) if lazy else module_level(tree)):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            names = {f"{base}.{alias.name}" for alias in node.names}
            out |= names                      # `from . import x` imports the module x, not more of its package
            if not names <= set(MODULES):     # a name defined in `base` needs `base` itself
                out.add(base)
    return out


def internal_graph(lazy: bool = True) -> dict[str, set[str]]:
    """Edges between granstab's own modules. Importing a.b.c also runs a and a.b: edges too, except to the
    importer's own packages, which Python has already started (an explicit `import granstab` is an edge)."""
    graph = {}
    for name, path in MODULES.items():
        explicit = imported_modules(name, path, lazy)
        implied = {".".join(imp.split(".")[:i]) for imp in explicit for i in range(1, imp.count(".") + 1)}
        implied = {t for t in implied if not name.startswith(t + ".")}
        graph[name] = {t for t in explicit | implied if t in MODULES and t != name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the directed graph as a list of nodes (first = last), or None (depth-first search)."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_cycle_finder_finds_a_planted_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert find_cycle(graph) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "d": {"a", "b"}}) is None


def test_graph_sees_relative_and_lazy_imports():
    graph, eager = internal_graph(), internal_graph(lazy=False)
    assert "granstab.model.errors" in eager["granstab.model.scene"]        # from .reading import ...
    assert "granstab.model.scene" in eager["granstab.model.shapes"]
    assert "granstab" in eager["granstab.paper.gear"]          # import granstab
    assert "granstab.paper" in graph["granstab.cli"] - eager["granstab.cli"]   # inside cmd_reproduce()


def test_no_import_cycles_among_module_level_imports():
    """A module-level cycle makes `import` of a module fail or see a half-built one, depending on the order."""
    assert find_cycle(internal_graph(lazy=False)) is None


def test_no_import_cycles_counting_lazy_imports():
    """An import inside a function that only dodges a cycle is still a cycle: two modules that need each other."""
    assert find_cycle(internal_graph()) is None


def room_of(module: str) -> int:
    """The level of a module's room in ROOMS (granstab itself is the facade, `__init__`)."""
    part = module.split(".")[1] if "." in module else "__init__"
    return next(i for i, names in enumerate(ROOMS) if part in names)


def test_every_module_lives_in_a_room():
    assert {m.split(".")[1] for m in MODULES if "." in m} <= {n for names in ROOMS for n in names}


def test_arrows_between_rooms_only_go_down():
    """Lazy imports counted: a room never imports a room above it (the design document's picture)."""
    up = sorted(f"{a} -> {b}" for a, targets in internal_graph().items() for b in targets
                if room_of(b) > room_of(a))
    assert not up, up


def test_room_checker_sees_an_upward_arrow():
    assert room_of("granstab.mechanics.branches") < room_of("granstab.solve.threads")
    assert room_of("granstab.model.scene") < room_of("granstab.io.schema") == room_of("granstab.mechanics.rigid")


def test_core_never_imports_the_explorer_or_benchmarks_and_only_paper_the_report_writers():
    """No core module (the CLI included: `granstab publish` and `bench` come from entry points, cli_options.PLUGINS)
    imports the explorer or the benchmarks, even inside a function; the report writers (matplotlib) are imported
    inside the paper room only (`granstab reproduce` reaches them through granstab.paper.reproduce)."""
    for name, path in MODULES.items():
        imports = imported_modules(name, path)
        assert not any(i.split(".")[0] in FORBIDDEN for i in imports), name
        if not name.startswith("granstab.paper"):
            assert not any(i in REPORT_WRITERS or (i.startswith("granstab.paper.") and i.endswith("_report"))
                           for i in imports), name


def test_the_import_check_sees_a_lazy_import_of_the_explorer(tmp_path):
    path = tmp_path / "m.py"
    path.write_text("def f():\n    from granstab_app.publish import publish\n", encoding="utf-8")
    assert "granstab_app.publish" in imported_modules("granstab.m", path)


def test_importing_every_core_module_loads_no_app_viser_or_benchmarks():
    """A fresh interpreter imports granstab and every module of it (the CLI and the report writers included;
    __main__ would run the CLI); `-X importtime` lists every module that was loaded."""
    names = sorted(name for name in MODULES if name != "granstab.__main__")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-X", "importtime", "-c", "import " + ", ".join(names)],
                          capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr.strip().splitlines()[-1]
    loaded = {line.rsplit("|", 1)[-1].strip() for line in proc.stderr.splitlines() if line.startswith("import time:")}
    assert set(names) <= loaded and "numpy" in loaded                # the listing is complete
    leaked = sorted(m for m in loaded if m.split(".")[0] in FORBIDDEN)
    assert not leaked, f"importing the core loads {leaked}"
