"""`granstab bench`: the benchmarks' command in the `granstab` CLI, registered through the entry-point group
`granstab.commands` (pyproject.toml) so that the core never imports the benchmarks."""
from __future__ import annotations

from pathlib import Path

from granstab.cli_options import InputError


def add(sub) -> None:
    p = sub.add_parser("bench", help="error against run time; writes BENCHMARKS.md and plots",
                       description="Every topic: writes BENCHMARKS.md whole (and docs/bench/). --only TOPIC: reruns "
                                   "that topic and rewrites its section alone, each section with its own date, "
                                   "machine and load.")
    p.add_argument("--quick", action="store_true", help="small sizes and few repeats (under a minute)")
    p.add_argument("--out", default=".")
    p.add_argument("--only", action="append", metavar="TOPIC",
                   help="rerun only this topic (repeatable; choose from granstab_bench.TOPICS): its section of the "
                        "existing BENCHMARKS.md is rewritten, the others are kept byte for byte")
    p.add_argument("--device", choices=["cpu", "gpu"], default="cpu",
                   help="gpu: the GPU topics (branches, scan, million: GPU beside CPU) into BENCHMARKS-gpu.md")
    p.set_defaults(run=cmd_bench)


def cmd_bench(args) -> int:
    from granstab.solve.device import gpu_available

    from .document import NotGenerated
    from .runner import TOPICS, run
    unknown = sorted(set(args.only or ()) - set(TOPICS))
    if unknown:
        raise InputError(f"--only: unknown topic {unknown[0]!r} (choose from {', '.join(TOPICS)})")
    if args.device == "gpu" and not gpu_available():
        raise InputError("--device gpu: needs CuPy and a CUDA GPU (pip install 'granstab[gpu]'); without one the "
                         "CPU benchmarks are `granstab bench`")
    try:
        run(quick=args.quick, out=Path(args.out), only=args.only, device=args.device)
    except NotGenerated as exc:
        raise InputError(str(exc)) from None
    return 0
