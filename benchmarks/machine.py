"""The machine a benchmark ran on: CPU, cores, memory, versions, BLAS, GPU, and its load now (a shared machine)."""
from __future__ import annotations

import os
import platform
from pathlib import Path

import numpy as np
import scipy


def load_now() -> float | None:
    """The 1-minute load average now (None where the system has none)."""
    try:
        return os.getloadavg()[0]
    except OSError:
        return None


def _first(path: str, key: str) -> str:
    """The value of the first `key: value` line of a /proc file ('' where there is none)."""
    try:
        for line in Path(path).read_text().splitlines():
            if line.startswith(key):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


def machine() -> dict:
    """CPU, cores, memory, OS, Python, numpy, scipy and BLAS."""
    mem = _first("/proc/meminfo", "MemTotal")
    blas = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
    return {"cpu": _first("/proc/cpuinfo", "model name") or platform.processor(), "cores": os.cpu_count(),
            "memory": f"{int(mem.split()[0]) / 2**20:.0f} GiB" if mem else "", "python": platform.python_version(),
            "numpy": np.__version__, "scipy": scipy.__version__,
            "blas": f"{blas['name']} {blas.get('version', '')}", "os": platform.platform(), "gpu": gpu_name()}


def gpu_name() -> str:
    """The GPU CuPy sees (name, memory, CuPy version), or 'none'."""
    from granstab.solve.device import gpu_available
    if not gpu_available():
        return "none"
    import cupy
    props = cupy.cuda.runtime.getDeviceProperties(0)
    name = props["name"].decode() if isinstance(props["name"], bytes) else props["name"]
    return f"{name}, {props['totalGlobalMem'] / 2 ** 30:.0f} GiB (CuPy {cupy.__version__})"
