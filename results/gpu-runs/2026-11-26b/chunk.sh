#!/usr/bin/env bash
# Steady maps on a lent GPU: the GPU tests after the hardware-aware test
# changes, then the coupling map at 1000 x 1000 (steady, no baselines) with
# PIDM_GPU_STEADY_CHUNK from the whole slice (1024) down to 1, against its
# 10-period window; every chunk's map must equal the whole slice's.
# (The knob was removed after this run, in 3c7b2b9: it changed nothing.)
#
#   ../shared/gpu/pack --tests it      # here; then on the lent machine:
#   bash results/gpu-runs/2026-11-26b/chunk.sh
set -uo pipefail
source .devpack/env.sh
O=${OUT:-/tmp/chunk-out}
W=/tmp/w
mkdir -p "$O" "$W"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
start=$SECONDS
echo "== GPU tests"
CI=true timeout 200 .devpack/tests/it gpu:: crosscheck:: --test-threads 1 > "$O/tests.log" 2>&1
echo "rc $? after $((SECONDS - start)) s"
grep -E "^test .*FAILED|test result|in its scene:|roundings \(" "$O/tests.log" | tail -30

echo "== steady chunk: coupling 1000 x 1000, no baselines"
sed -e 's/steps = 61/steps = 1000/g' -e 's/baselines = true/baselines = false/' sweeps/coupling.toml > $W/c1000.toml
printf '\n[simulation]\nmeasure = "window"\n' | cat $W/c1000.toml - > $W/c1000w.toml
for p in f64 f32; do
  pidm run $W/c1000w.toml --backend gpu --precision $p --out $W/w.h5 --progress none 2>&1 | grep -o "wrote.*" | sed "s/^/$p window: /"
  for round in 1 2; do
    for c in 1024 256 64 16 4 1; do
      PIDM_GPU_STEADY_CHUNK=$c pidm run $W/c1000.toml --backend gpu --precision $p --out $W/s_${p}_$c.h5 --progress none 2>&1 | grep -o "[0-9.]* s wall of which [0-9.]* s integrating" | sed "s/^/$p steady chunk $c round $round: /"
    done
  done
done
python3 - "$W" <<'PY'
import sys, h5py, numpy as np
w = sys.argv[1]
def maps(f):
    out = {}
    with h5py.File(f) as h:
        h.visititems(lambda n, o: out.__setitem__(n, o[...]) if isinstance(o, h5py.Dataset) else None)
    return out
for p in ["f64", "f32"]:
    a = maps(f"{w}/s_{p}_1024.h5")
    for c in [256, 64, 16, 4, 1]:
        b = maps(f"{w}/s_{p}_{c}.h5")
        diff = [k for k in a if a[k].dtype.kind in "fiu" and not np.array_equal(a[k], b[k], equal_nan=True)]
        print(f"{p} chunk {c} against 1024: {'equal' if not diff else 'DIFFERS in ' + ', '.join(diff)}")
PY
echo "== end after $((SECONDS - start)) s"
