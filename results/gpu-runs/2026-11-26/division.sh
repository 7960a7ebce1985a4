#!/usr/bin/env bash
# f32 division and square root corrected by one fused multiply-add (this
# commit) against the hardware's own (main's binary, carried as pidm-old)
# on the lent GPU: the f32 GPU tests that failed there, f32 against the CPU
# in f64 on seeds 61-100 (3,000 instances each, check off, and auto), and
# the time of a 20,000-instance random scene.
#
#   ../shared/gpu/pack --tests it; cp OLD_PIDM .devpack/bin/pidm-old
#   bash results/gpu-runs/2026-11-26/division.sh
set -uo pipefail
source .devpack/env.sh
O=${OUT:-/tmp/div-out}
W=/tmp/w
mkdir -p "$O" "$W"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
echo "== f32 GPU tests"
CI=true timeout 150 .devpack/tests/it gpu::f32 gpu::the_f32 gpu::random_scene gpu::paper --test-threads 1 --nocapture > "$O/tests.log" 2>&1
echo "rc $?"
grep -E "^test |test result|panicked|roundings|shader alone|max abs|FAIL" "$O/tests.log" | tail -40
echo "== accuracy, seeds 61-100: CPU f64; f32 old (off), new (off, auto)"
for s in $(seq 61 100); do
  pidm random-scene --seed $s --count 3000 > $W/r$s.toml
  pidm run $W/r$s.toml --backend cpu --out $W/cpu_$s.h5 --progress none > /dev/null 2>&1
  PIDM_F32_CHECK=off pidm-old run $W/r$s.toml --backend gpu --precision f32 --out $W/old_$s.h5 --progress none > $W/old_$s.log 2>&1
  PIDM_F32_CHECK=off pidm run $W/r$s.toml --backend gpu --precision f32 --out $W/off_$s.h5 --progress none > $W/off_$s.log 2>&1
  pidm run $W/r$s.toml --backend gpu --precision f32 --out $W/auto_$s.h5 --progress none > $W/auto_$s.log 2>&1
done
python3 - "$W" <<'PY'
import sys, re
sys.path.insert(0, "results")
from tolerance.compare import compare, load
w = sys.argv[1]
for run in ["old", "off", "auto"]:
    total, secs, where = 0, 0.0, []
    for s in range(61, 101):
        over, failed = compare(load(f"{w}/cpu_{s}.h5"), load(f"{w}/{run}_{s}.h5"))
        total += len(over)
        where += [f"{s}#{k} ({r:.1f}x)" for k, r in over] + ([f"{s}: {failed} failed only in f32"] if failed else [])
        secs += float(re.search(r"of which ([0-9.]+) s integrating", open(f"{w}/{run}_{s}.log").read()).group(1))
    print(f"{run}: {total} of 120000 over 0.005 um + 1 %, {secs:.1f} s integrating: {', '.join(where)}")
PY
echo "== random 20,000 (seed 7, 4 cycles), check off: old, new; auto"
pidm random-scene --seed 7 --count 20000 --cycles 4 > $W/r20k.toml
for r in 1 2; do
  for b in pidm-old pidm; do
    PIDM_F32_CHECK=off $b run $W/r20k.toml --backend gpu --precision f32 --out $W/r.h5 --progress none 2>&1 | grep -o "$b\|[0-9.]* s wall of which [0-9.]* s integrating" | tr '\n' ' '; echo " ($b)"
  done
  pidm run $W/r20k.toml --backend gpu --precision f32 --out $W/r.h5 --progress none 2>&1 | grep -o "[0-9.]* s wall of which [0-9.]* s integrating" | tr '\n' ' '; echo " (pidm, auto)"
done
echo "== end"
