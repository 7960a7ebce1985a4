#!/usr/bin/env bash
# f32's check share on a lent GPU (issue 19), second round: the GPU tests at
# the heaviest fifth (the reworked check test had not run on hardware); a
# 20,000-instance random scene (seed 7, 4 cycles) in f64 and in f32 with the
# check off, by twins (auto) at shares 0.2 and 0.3 and by the reference;
# the coupling map at 1000 x 1000 measured steady against a 10-period
# window (the steady map's small GPU lead); and fresh seeds from 170 on
# against the CPU in f64 with the check off and by twins at 0.2 and 0.3.
#
#   ../shared/gpu/pack --tests it      # here; then on the lent machine:
#   bash results/gpu-runs/2026-11-26b/shares.sh
set -uo pipefail
source .devpack/env.sh
O=${OUT:-/tmp/shares-out}
W=/tmp/w
mkdir -p "$O" "$W"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
start=$SECONDS

# Whole-process wall time [s] of one command; its output goes to $W/log.
t() {
  local s e rc
  s=$(date +%s.%N); "$@" > "$W/log" 2>&1; rc=$?; e=$(date +%s.%N)
  python3 -c "print(f'{$e-$s:.3f}')"
  [ $rc = 0 ] || { echo "FAILED rc=$rc: $*" >&2; tail -3 "$W/log" >&2; }
}
integ() { grep -o '[0-9.]* s wall of which [0-9.]* s integrating' "$W/log"; }
checked() { grep -o '[0-9]* f32 runs, the heaviest [0-9.]* %' "$W/log"; }

echo "== GPU tests"
CI=true timeout 220 .devpack/tests/it gpu:: crosscheck:: --test-threads 1 > "$O/tests.log" 2>&1
echo "rc $? after $((SECONDS - start)) s"
grep -E "^test .*FAILED|test result|worst|panicked" "$O/tests.log" | tail -30

echo "== speed: random 20,000 (seed 7, 4 cycles)"
pidm random-scene --seed 7 --count 20000 --cycles 4 > $W/r20k.toml
echo "cpu r20k $(t pidm run $W/r20k.toml --backend cpu --out $W/cpu_r20k.h5 --progress none) s; $(integ)"
for round in 1 2; do
  echo "gpu f64 r20k $(t pidm run $W/r20k.toml --backend gpu --precision f64 --out $W/f64_r20k.h5 --progress none) s; $(integ)"
  for run in off:0.2 auto:0.2 auto:0.3 reference:0.2; do
    c=${run%:*}; s=${run#*:}
    echo "gpu f32 check=$c share=$s r20k $(PIDM_F32_CHECK=$c PIDM_F32_CHECK_SHARE=$s t pidm run $W/r20k.toml --backend gpu --precision f32 --out $W/${c}_${s}_r20k.h5 --progress none) s; $(integ); $(checked)"
  done
done
python3 - "$W" <<'PY'
import sys
sys.path.insert(0, "results")
from tolerance.compare import compare, load
w = sys.argv[1]
ref = load(f"{w}/cpu_r20k.h5")
for run in ["f64", "off_0.2", "auto_0.2", "auto_0.3", "reference_0.2"]:
    over, failed = compare(ref, load(f"{w}/{run}_r20k.h5"))
    worst = max((r for _, r in over), default=0.0)
    print(f"r20k {run} against CPU f64: {len(over)} over (worst {worst:.1f}x), {failed} failed only there: {over[:12]}")
PY

echo "== steady against window: coupling 1000 x 1000, no baselines"
sed -e 's/steps = 61/steps = 1000/g' -e 's/baselines = true/baselines = false/' sweeps/coupling.toml > $W/c1000.toml
printf '\n[simulation]\nmeasure = "window"\n' | cat $W/c1000.toml - > $W/c1000w.toml
for p in f64 f32; do
  for m in c1000 c1000w; do
    echo "gpu $p $m $(t pidm run $W/$m.toml --backend gpu --precision $p --out $W/$m.h5 --progress none) s; $(integ)"
  done
done
echo "cpu c1000 $(t pidm run $W/c1000.toml --backend cpu --out $W/c.h5 --progress none) s; $(integ)"
echo "cpu c1000w $(t pidm run $W/c1000w.toml --backend cpu --out $W/c.h5 --progress none) s; $(integ)"

echo "== accuracy: fresh seeds from 170, 3,000 instances each (after $((SECONDS - start)) s)"
A=$W/acc; mkdir -p $A
for s in $(seq 170 269); do
  [ $((SECONDS - start)) -gt ${BUDGET:-420} ] && break
  pidm random-scene --seed $s --count 3000 > $A/r$s.toml
  pidm run $A/r$s.toml --backend cpu --out $A/cpu_$s.h5 --progress none > /dev/null 2>&1
  PIDM_F32_CHECK=off pidm run $A/r$s.toml --backend gpu --precision f32 --out $A/off_$s.h5 --progress none > /dev/null 2>&1
  pidm run $A/r$s.toml --backend gpu --precision f32 --out $A/auto2_$s.h5 --progress none > /dev/null 2>&1
  PIDM_F32_CHECK_SHARE=0.3 pidm run $A/r$s.toml --backend gpu --precision f32 --out $A/auto3_$s.h5 --progress none > /dev/null 2>&1
  echo -n "$s "
done
echo
seeds=$(ls $A | sed -n 's/^auto3_\([0-9]*\)\.h5$/\1/p' | sort -n | tr '\n' ' ')
python3 results/check/share.py $A $seeds
python3 - "$A" $seeds <<'PY'
import sys
sys.path.insert(0, "results")
from tolerance.compare import compare, load
a, seeds = sys.argv[1], sys.argv[2:]
for run in ["off", "auto2", "auto3"]:
    where, n = [], 0
    for s in seeds:
        over, failed = compare(load(f"{a}/cpu_{s}.h5"), load(f"{a}/{run}_{s}.h5"))
        n += 3000
        where += [f"{s}#{k} ({r:.1f}x)" for k, r in over] + ([f"{s}: {failed} failed only in f32"] if failed else [])
    print(f"{run}: {len([w for w in where if '#' in w])} of {n} over: {', '.join(where)}")
PY
echo "== end after $((SECONDS - start)) s"
