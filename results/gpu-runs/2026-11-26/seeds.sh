#!/usr/bin/env bash
# f32 against the CPU in f64 on the lent GPU, seeds 1-60 (3,000 random
# instances each; the seeds the tests and earlier studies picked instances
# from): f32 with its check off and with auto (twins on hardware).
#
#   ../shared/gpu/pack; bash results/gpu-runs/2026-11-26/seeds.sh
set -uo pipefail
source .devpack/env.sh
O=${OUT:-/tmp/seeds-out}
W=/tmp/w
mkdir -p "$O" "$W"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
start=$SECONDS
for s in $(seq 1 60); do
  [ $((SECONDS - start)) -gt ${BUDGET:-200} ] && break
  pidm random-scene --seed $s --count 3000 > $W/r$s.toml
  pidm run $W/r$s.toml --backend cpu --out $W/cpu_$s.h5 --progress none > /dev/null 2>&1
  PIDM_F32_CHECK=off pidm run $W/r$s.toml --backend gpu --precision f32 --out $W/off_$s.h5 --progress none > $W/off_$s.log 2>&1
  pidm run $W/r$s.toml --backend gpu --precision f32 --out $W/auto_$s.h5 --progress none > $W/auto_$s.log 2>&1
  echo "seed $s" >> "$O/progress.txt"
done
python3 - "$W" <<'PY'
import sys, re, os
sys.path.insert(0, "results")
from tolerance.compare import compare, load
w = sys.argv[1]
seeds = [s for s in range(1, 61) if os.path.exists(f"{w}/auto_{s}.h5")]
for run in ["off", "auto"]:
    total, secs, where = 0, 0.0, []
    for s in seeds:
        over, failed = compare(load(f"{w}/cpu_{s}.h5"), load(f"{w}/{run}_{s}.h5"))
        total += len(over)
        where += [f"{s}#{k} ({r:.1f}x)" for k, r in over] + ([f"{s}: {failed} failed only in f32"] if failed else [])
        secs += float(re.search(r"of which ([0-9.]+) s integrating", open(f"{w}/{run}_{s}.log").read()).group(1))
    print(f"{run}: {total} of {3000 * len(seeds)} over 0.005 um + 1 % (seeds {seeds[0]}-{seeds[-1]}), {secs:.1f} s integrating: {', '.join(where)}")
PY
echo "== end"
