#!/usr/bin/env bash
# Baseline on the lent GPU (main at b2fdd15): timestamped runs, then the GPU tests.
source .devpack/env.sh
export PIDM_CACHE_DIR=/tmp/pidm-cache
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
( time pidm info ) 2>&1 | tail -12
sed -e 's/steps = 61/steps = 200/g' -e 's/^baselines = true/baselines = false/' sweeps/coupling.toml > /tmp/c200.toml
stamp() { while IFS= read -r line; do printf '%s %s\n' "$(date +%s.%N | cut -c7-16)" "$line"; done; }
timed() { local s=$(date +%s.%N); echo "start $(echo $s | cut -c7-16)"; pidm run "$@" 2>&1 | stamp; local e=$(date +%s.%N); echo "end $(echo $e | cut -c7-16) total $(python3 -c "print(f'{$e-$s:.3f}')")"; }
# Warm the pipelines (cold compile timed).
timed sweeps/paper.toml --backend gpu --precision f32 --out /tmp/p32.h5
timed sweeps/paper.toml --backend gpu --precision f64 --out /tmp/p64.h5
for r in 1 2 3; do
  timed /tmp/c200.toml --backend gpu --precision f32 --out /tmp/c32.h5
  timed /tmp/c200.toml --backend gpu --precision f64 --out /tmp/c64.h5
  timed /tmp/c200.toml --backend cpu --out /tmp/ccpu.h5
done
echo "== tests"
CI=true timeout 420 .devpack/tests/it gpu:: --test-threads 1 2>&1 | tail -40
