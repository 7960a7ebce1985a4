#!/usr/bin/env bash
source .devpack/env.sh
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
echo "== tests"
CI=true timeout 240 .devpack/tests/it gpu:: crosscheck:: --test-threads 1 2>&1 | grep -E "^test |test result|panicked|max" | tail -30
echo "== bench"
bash results/gpu_bench.sh full 2>&1 | tail -30
echo "== old (main at b2fdd15) against new, coupling 1000 b"
export PIDM_CACHE_DIR=/tmp/pidm-cache2
W=/tmp/w; mkdir -p $W
sed -e 's/steps = 61/steps = 1000/g' sweeps/coupling.toml > $W/c1000b.toml
t() { local s=$(date +%s.%N); "$@" > $W/log 2>&1; local rc=$?; local e=$(date +%s.%N); python3 -c "print(f'{$e-$s:.3f}')"; [ $rc = 0 ] || { echo "FAILED rc=$rc: $*" >&2; tail -3 $W/log >&2; }; }
for p in f64 f32; do pidm run sweeps/paper.toml --backend gpu --precision $p --out $W/p.h5 >/dev/null 2>&1; pidm-old run sweeps/paper.toml --backend gpu --precision $p --out $W/p.h5 >/dev/null 2>&1; done
for r in 1 2 3; do
  for p in f64 f32; do
    echo "new $p $(t pidm run $W/c1000b.toml --backend gpu --precision $p --out $W/c.h5) $(grep -o '[0-9.]* s wall of which.*integrating' $W/log)"
    echo "old $p $(t pidm-old run $W/c1000b.toml --backend gpu --precision $p --out $W/c.h5) $(grep -o '[0-9.]* s wall of which.*integrating' $W/log)"
  done
done
