"""Run the topics of `TOPICS` and write BENCHMARKS.md (rewritten after every topic, so results stream in), the
figures in docs/bench/ and every topic's results and run in docs/bench/results.json (benchmarks/document.py
writes the file)."""
from __future__ import annotations

import importlib
import inspect
import json
import os
import sys
import time
from pathlib import Path

from granstab.solve.threads import blas_threads

from . import TOPICS
from .document import Document
from .machine import load_now, machine

QUICK_BLAS_THREADS = 1   # --quick: every problem is small, and a BLAS pool on a busy 2-core machine costs 10-100×

USAGE = """\
## Using the fast paths

```python
import granstab
from granstab.model import packings
from granstab.solve import sparse

scene = packings.random_packing(3, 100_000)            # or lattice(dim, size); valid contact data, equilibrium loads
result = granstab.analyze(scene)                       # method="auto": dense up to sparse.DENSE_MAX_DOF dofs, else
                                                       # the lowest k = 6 eigenpairs per branch (warnings say so)
result = granstab.analyze(scene, method="sparse", k=10, progress=True, on_branch=print)   # streamed, tqdm bar
modes = sparse.lowest_modes(sparse.sparse_problem(scene), k=6, method="auto")  # shift-invert | lobpcg
modes.eigenvalues, modes.vectors, modes.residuals, modes.verified              # verified: inertia check passed
```

The sparse path leaves out the uniqueness analysis (spectra of ℍ, Type-2): each branch's `uniqueness_n_zero` is -1
there.
"""


GPU_TOPICS = ("branches", "scan", "million")   # the topics that measure the GPU beside the CPU wherever CuPy sees one


FILES = {"cpu": ("BENCHMARKS.md", "results.json"), "gpu": ("BENCHMARKS-gpu.md", "results-gpu.json")}


def command(quick: bool, only, device: str) -> str:
    """The command line that runs these topics (it stands in each section's run line)."""
    return " ".join(["granstab bench", *(["--quick"] if quick else []), *(["--device gpu"] if device == "gpu" else []),
                     *(f"--only {t}" for t in only or ())])


def run_topic(topic: str, quick: bool, device: str, figdir: Path) -> tuple[dict, str, dict]:
    """Run one topic, draw its figures; its results, its Markdown section and the run's metadata (date, run time,
    machine, 1-minute load average at the start and end, CPUs)."""
    module = importlib.import_module(f"{__package__}.{topic}")
    meta = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "quick": quick, "machine": machine(),
            "cpus": os.cpu_count(), "load_start": load_now(),
            "blas_threads": f"{QUICK_BLAS_THREADS} BLAS thread" if quick else "BLAS threads: the library default"}
    t = time.perf_counter()
    with blas_threads(QUICK_BLAS_THREADS if quick else None):     # after the import: limits loaded libraries
        results = (module.run(quick, device=device) if "device" in inspect.signature(module.run).parameters
                   else module.run(quick))
    meta.update(seconds=time.perf_counter() - t, load_end=load_now())
    if hasattr(module, "plot"):
        module.plot(results, figdir)
    return results, module.markdown(results), meta


def run(quick: bool = False, out: Path = Path("."), only=None, device: str = "cpu") -> Path:
    """Run the topics (all, or those named in `only`), draw their figures into `out`/docs/bench and write their
    sections: every topic writes BENCHMARKS.md whole; `only` rewrites those topics' sections of the existing file
    and keeps the others byte for byte (results.json likewise). device="gpu": the GPU topics (GPU_TOPICS, or
    `only`) into BENCHMARKS-gpu.md and results-gpu.json. The file is written after every topic."""
    unknown = sorted(set(only or ()) - set(TOPICS))
    if unknown:
        raise ValueError(f"unknown benchmark topic {unknown[0]!r} (choose from {', '.join(TOPICS)})")
    topics = [t for t in TOPICS if t in (only or (GPU_TOPICS if device == "gpu" else TOPICS))]
    name, results_name = FILES[device]
    path, results_path = Path(out) / name, Path(out) / "docs" / "bench" / results_name
    figdir = results_path.parent
    figdir.mkdir(parents=True, exist_ok=True)
    static = USAGE if device == "cpu" else None
    whole = only is None
    doc = Document(device, static=static) if whole else Document.read(path, device, static=static)
    stored = {} if whole or not results_path.exists() else json.loads(results_path.read_text())
    line = command(quick, only, device)
    for topic in topics:
        results, text, meta = run_topic(topic, quick, device, figdir)
        meta["command"] = line
        doc.put(topic, text, meta)
        stored[topic] = {"run": meta, "results": results}
        path.write_text(doc.render(TOPICS), encoding="utf-8")
        results_path.write_text(json.dumps(stored, indent=1, default=float))
        print(f"[bench] {topic}: {meta['seconds']:.1f} s -> {path}", file=sys.stderr)
    return path
