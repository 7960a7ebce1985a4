#!/usr/bin/env bash
# The final code on the lent GPU: its tests, and f64 against the CPU on random scenes.
source .devpack/env.sh
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
export PIDM_CACHE_DIR=/tmp/pidm-cache
W=/tmp/w; mkdir -p $W
echo "== tests"
CI=true timeout 300 .devpack/tests/it gpu:: crosscheck:: cli:: --test-threads 1 2>&1 | grep -E "^test |test result|panicked"
agree() { python3 - "$@" <<'PY'
import sys, h5py, numpy as np
a = h5py.File(sys.argv[1]); b = h5py.File(sys.argv[2])
d = np.max(np.stack([np.abs(a["maps"][k][...] - b["maps"][k][...]) for k in ("step_x", "step_y")]), axis=0) * 1e6
s = int(np.sum(a["maps/status"][...] != b["maps/status"][...]))
print(f"{len(d)} instances: above 1e-9 um {int(np.sum(d > 1e-9))}, above 1e-11 um {int(np.sum(d > 1e-11))}, largest {d.max():.2e} um, statuses differing {s}")
PY
}
echo "== f64 GPU against the CPU"
for spec in "11 1000" "7 20000"; do
  set -- $spec
  pidm random-scene --seed $1 --count $2 --cycles 4 > $W/r.toml
  pidm run $W/r.toml --backend cpu --out $W/cpu.h5 2>&1 | grep wrote
  pidm run $W/r.toml --backend gpu --precision f64 --out $W/gpu.h5 2>&1 | grep -E "wrote|ran on the CPU"
  echo "seed $1, $2 instances: $(agree $W/cpu.h5 $W/gpu.h5)"
done
