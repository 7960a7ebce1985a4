#!/bin/bash
# The heads readback (results/gpu.md, "Where a steady map's GPU time goes"):
# how many instances of the coupling map at 200 x 200 (steady, no baselines)
# end periodic on the CPU, so that the GPU reads back their heads alone; and
# what a steady batch reads back on lavapipe (PIDM_GPU_PHASES=1).
#
#   bash results/heads/run.sh > results/heads/run.txt
set -euo pipefail
pidm=${PIDM:-target/release/pidm}
w=$(mktemp -d)
trap 'rm -rf "$w"' EXIT
sed -e 's/steps = 61/steps = 200/g' -e 's/baselines = true/baselines = false/' sweeps/coupling.toml > "$w/c200.toml"
echo "\$ pidm run c200.toml --backend cpu"
"$pidm" run "$w/c200.toml" --backend cpu --out "$w/cpu.h5" --progress none 2>/dev/null | grep -E "periodic|wrote"
python3 - "$w/cpu.h5" <<'PY'
import sys
import h5py
with h5py.File(sys.argv[1]) as f:
    lag = f["maps/period_lag"][...]
print(f"periodic (period_lag > 0): {(lag > 0).sum()} of {lag.size}")
PY
echo "\$ PIDM_GPU_PHASES=1 WGPU_BACKEND=vulkan pidm run c200.toml --backend gpu"
PIDM_GPU_PHASES=1 WGPU_BACKEND=vulkan "$pidm" run "$w/c200.toml" --backend gpu --out "$w/gpu.h5" --progress none 2>&1 | grep -E "GPU batch of [0-9]{4,}|wrote"
