#!/usr/bin/env bash
# Start-up, teardown and the CPU/GPU crossover on the lent GPU.
source .devpack/env.sh
export PIDM_CACHE_DIR=/tmp/pidm-cache
W=/tmp/w; mkdir -p $W
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
t() { local s=$(date +%s.%N); "$@" > $W/log 2>&1; local rc=$?; local e=$(date +%s.%N); python3 -c "print(f'{$e-$s:.3f}')"; [ $rc = 0 ] || { echo "FAILED rc=$rc: $*" >&2; tail -3 $W/log >&2; }; }
# Warm both pipelines (and time the cold compile).
for p in f32 f64; do echo "cold $p $(t pidm run sweeps/paper.toml --backend gpu --precision $p --out $W/p.h5)"; grep ready $W/log; done
echo "== start-up and teardown (new binary, then main's), coupling 200 f64"
sed -e 's/steps = 61/steps = 200/g' -e 's/^baselines = true/baselines = false/' sweeps/coupling.toml > $W/c200.toml
for r in 1 2 3; do
  echo "new $(t pidm run $W/c200.toml --backend gpu --precision f64 --out $W/c.h5) $(grep ready $W/log)"
  echo "old $(t pidm-old run $W/c200.toml --backend gpu --precision f64 --out $W/c.h5)"
  echo "cpu $(t pidm run $W/c200.toml --backend cpu --out $W/c.h5) $(grep -o 'of which.*integrating' $W/log)"
done
echo "== paper: auto, gpu f64, gpu f32, cpu"
for r in 1 2 3; do
  echo "auto $(t pidm run sweeps/paper.toml --out $W/p.h5) $(head -1 $W/log | cut -c1-60)"
  echo "gpu64 $(t pidm run sweeps/paper.toml --backend gpu --precision f64 --out $W/p.h5) $(grep -o 'of which.*integrating' $W/log)"
  echo "gpu32 $(t pidm run sweeps/paper.toml --backend gpu --precision f32 --out $W/p.h5) $(grep -o 'of which.*integrating' $W/log)"
  echo "cpu $(t pidm run sweeps/paper.toml --backend cpu --out $W/p.h5) $(grep -o 'of which.*integrating' $W/log)"
done
echo "== crossover: coupling N x N, no baselines (whole process s: gpu f64, gpu f32, cpu)"
for n in 4 8 16 32 64 100 141 200; do
  sed -e "s/steps = 61/steps = $n/g" -e 's/^baselines = true/baselines = false/' sweeps/coupling.toml > $W/cn.toml
  for r in 1 2; do
    echo "N=$n $((n*n)) $(t pidm run $W/cn.toml --backend gpu --precision f64 --out $W/c.h5) $(t pidm run $W/cn.toml --backend gpu --precision f32 --out $W/c.h5) $(t pidm run $W/cn.toml --backend cpu --out $W/c.h5)"
  done
done
echo "== crossover: random instances (whole process s: gpu f64, gpu f32, cpu)"
for n in 16 64 256 1024 4096; do
  pidm random-scene --seed 3 --count $n --cycles 4 > $W/r.toml
  for r in 1 2; do
    echo "rand $n $(t pidm run $W/r.toml --backend gpu --precision f64 --out $W/r.h5) $(t pidm run $W/r.toml --backend gpu --precision f32 --out $W/r.h5) $(t pidm run $W/r.toml --backend cpu --out $W/r.h5)"
  done
done
