#!/bin/bash
# The yardstick's own convergence (results/gpu.md, "The CPU's own
# convergence"): for each seed, a 3,000-instance random scene run on the CPU
# at the default tolerance (1e-4 rad) and at 1e-5 and 1e-6 rad, in f32 on
# the GPU (lavapipe here) at the default, and in the f32 shader's CPU mirror
# (`--backend cpu --precision f32`); then compare.py counts instances over
# 0.005 um + 1 % between each pair.
#
#   bash results/tolerance/run.sh OUT_DIR [SEED ...]
#
# About 40 s a seed on the CPU's 2 cores plus 20 s of lavapipe.
set -euo pipefail
out=$1; shift
seeds=${*:-4 5 11 21 31 32 33 34 41 42 43 44 51 52 53 54 55 56}
pidm=${PIDM:-target/release/pidm}
mkdir -p "$out"
for s in $seeds; do
  scene=$out/r$s.toml
  [ -f "$scene" ] || "$pidm" random-scene --seed "$s" --count 3000 > "$scene"
  for t in 1e-4 1e-5 1e-6; do
    tight=$out/r${s}_$t.toml
    sed "s/^settle = 1$/settle = 1\ntolerance = $t/" "$scene" > "$tight"
    grep -q "^tolerance = $t$" "$tight"
    [ -f "$out/cpu_${t}_$s.h5" ] || "$pidm" run "$tight" --backend cpu --out "$out/cpu_${t}_$s.h5" --progress none > /dev/null
  done
  [ -f "$out/mirror_$s.h5" ] || "$pidm" run "$scene" --backend cpu --precision f32 --out "$out/mirror_$s.h5" --progress none > /dev/null
  [ -f "$out/f32_$s.h5" ] || WGPU_BACKEND=vulkan "$pidm" run "$scene" --backend gpu --precision f32 --out "$out/f32_$s.h5" --progress none > /dev/null
  echo "seed $s done" >&2
done
python3 "$(dirname "$0")/compare.py" "$out" $seeds
