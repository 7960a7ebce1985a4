#!/bin/bash
# f32's check of its heaviest runs against the f64 CPU (results/gpu.md, "The
# heaviest tenth"): for each seed, a 3,000-instance random scene run on the
# CPU in f64, and in f32 on the GPU (lavapipe here) with each of the check's
# settings (PIDM_F32_CHECK = off, twins, reference; auto is reference on a
# software adapter, twins on any other), and in the f32 shader's CPU mirror;
# compare.py counts the instances over 0.005 um + 1 % of the f64 step and
# prints each run's integration time and how many runs went to the CPU.
#
#   bash results/check/run.sh OUT_DIR [SEED ...]
#
# CHECKS (default "off twins reference") chooses the check settings run on
# the GPU; MIRROR=0 leaves out the CPU mirror (on the lent GPU machine).
#
# About 3 s a seed on the CPU's 2 cores plus 3 x 20 s of lavapipe.
set -euo pipefail
out=$1; shift
seeds=${*:-61 62 63 64 65 66 67 68 69 70 71 72 73 74 75 76 77 78 79 80}
pidm=${PIDM:-target/release/pidm}
mkdir -p "$out"
for s in $seeds; do
  scene=$out/r$s.toml
  [ -f "$scene" ] || "$pidm" random-scene --seed "$s" --count 3000 > "$scene"
  [ -f "$out/cpu_$s.h5" ] || "$pidm" run "$scene" --backend cpu --out "$out/cpu_$s.h5" --progress none > /dev/null
  [ "${MIRROR:-1}" = 0 ] || [ -f "$out/mirror_$s.h5" ] || "$pidm" run "$scene" --backend cpu --precision f32 --out "$out/mirror_$s.h5" --progress none > "$out/mirror_$s.log"
  for check in ${CHECKS:-off twins reference}; do
    [ -f "$out/${check}_$s.h5" ] || PIDM_F32_CHECK=$check WGPU_BACKEND=vulkan "$pidm" run "$scene" \
      --backend gpu --precision f32 --out "$out/${check}_$s.h5" --progress none > "$out/${check}_$s.log"
  done
  echo "seed $s done" >&2
done
python3 "$(dirname "$0")/compare.py" "$out" $seeds
