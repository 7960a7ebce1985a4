#!/usr/bin/env bash
# The CPU continuing the GPU's f64 tail: new binary against main's, and the CPU.
source .devpack/env.sh
export PIDM_CACHE_DIR=/tmp/pidm-cache
W=/tmp/w; mkdir -p $W
t() { local s=$(date +%s.%N); "$@" > $W/log 2>&1; local rc=$?; local e=$(date +%s.%N); python3 -c "print(f'{$e-$s:.3f}')"; [ $rc = 0 ] || { echo "FAILED rc=$rc: $*" >&2; tail -3 $W/log >&2; }; }
cmp() { python3 - "$@" <<'PY'
import sys, h5py, numpy as np
a = h5py.File(sys.argv[1]); b = h5py.File(sys.argv[2])
d = max(float(np.max(np.abs(a["maps"][k][...] - b["maps"][k][...]))) for k in ("step_x", "step_y")) * 1e6
s = int(np.sum(a["maps/status"][...] != b["maps/status"][...]))
print(f"max |d| {d:.2e} um, statuses differing {s}")
PY
}
pidm run sweeps/paper.toml --backend gpu --precision f64 --out $W/p.h5 > /dev/null 2>&1
pidm-old run sweeps/paper.toml --backend gpu --precision f64 --out $W/p.h5 > /dev/null 2>&1
for n in 1024 4096 20000; do
  seed=3; [ $n = 20000 ] && seed=7
  pidm random-scene --seed $seed --count $n --cycles 4 > $W/r$n.toml
  echo "rand $n cpu $(t pidm run $W/r$n.toml --backend cpu --out $W/r$n-cpu.h5) $(grep -o 'of which.*integrating' $W/log)"
  for r in 1 2; do
    echo "rand $n new $(t pidm run $W/r$n.toml --backend gpu --precision f64 --out $W/r$n-new.h5) $(grep -o 'of which.*integrating' $W/log) $(grep -o '[0-9]* of the integrations ran on the CPU' $W/log)"
    echo "rand $n old $(t pidm-old run $W/r$n.toml --backend gpu --precision f64 --out $W/r$n-old.h5) $(grep -o 'of which.*integrating' $W/log) $(grep -o '[0-9]* of the integrations ran on the CPU' $W/log)"
  done
  echo "new vs cpu: $(cmp $W/r$n-new.h5 $W/r$n-cpu.h5); old vs cpu: $(cmp $W/r$n-old.h5 $W/r$n-cpu.h5)"
done
sed -e 's/steps = 61/steps = 1000/g' sweeps/coupling.toml > $W/c1000b.toml
echo "c1000b cpu $(t pidm run $W/c1000b.toml --backend cpu --out $W/c-cpu.h5) $(grep -o 'of which.*integrating' $W/log)"
for r in 1 2; do
  echo "c1000b new $(t pidm run $W/c1000b.toml --backend gpu --precision f64 --out $W/c-new.h5) $(grep -o 'of which.*integrating' $W/log) $(grep -o '[0-9]* of the integrations ran on the CPU' $W/log)"
  echo "c1000b old $(t pidm-old run $W/c1000b.toml --backend gpu --precision f64 --out $W/c-old.h5) $(grep -o 'of which.*integrating' $W/log)"
  echo "c1000b new f32 $(t pidm run $W/c1000b.toml --backend gpu --precision f32 --out $W/c-32.h5) $(grep -o 'of which.*integrating' $W/log)"
done
echo "new vs cpu: $(cmp $W/c-new.h5 $W/c-cpu.h5); old vs cpu: $(cmp $W/c-old.h5 $W/c-cpu.h5)"
echo "== tests"
CI=true timeout 300 .devpack/tests/it gpu:: --test-threads 1 2>&1 | grep -E "^test |test result"
