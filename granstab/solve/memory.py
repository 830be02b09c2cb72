"""Peak memory of the sparse path, estimated before it runs, against the memory this machine can give (issue 41):
a whole packing that would not fit is refused in one line with the estimate and the memory it would need, instead
of being killed by the kernel's OOM killer (and taking a shared machine's other work with it).

The parts (bytes; n dofs, M contacts, per = dofs a particle):

* the factor of Hs - σI (shift-invert, sparse.py; multifrontal.py): its stored entries, float64, plus the float32
  copy its preconditioning solves read up to multifrontal.SINGLE_MAX entries (12 bytes an entry, else 8); nested
  dissection fills ~FILL_2D · n log₂ n entries in 2D (measured 13.4 and 13.9 · n log₂ n on periodic packings of
  3·10⁴ and 1.2·10⁵ dofs; 8.07 bytes an estimated entry at 3·10⁶ dofs, float64 only) and ~FILL_3D · n^{4/3} in 3D
  (30 and 37 on random packings of 5·10³ and 2.4·10⁴ dofs: not yet asymptotic, the larger taken with a margin);
* the block Krylov basis and B applied to it (krylov._block_near: 2 × 75 columns, restarted in place, and the
  blocks of a cycle: KRYLOV_COLUMNS float64 columns of n), or LOBPCG's blocks (krylov._lobpcg: ~LOBPCG_COLUMNS);
* everything else per contact entry (the scene, contact blocks, the sparse parts Hs, Hm, A, S, rigid bases, the
  Ritz basis): BASE_PER_ENTRY bytes per contact and per² (the contact's share of Hs's blocks), plus the interpreter
  and its libraries (BASE_BYTES).

Fitted to the periodic benchmark's packing with one contact at yield (benchmarks/million.py, memtrace's phases,
2026-11-29): at 3.0·10⁶ dofs (10⁶ disks) resident 4.83 GB before the factor (the parts), the factor 6.8 GB (8.07
bytes per estimated entry), the block Krylov solve 4.2 GB more (188 columns), peak 15.83 GB; the estimate gives
15.9 GB; at 6.0·10⁵ dofs (2·10⁵ disks) 3.78 GB measured, 3.73 estimated. The memory this machine can give:
MemAvailable (/proc/meminfo), within the process's cgroup limit where one is set, or the environment's
GRANSTAB_MEMORY (bytes, or with a suffix K, M, G: a cap the user sets, e.g. on a machine shared with others)."""
from __future__ import annotations

import math
import os
from pathlib import Path

from .budget import OverBudget
from .multifrontal import SINGLE_MAX

FILL_2D = 14.0            # factor entries per n log₂ n (module docstring)
FILL_3D = 40.0            # factor entries per n^{4/3}
FACTOR_BYTES = 8          # float64 factor, per entry …
SINGLE_BYTES = 4          # … and its float32 copy (multifrontal.SINGLE_MAX)
KRYLOV_COLUMNS = 190      # columns of n float64 held by the block Krylov solve at its peak (X, B·X, a cycle's blocks)
LOBPCG_COLUMNS = 120      # LOBPCG's blocks (X, AX, P, AP, R, AR, M⁻¹R ... of ~10 columns) and its preconditioner
BASE_PER_ENTRY = 190      # bytes per contact and per² for the scene, blocks, sparse parts (module docstring) …
BASE_BYTES = 0.12 * 2 ** 30   # … and the interpreter with numpy and scipy loaded
UNITS = {"": 1, "K": 2 ** 10, "M": 2 ** 20, "G": 2 ** 30, "T": 2 ** 40}


def factor_entries(n: int, dim: int) -> float:
    """Estimated stored entries of the nested-dissection factor of n dofs (module docstring)."""
    return FILL_2D * n * math.log2(max(n, 2)) if dim == 2 else FILL_3D * n ** (4 / 3)


def sparse_peak(n: int, n_contacts: int, dim: int, method: str) -> dict:
    """The sparse path's peak memory by part (bytes; module docstring). method: "shift-invert" or "lobpcg"."""
    per = 3 if dim == 2 else 6
    parts = {"assembly": float(BASE_BYTES + BASE_PER_ENTRY * n_contacts * per * per)}
    if method == "lobpcg":
        parts["lobpcg"] = 8.0 * n * LOBPCG_COLUMNS
    else:
        entries = factor_entries(n, dim)
        parts["factor"] = (FACTOR_BYTES + SINGLE_BYTES * (entries <= SINGLE_MAX)) * entries
        parts["krylov"] = 8.0 * n * KRYLOV_COLUMNS
    return parts


def no_inertia(scene, n: int) -> str:
    """Why a whole packing solved by LOBPCG (3D above sparse.LU_MAX_DOF_3D dofs, or on a GPU) has no inertia count,
    with the memory its factor would need (`factor_entries`, float64)."""
    need = FACTOR_BYTES * factor_entries(n, scene.dim) / 2 ** 30
    return (f"no inertia count, so nothing proves the computed eigenvalues are the lowest: LOBPCG runs without a "
            f"factorisation (the nested-dissection factor of {n} dofs in {scene.dim}D would take about {need:.3g} GB; "
            "its fill grows as n^4/3 in 3D, and the GPU has no sparse factorisation)")


def parse_bytes(text: str) -> int:
    """'2G', '512M', '1073741824' → bytes; budget.OverBudget (one line: the CLI's exit 2) otherwise."""
    t = text.strip().upper().removesuffix("B")
    unit = t[-1:] if t[-1:] in UNITS and not t[-1:].isdigit() else ""
    try:
        value = float(t[:len(t) - len(unit)])
    except ValueError:
        raise OverBudget(f"GRANSTAB_MEMORY: not a size ({text!r}; e.g. 16G, 512M or bytes)") from None
    if not (value > 0 and math.isfinite(value)):
        raise OverBudget(f"GRANSTAB_MEMORY: must be a positive finite size ({text!r})")
    return int(value * UNITS[unit])


def available() -> tuple[int | None, str]:
    """(bytes this process may still take, where that was read): GRANSTAB_MEMORY, else MemAvailable within the
    cgroup's limit; (None, ...) where nothing can be read."""
    cap = os.environ.get("GRANSTAB_MEMORY")
    if cap:
        return parse_bytes(cap), "GRANSTAB_MEMORY"
    found = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                found.append(int(line.split()[1]) * 1024)
    except OSError:
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = Path("/sys/fs/cgroup/memory.current").read_text().strip()
        if limit != "max":
            found.append(int(limit) - int(used))
    except (OSError, ValueError):
        pass
    return (min(found), "MemAvailable") if found else (None, "unknown")


def refusal(source: str, n: int, n_contacts: int, dim: int, method: str) -> tuple[dict, str | None]:
    """The estimate ({"estimated_bytes", "parts", "available_bytes", "available_from"}) and, where it exceeds what
    is available, the one-line refusal (what it needs, what there is, what to do); None where it fits."""
    parts = sparse_peak(n, n_contacts, dim, method)
    need = sum(parts.values())
    have, source_of = available()
    info = {"estimated_bytes": need, "parts": parts, "available_bytes": have, "available_from": source_of,
            "fits": have is None or need <= have}
    if info["fits"]:
        return info, None
    shown = ", ".join(f"{key} {value / 2 ** 30:.2g}" for key, value in parts.items())
    return info, (f"{source}: refused: the sparse path ({method}) of {n} dofs needs about {need / 2 ** 30:.3g} GB at "
                  f"its peak ({shown} GB; the factor's fill grows as n log n in 2D, n^4/3 in 3D), more than the "
                  f"{have / 2 ** 30:.3g} GB available ({source_of}): analyse a region (--region) or local clusters "
                  "(granstab scan), or run it where that much memory is free")
