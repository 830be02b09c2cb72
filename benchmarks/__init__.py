"""`granstab bench`: every fast path against its obvious alternative, measured side by side in one run.

Outside the core package: the core never imports this package (it may import granstab_app/ for the app latency).
Contract of a topic: a module `benchmarks/<topic>.py` with `run(quick: bool = False) -> dict` (optionally with a
`device` keyword, which `granstab bench --device gpu` passes; JSON-able results: medians, ratios and errors side by
side) and `markdown(results: dict) -> str` (its BENCHMARKS.md section, starting
with its "## " heading), optionally `plot(results: dict, figdir: Path)` for its figures in docs/bench/; listed in
`TOPICS` in report order. `granstab_bench.runner.run` (what `granstab bench` calls) writes BENCHMARKS.md.
"""

TOPICS = ("assembly", "sparse_vs_dense", "scaling", "field", "branches", "app_latency", "accuracy", "leave_out",
          "metrics", "packing300", "scan", "attribution", "reading", "converting", "superquadrics", "periodic", "jamming",
          "browser_latency", "app_load", "sessions", "classroom", "rigidity", "track", "track_lammps", "calibration", "frames", "estimates", "uncertainty",
          "scale", "million")
