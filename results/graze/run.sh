#!/bin/bash
# f32 with the band-graze guard against the f64 CPU (results/gpu.md, "Band
# grazes"): for each seed, a 3,000-instance random scene run on the CPU in
# f64, on the CPU in f64 with every parameter nudged by 6e-8 relative (the
# rounding of f32's coefficients: how far the yardstick itself moves at
# f32's parameter resolution), in f32 on the GPU (lavapipe here) and in the
# f32 shader's CPU mirror; compare.py counts the instances over 0.005 um +
# 1 % of the f64 step. Each f32 run's summary line says how many
# integrations ran on the CPU in f64 (grazes, failures and the slow tail);
# it is kept in OUT_DIR/f32_S.log and mirror_S.log.
#
#   bash results/graze/run.sh OUT_DIR [SEED ...]
#
# About 10 s a seed on the CPU's 2 cores plus 20-35 s of lavapipe.
set -euo pipefail
out=$1; shift
seeds=${*:-61 62 63 64 65 66 67 68 69 70 71 72 73 74 75 76 77 78 79 80}
pidm=${PIDM:-target/release/pidm}
here=$(dirname "$0")
mkdir -p "$out"
for s in $seeds; do
  scene=$out/r$s.toml
  [ -f "$scene" ] || "$pidm" random-scene --seed "$s" --count 3000 > "$scene"
  [ -f "$out/nudged_$s.toml" ] || python3 "$here/../twins/nudge.py" "$scene" 6e-8 "$s" "$out/nudged_$s.toml" 1
  [ -f "$out/cpu_$s.h5" ] || "$pidm" run "$scene" --backend cpu --out "$out/cpu_$s.h5" --progress none > /dev/null
  [ -f "$out/nudged_$s.h5" ] || "$pidm" run "$out/nudged_$s.toml" --backend cpu --out "$out/nudged_$s.h5" --progress none > /dev/null
  [ -f "$out/mirror_$s.h5" ] || "$pidm" run "$scene" --backend cpu --precision f32 --out "$out/mirror_$s.h5" --progress none > "$out/mirror_$s.log"
  [ -f "$out/f32_$s.h5" ] || WGPU_BACKEND=vulkan "$pidm" run "$scene" --backend gpu --precision f32 --out "$out/f32_$s.h5" --progress none > "$out/f32_$s.log"
  echo "seed $s done" >&2
done
python3 "$here/compare.py" "$out" $seeds
