#!/usr/bin/env bash
# The f32 path on a lent GPU (issue 19): GPU tests, the issue's speed targets
# (coupling 1000 x 1000 with baselines and a 20,000-instance random scene,
# f32 with each check setting against f64 and the 16-core CPU) and f32's
# accuracy against the CPU in f64 on the random seeds of results/check.
#
#   ../shared/gpu/pack --tests it      # here; then on the lent machine:
#   bash results/gpu-runs/2026-11-26/f32.sh
#
# Logs go to $OUT (the device tool's output folder) or /tmp/f32-out.
set -uo pipefail
source .devpack/env.sh
O=${OUT:-/tmp/f32-out}
W=/tmp/w
mkdir -p "$O" "$W"
export PIDM=pidm
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
pidm info 2>&1

# Whole-process wall time [s] of one command; its output goes to $W/log.
t() {
  local s e rc
  s=$(date +%s.%N); "$@" > "$W/log" 2>&1; rc=$?; e=$(date +%s.%N)
  python3 -c "print(f'{$e-$s:.3f}')"
  [ $rc = 0 ] || { echo "FAILED rc=$rc: $*" >&2; tail -3 "$W/log" >&2; }
}
integ() { grep -o '[0-9.]* s wall of which [0-9.]* s integrating' "$W/log"; }

echo "== cold pipelines (paper scene)"
for p in f32 f64; do
  echo "$p cold $(t pidm run sweeps/paper.toml --backend gpu --precision $p --out $W/p.h5) s; $(grep -o 'GPU ready.*' $W/log)"
  echo "$p warm $(t pidm run sweeps/paper.toml --backend gpu --precision $p --out $W/p.h5) s; $(grep -o 'GPU ready.*' $W/log)"
done

echo "== GPU tests"
CI=true timeout 200 .devpack/tests/it gpu:: crosscheck:: --test-threads 1 > "$O/tests.log" 2>&1
echo "rc $?"
grep -E "^test |test result|panicked|worst|max" "$O/tests.log" | tail -45

echo "== speed: coupling 1000 x 1000 with baselines, random 20,000 (seed 7, 4 cycles)"
sed -e 's/steps = 61/steps = 1000/g' sweeps/coupling.toml > $W/c1000b.toml
pidm random-scene --seed 7 --count 20000 --cycles 4 > $W/r20k.toml
echo "cpu c1000b $(t pidm run $W/c1000b.toml --backend cpu --out $W/c_cpu.h5 --progress none) s; $(integ)"
echo "cpu r20k $(t pidm run $W/r20k.toml --backend cpu --out $W/cpu_r20k.h5 --progress none) s; $(integ)"
for round in 1 2; do
  for p in f64 f32; do
    echo "gpu $p c1000b $(t pidm run $W/c1000b.toml --backend gpu --precision $p --out $W/c_$p.h5 --progress none) s; $(integ)"
  done
  echo "gpu f64 r20k $(t pidm run $W/r20k.toml --backend gpu --precision f64 --out $W/f64_r20k.h5 --progress none) s; $(integ)"
  for c in auto off reference; do
    echo "gpu f32 check=$c r20k $(PIDM_F32_CHECK=$c t pidm run $W/r20k.toml --backend gpu --precision f32 --out $W/${c}_r20k.h5 --progress none) s; $(integ)"
    cp "$W/log" "$O/r20k_${c}_$round.log"
  done
done
python3 - "$W" <<'PY'
import sys
sys.path.insert(0, "results")
from tolerance.compare import compare, load
w = sys.argv[1]
ref = load(f"{w}/cpu_r20k.h5")
for run in ["f64", "auto", "off", "reference"]:
    over, failed = compare(ref, load(f"{w}/{run}_r20k.h5"))
    worst = max((r for _, r in over), default=0.0)
    print(f"r20k {run} against CPU f64: {len(over)} over 0.005 um + 1 % (worst {worst:.1f}x), {failed} failed only there: {over[:12]}")
PY

echo "== accuracy: seeds 81-100 (fresh), then 61-80, 3,000 instances each"
CHECKS="off twins reference" MIRROR=0 bash results/check/run.sh "$O/acc81" $(seq 81 100) 2>/dev/null
CHECKS="off twins" MIRROR=0 bash results/check/run.sh "$O/acc61" $(seq 61 80) 2>/dev/null
rm -f "$O"/acc*/*.h5
echo "== end"
