"""One array namespace for the stacked eigenproblems (numpy on the CPU, CuPy on a GPU).

The two places where granstab solves many small symmetric eigenproblems — the 2^Ms loading branches of a cluster
(lowrank.py, ritz.py) and the clusters of a scan (scan/batch.py) — write their stacked arithmetic against `backend.xp` (array-API style:
`xp.linalg.eigh`, `xp.matmul`, ...), so the same code runs on numpy or on CuPy. The rest of the core stays
numpy/scipy. CuPy is the optional extra `.[gpu]` (cupy-cuda12x; `.[gpu-cuda13]`: cupy-cuda13x); `device="gpu"`
without it is a one-line error.

Stacks are cut into chunks that fit the device (CPU: CHUNK_BYTES of working arrays; GPU: half its free memory),
and only what the caller keeps (eigenvalues, residual norms, selected columns) comes back to the host.

Achieved accuracy: for every eigenpair the residual norm ‖A v − λ v‖₂ (v unit) is computed on the device; a
symmetric A has an eigenvalue within that distance of λ (Bauer-Fike for normal matrices), so it is an
absolute error bound per eigenvalue, valid whatever solver the device used (LAPACK syevd on the CPU, batched
Jacobi on the GPU, which is ~1e-14 relative rather than 1e-16).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .threads import sized

DEVICES = ("cpu", "gpu", "auto")
CHUNK_BYTES = 64 * 2 ** 20   # CPU working set of one chunk (its matrices and eigenvectors)
GPU_FRACTION = 0.5           # of the free device memory for one chunk (cuSOLVER needs workspace besides)


class DeviceError(ValueError):
    """A device that cannot be used (no CuPy, no GPU, unknown name): one line for the CLI."""


def _cupy():
    """CuPy with a usable device, or None."""
    try:
        import cupy
        if cupy.cuda.runtime.getDeviceCount() < 1:
            return None
        return cupy
    except Exception:  # ImportError, or CUDA runtime errors when the driver is missing
        return None


def gpu_available() -> bool:
    """True when CuPy is installed and sees at least one GPU."""
    return _cupy() is not None


@dataclass(frozen=True, eq=False)
class Backend:
    """An array namespace `xp` with its device name, transfers and chunk sizes."""

    name: str
    xp: object

    def asarray(self, a):
        """Host array → device array (float64)."""
        return self.xp.asarray(a, dtype=self.xp.float64)

    def to_host(self, a) -> np.ndarray:
        """Device array → numpy array."""
        return a.get() if hasattr(a, "get") else np.asarray(a)

    def chunk(self, per_item_bytes: float, total: int) -> int:
        """How many items of `per_item_bytes` working memory one chunk holds (at least 1, at most total)."""
        if self.name == "gpu":
            free, _ = self.xp.cuda.runtime.memGetInfo()
            budget = GPU_FRACTION * free
        else:
            budget = CHUNK_BYTES
        return int(max(1, min(total, budget // max(per_item_bytes, 1))))

    def threads(self, n: int):
        """BLAS threads for work on n×n matrices (threads.py); the GPU needs none."""
        from contextlib import nullcontext
        return sized(n) if self.name == "cpu" else nullcontext()

    @property
    def eps(self) -> float:
        return float(np.finfo(np.float64).eps)


def backend(device: str = "cpu") -> Backend:
    """The Backend for "cpu", "gpu" (CuPy and a GPU, else DeviceError) or "auto" (GPU when present)."""
    if device not in DEVICES:
        raise DeviceError(f"device must be one of {', '.join(DEVICES)}, got {device!r}")
    if device == "cpu":
        return Backend("cpu", np)
    cp = _cupy()
    if cp is None:
        if device == "gpu":
            raise DeviceError("device 'gpu' needs CuPy and a CUDA GPU: pip install 'granstab[gpu]' (CUDA 12) or "
                              "'granstab[gpu-cuda13]' (CUDA 13) on a machine with one, or use --device cpu")
        return Backend("cpu", np)
    return Backend("gpu", cp)


def residual_norms(xp, A, lam, V):
    """‖A v_j − λ_j v_j‖₂ for every eigenpair of a stack A (L, n, n): (L, n) absolute error bounds (module doc)."""
    R = xp.matmul(A, V) - V * lam[:, None, :]
    return xp.sqrt(xp.sum(R * R, axis=1))


def eigh_stack(stack, device: str = "cpu", keep=None, symmetric: bool = False):
    """Eigen-decompose a stack of symmetric matrices (L, n, n) on `device`, in chunks that fit it (symmetrised first,
    unless `symmetric`: the caller's matrices are exactly symmetric already).

    keep(xp, A, lam, V, start) → dict of device arrays: what to bring back per chunk (default: eigenvalues "lam",
    eigenvectors "V" and the per-pair residual norms "residual", see `residual_norms`). Returns a dict of numpy
    arrays concatenated over the chunks, plus "device" (the name used) and "eps" (its unit round-off).
    """
    be = backend(device)
    stack = np.asarray(stack)
    L, n = stack.shape[0], stack.shape[-1]
    size = be.chunk(8.0 * n * n * 4, L)                      # the matrices, vectors, a product and its residual
    keep = keep or _keep_all
    parts: dict[str, list] = {}
    with be.threads(n):
        for start in range(0, L, size):
            A = be.asarray(stack[start:start + size])
            if not symmetric:
                A = 0.5 * (A + be.xp.swapaxes(A, 1, 2))
            lam, V = be.xp.linalg.eigh(A)
            for key, value in keep(be.xp, A, lam, V, start).items():
                parts.setdefault(key, []).append(be.to_host(value))
    out = {key: np.concatenate(value) for key, value in parts.items()}
    out.update(device=be.name, eps=be.eps)
    return out


def _keep_all(xp, A, lam, V, start):
    return {"lam": lam, "V": V, "residual": residual_norms(xp, A, lam, V)}
