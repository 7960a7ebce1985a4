#!/usr/bin/env bash
# Issue 39 on a lent device, in one call (about 8 minutes):
#   ../shared/gpu/pack --tests it            # here, then on the lent machine:
#   source .devpack/env.sh && OUT=/tmp/r PACK=$OUT/all.tgz bash results/gpu-runs/2026-11-28/replicas.sh
# (the device tool returns at most 8 files of its $OUT: PACK puts every
# log and result file into one archive there)
# 1. the 6 x 6 two-frequency map: GPU f64 (cold, then warm, with --profile),
#    GPU f32, the same without replicas (f64), the CPU on every core; each
#    GPU map against the CPU's by issue 39's rule (results/replicas/within.py);
# 2. the quasi-periodic instance on the CPU, replicas auto against 1;
# 3. the GPU and replica tests of tests/it;
# 4. results/gpu/bench.sh in what is left of the budget.
set -uo pipefail
out=${OUT:-/tmp/pidm-replicas}
budget=${BUDGET:-490}
mkdir -p "$out"
export PIDM_CACHE_DIR=/tmp/pidm-cache
t0=$(date +%s)
left() { echo $((budget - ($(date +%s) - t0))); }
# timed LABEL SECONDS CMD...: runs CMD with a limit, its output in LABEL.log,
# its wall seconds in times.txt.
timed() {
    local label=$1 limit=$2
    shift 2
    local a b
    a=$(date +%s.%N)
    timeout "$limit" "$@" > "$out/$label.log" 2>&1
    local rc=$?
    b=$(date +%s.%N)
    awk -v l="$label" -v a="$a" -v b="$b" -v rc="$rc" \
        'BEGIN { printf "%-14s %8.2f s  rc %s\n", l, b - a, rc }' | tee -a "$out/times.txt"
}
pidm info > "$out/info.txt" 2>&1
nproc >> "$out/info.txt"
S=results/pipeline/twofreq6.toml
timed gpu64_cold 90 pidm run $S --backend gpu --precision f64 --profile --out "$out/gpu64_cold.h5"
timed gpu64 90 pidm run $S --backend gpu --precision f64 --profile --out "$out/gpu64.h5"
timed gpu64_b 90 pidm run $S --backend gpu --precision f64 --out "$out/gpu64_b.h5"
timed gpu32 90 pidm run $S --backend gpu --precision f32 --profile --out "$out/gpu32.h5"
timed gpu64_one 90 pidm run results/replicas/twofreq6_one.toml --backend gpu --precision f64 --profile --out "$out/gpu64_one.h5"
timed cpu 90 pidm run $S --backend cpu --out "$out/cpu.h5"
timed cpu_b 90 pidm run $S --backend cpu --out "$out/cpu_b.h5"
for g in gpu64 gpu64_b gpu32 gpu64_one; do
    echo "== cpu against $g" >> "$out/within.txt"
    python3 results/replicas/within.py "$out/cpu.h5" "$out/$g.h5" >> "$out/within.txt" 2>&1
done
python3 results/compare_maps.py "$out/gpu64.h5" "$out/gpu64_b.h5" > "$out/gpu64_repeat.txt" 2>&1
for r in 1 2 3; do
    timed quasi_auto 30 pidm run results/replicas/quasi.toml --backend cpu --threads 2 --out "$out/qa.h5"
    timed quasi_one 30 pidm run results/replicas/quasi_one.toml --backend cpu --threads 2 --out "$out/q1.h5"
done
timed quasi_gpu 60 pidm run results/replicas/quasi.toml --backend gpu --precision f64 --profile --out "$out/qg.h5"
python3 results/replicas/within.py "$out/qa.h5" "$out/qg.h5" > "$out/quasi_within.txt" 2>&1
t=$(left); t=$((t > 230 ? 170 : t - 60))
[ "$t" -gt 20 ] && CI=true timed tests "$t" .devpack/tests/it replicas:: gpu:: gpu_phase:: gpu_lugre:: lanes:: variants:: --test-threads 1
t=$(left)
[ "$t" -gt 40 ] && OUT=$out/bench PIDM_BENCH_BUDGET=$((t - 5)) PIDM_BENCH_TIMEOUT=90 PIDM_BENCH_SATURATION=40 \
    timed bench $((t - 2)) bash results/gpu/bench.sh
rm -f "$out"/*.h5.tmp
echo "done at $(($(date +%s) - t0)) s" >> "$out/times.txt"
[ -n "${PACK:-}" ] && tar czf "$PACK" -C "$out" .
