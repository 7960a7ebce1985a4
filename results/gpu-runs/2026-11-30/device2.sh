#!/usr/bin/env bash
# LuGre's backward travel on a lent device (issue 59), in one call of at
# most about 6.5 minutes:
#   ../shared/gpu/pack --tests it            # here, then on the lent machine:
#   source .devpack/env.sh && OUT=$OUT bash results/gpu-runs/2026-11-30/device2.sh
# 1. the GPU tests of the backward travel (both laws), LuGre's mirror test;
# 2. the LuGre coupling map at 200 x 200 (results/gpu/bench.sh's lugre200)
#    on the GPU, f64, with and without `[output] backward = true` in turn
#    (cold first, then 2 pairs), the CPU's run with it, and the backward
#    maps against the CPU's (backward_within.py);
# 3. `pidm info --registers` (the driver's own statistics where it gives
#    them, and RADV's).
# Every log goes into $OUT/all.tgz (the device returns at most 8 files).
set -uo pipefail
out=${OUT:-/tmp/pidm-device2}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
mkdir -p "$out/runs"
w=$(mktemp -d)
export PIDM_CACHE_DIR=$w/cache
t0=$(date +%s)
timed() {
    local label=$1 limit=$2
    shift 2
    local a b inner
    a=$(date +%s.%N)
    timeout "$limit" "$@" > "$out/runs/$label.log" 2>&1
    local rc=$?
    b=$(date +%s.%N)
    inner=$(grep -oE 'of which [0-9.]+ s integrating' "$out/runs/$label.log" | head -1 | grep -oE '[0-9.]+' | head -1)
    awk -v l="$label" -v a="$a" -v b="$b" -v rc="$rc" -v i="${inner:--}" \
        'BEGIN { printf "%-16s %8.2f s  integrating %s s  rc %s\n", l, b - a, i, rc }' | tee -a "$out/times.txt"
}
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > "$out/adapter.txt" 2>&1
CI=true timed tests 170 .devpack/tests/it gpu_lugre_backward:: gpu_backward:: \
    gpu_lugre::the_shader_mirrors backward::pidm_runs_lugres --test-threads 1
grep -E '^test |test result|largest|MirrorCheck' "$out/runs/tests.log"
sed -e "s/steps = 61/steps = 200/g" -e 's/^name = "coupling"/name = "lugre200"/' \
    -e 's/^\[output\]/[mechanism]\nfriction = "lugre"\n\n[output]/' \
    "$root/sweeps/coupling.toml" > "$w/l.toml"
sed -e 's/^\[output\]/[output]\nbackward = true/' "$w/l.toml" > "$w/l_bw.toml"
timed bw_cold 90 pidm run "$w/l_bw.toml" --backend gpu --out "$w/bw.h5"
timed nb_cold 60 pidm run "$w/l.toml" --backend gpu --out "$w/nb.h5"
for r in 1 2; do
    timed "nb_$r" 30 pidm run "$w/l.toml" --backend gpu --out "$w/nb.h5"
    timed "bw_$r" 30 pidm run "$w/l_bw.toml" --backend gpu --out "$w/bw.h5"
done
timed cpu_bw 60 pidm run "$w/l_bw.toml" --backend cpu --out "$w/cpu_bw.h5"
python3 "$here/backward_within.py" "$w/cpu_bw.h5" "$w/bw.h5" > "$out/within.txt" 2>&1
python3 "$here/backward_within.py" "$w/nb.h5" "$w/bw.h5" --steps-only >> "$out/within.txt" 2>&1
cat "$out/within.txt"
left=$((390 - ($(date +%s) - t0)))
[ "$left" -gt 20 ] && timed registers "$left" pidm info --registers
grep -iE 'lugre|budget|driver' "$out/runs/registers.log" | head -20
echo "done at $(($(date +%s) - t0)) s" | tee -a "$out/times.txt"
tar -czf "$w/all.tgz" -C "$out" . && mv "$w/all.tgz" "$out/all.tgz" && rm -rf "$out/runs"
rm -rf "$w"
