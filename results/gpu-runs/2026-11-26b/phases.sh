#!/usr/bin/env bash
# Where a steady map's GPU time goes (PIDM_GPU_PHASES=1): the coupling map
# at 1000 x 1000 (no baselines) steady and as a 10-period window, f64 and
# f32, two rounds each. (phases.log, in git history, came from this loop
# given inline to the device tool, at fbcbbc3.)
#
#   ../shared/gpu/pack      # here; then on the lent machine:
#   bash results/gpu-runs/2026-11-26b/phases.sh
set -uo pipefail
source .devpack/env.sh
W=/tmp/w
mkdir -p "$W"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
sed -e 's/steps = 61/steps = 1000/g' -e 's/baselines = true/baselines = false/' sweeps/coupling.toml > $W/c1000.toml
printf '\n[simulation]\nmeasure = "window"\n' | cat $W/c1000.toml - > $W/c1000w.toml
for round in 1 2; do
  for p in f64 f32; do
    for m in c1000 c1000w; do
      echo "== $p $m round $round"
      PIDM_GPU_PHASES=1 pidm run $W/$m.toml --backend gpu --precision $p --out $W/o.h5 --progress none 2>&1 | grep -E "GPU batch of [0-9]{4,}|wrote"
    done
  done
done
