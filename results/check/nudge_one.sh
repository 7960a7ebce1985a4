#!/bin/bash
# Is one random instance's f64 step determined at f32's resolution? Runs
# instance K of `pidm random-scene --seed SEED --count COUNT --cycles
# CYCLES` on the CPU in f64, then six times with its parameters nudged by
# 6e-8 (results/twins/nudge.py, sign patterns 1-6), and prints each step
# [um per own drive cycle] and step count. With f32 in lavapipe (check off)
# for comparison. results/gpu.md, "f32 on an H200" and "The heaviest fifth".
#
#   bash results/check/nudge_one.sh SEED K [COUNT [CYCLES]]
set -euo pipefail
seed=$1; k=$2; count=${3:-3000}; cycles=${4:-4}
pidm=${PIDM:-target/release/pidm}
dir=$(dirname "$0")
w=$(mktemp -d)
trap 'rm -rf "$w"' EXIT
"$pidm" random-scene --seed "$seed" --count "$count" --cycles "$cycles" > "$w/all.toml"
# The scene's header (up to its first point) and point K.
python3 - "$w/all.toml" "$k" "$w/one.toml" <<'PY'
import sys
lines = open(sys.argv[1]).read().split("\n")
i = lines.index(f'label = "random {sys.argv[2]}"')
head = lines[: lines.index("[[points]]")]
open(sys.argv[3], "w").write("\n".join(head + lines[i - 1 : i + 4]) + "\n")
PY
show() {
  python3 -c "
import h5py
with h5py.File('$w/o.h5', 'r') as h:
    x, y, n = (h['maps/' + m][0] for m in ('step_x', 'step_y', 'steps'))
print(f'$1: x {x * 1e6:+.5f} um, y {y * 1e6:+.5f} um, {n} steps')"
}
"$pidm" run "$w/one.toml" --backend cpu --out "$w/o.h5" --progress none > /dev/null 2>&1
show "seed $seed #$k, CPU f64"
for s in 1 2 3 4 5 6; do
  python3 "$dir/../twins/nudge.py" "$w/one.toml" 6e-8 "$s" "$w/n.toml" 1
  "$pidm" run "$w/n.toml" --backend cpu --out "$w/o.h5" --progress none > /dev/null 2>&1
  show "  nudged, signs $s"
done
PIDM_F32_CHECK=off WGPU_BACKEND=vulkan "$pidm" run "$w/one.toml" --backend gpu --precision f32 \
  --out "$w/o.h5" --progress none > /dev/null 2>&1
show "  f32 on lavapipe, check off"
