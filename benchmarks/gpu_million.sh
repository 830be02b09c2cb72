#!/bin/bash
# Fill BENCHMARKS-gpu.md `million` (issue 41) in one go on a lent GPU machine (≤ 8 min in all). From the repository
# root, through the device tool's `run` (its image has CuPy, numpy and scipy; nothing can be fetched there):
#
#     run(command="bash benchmarks/gpu_million.sh", timeout_s=540)
#
# 1. the GPU tests (tests/solve/test_blockiter.py: LOBPCG on the device against the CPU, ~1 min);
# 2. `granstab bench --device gpu --only million`: the periodic benchmark's packing of 10⁶ disks (one contact at
#    yield: 2 branches) by solve/blockiter.py on the GPU, and by the shift-invert path on this host's CPU, with the
#    residuals, bounds and counts of both (~1 min for the packing, the CPU leg ~4-6 min, the GPU leg ≤ 1 min).
# What comes back under $OUT: BENCHMARKS-gpu.md and results-gpu.json (copy them over the repository's), the logs.
# Without a GPU it stops at once, saying so.
set -o pipefail
OUT=${OUT:-/tmp/gpu_million}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
python3 -m pip install -q --no-deps --no-build-isolation --no-index -e . >"$OUT/install.log" 2>&1 \
  || { echo "pip install -e . failed (see install.log)"; exit 2; }
python3 -c "from granstab.solve.device import gpu_available as g; import sys; sys.exit(0 if g() else 3)" \
  || { echo "no GPU seen by CuPy: nothing to measure"; exit 3; }
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv | tee "$OUT/gpu.txt"
timeout 150 python3 -m pytest -q -p no:cacheprovider -rs tests/solve/test_blockiter.py 2>&1 | tee "$OUT/tests.log"
timeout 420 python3 -m granstab bench --device gpu --only million 2>&1 | tee "$OUT/bench.log"
cp BENCHMARKS-gpu.md docs/bench/results-gpu.json "$OUT/" 2>/dev/null
echo "done: $(ls "$OUT")"
