#!/usr/bin/env bash
# Issue 59 on a lent device, in one call (at most about 8.5 minutes):
#   ../shared/gpu/pack --tests it            # here, then on the lent machine:
#   source .devpack/env.sh && OUT=$OUT bash results/gpu-runs/2026-11-30/device.sh
# 1. results/gpu/bench.sh (the device script) in BENCH seconds;
# 2. the backward travel's cost on the GPU: random 2,000 and 20,000
#    (`pidm random-scene --seed 11 --cycles 4`), f64, with and without
#    `[output] backward = true`, in turn (cold first, then 3 pairs), the
#    CPU's runs of both, and the maps against the CPU's (backward_within.py);
# 3. the GPU tests of the backward travel and LuGre's mirror on hardware.
# Every log goes into $OUT/all.tgz (the device returns at most 8 files).
set -uo pipefail
out=${OUT:-/tmp/pidm-device}
budget=${BUDGET:-500}
bench=${BENCH:-230}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out/runs"
w=$(mktemp -d)
t0=$(date +%s)
left() { echo $((budget - ($(date +%s) - t0))); }
# timed LABEL SECONDS CMD...: CMD with a limit, its output in runs/LABEL.log,
# its wall seconds in times.txt.
timed() {
    local label=$1 limit=$2
    shift 2
    local a b
    a=$(date +%s.%N)
    timeout "$limit" "$@" > "$out/runs/$label.log" 2>&1
    local rc=$?
    b=$(date +%s.%N)
    local inner
    inner=$(grep -oE 'of which [0-9.]+ s integrating' "$out/runs/$label.log" | head -1 | grep -oE '[0-9.]+' | head -1)
    awk -v l="$label" -v a="$a" -v b="$b" -v rc="$rc" -v i="${inner:--}" \
        'BEGIN { printf "%-16s %8.2f s  integrating %s s  rc %s\n", l, b - a, i, rc }' | tee -a "$out/times.txt"
}
OUT=$out/bench PIDM_BENCH_BUDGET=$((bench - 60)) PIDM_BENCH_TIMEOUT=70 PIDM_BENCH_PASSES=30 \
    PIDM_BENCH_STATS_TIMEOUT=55 timed bench "$bench" bash results/gpu/bench.sh
cat "$out/bench/phases.txt" 2> /dev/null | tail -30

export PIDM_CACHE_DIR=$w/cache
for n in 2000 20000; do
    pidm random-scene --seed 11 --count $n --cycles 4 > "$w/r$n.toml"
    { cat "$w/r$n.toml"; printf '\n[output]\nbackward = true\n'; } > "$w/r${n}_bw.toml"
done
timed bw_cold 150 pidm run "$w/r2000_bw.toml" --backend gpu --out "$w/bw_cold.h5"
timed nb_cold 90 pidm run "$w/r2000.toml" --backend gpu --out "$w/nb_cold.h5"
for r in 1 2 3; do
    timed "nb2k_$r" 40 pidm run "$w/r2000.toml" --backend gpu --out "$w/nb2k.h5"
    timed "bw2k_$r" 40 pidm run "$w/r2000_bw.toml" --backend gpu --out "$w/bw2k.h5"
done
timed cpu_bw2k 60 pidm run "$w/r2000_bw.toml" --backend cpu --out "$w/cpu_bw2k.h5"
timed cpu_nb2k 60 pidm run "$w/r2000.toml" --backend cpu --out "$w/cpu_nb2k.h5"
python3 "$here/backward_within.py" "$w/cpu_bw2k.h5" "$w/bw2k.h5" > "$out/within2k.txt" 2>&1
python3 "$here/backward_within.py" "$w/nb2k.h5" "$w/bw2k.h5" --steps-only >> "$out/within2k.txt" 2>&1
cat "$out/within2k.txt"
for r in 1 2; do
    [ "$(left)" -gt 150 ] || break
    timed "nb20k_$r" 60 pidm run "$w/r20000.toml" --backend gpu --out "$w/nb20k.h5"
    timed "bw20k_$r" 60 pidm run "$w/r20000_bw.toml" --backend gpu --out "$w/bw20k.h5"
done
t=$(($(left) - 15))
[ "$t" -gt 20 ] && CI=true timed tests "$t" .devpack/tests/it gpu_backward:: \
    gpu_lugre::the_shader_mirrors --test-threads 1
grep -E '^test |test result' "$out/runs/tests.log" 2> /dev/null
echo "done at $(($(date +%s) - t0)) s" | tee -a "$out/times.txt"
tar -czf "$w/all.tgz" -C "$out" . && mv "$w/all.tgz" "$out/all.tgz" && rm -rf "$out/runs" "$out/bench"
rm -rf "$w"
