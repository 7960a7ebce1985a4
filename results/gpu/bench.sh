#!/usr/bin/env bash
# The one device script (issues 32, 47): the device's answer in one call of
# at most 5 minutes.
#
#   ../shared/gpu/pack                         # here, then on the lent machine:
#   source .devpack/env.sh && OUT=$OUT bash results/gpu/bench.sh
#   WGPU_BACKEND=vulkan bash results/gpu/bench.sh smoke    # here, on lavapipe
#
# 1. The host's cores (--backend cpu) against the GPU in f64 and in f32, each
#    a whole `pidm run` process, on four scenes (smoke: 6 x 6, 30 x 30, 400,
#    8 x 8 of at most 20 periods), LuGre's first (it has no hardware figure
#    yet, so the budget must not run out before it):
#      lugre200      the coupling map at steps = 200 with LuGre friction
#                    (smoke: 6 x 6), f64 only (LuGre has no f32 shader): its
#                    phase lines say how its lanes spent their dispatches
#                    ("LuGre on the GPU": dispatches, period ends, slots filled)
#      coupling1000  sweeps/coupling.toml at steps = 1000 (steady, baselines)
#      random100k    pidm random-scene --seed 7 --count 100000 --cycles 4 --compact
#      twofreq128    128 x 128 over both drive frequencies, 10.03-12.57 Hz by
#                    14.11-17.93 Hz at 100 V, steady; the CPU runs the same
#                    ranges at 32 x 32 and its time x16 is its column, "(x16)"
#    table.md: whole-process seconds and speed-ups; integrating.md: each
#    run's "of which X s integrating"; phases.txt: every GPU run's phase
#    lines (PIDM_GPU_PHASES=1).
# 2. The time per lockstep pass (lockstep.md): 32, 1,024, 32,768 and 262,144
#    alike instances (smoke: 32, 256, 1,024), GPU f64: V_x = V_y from 100 to
#    100.001 V (distinct, so none is deduplicated), a window of 10 periods
#    (all within the first dispatch: a lane each). Alike lanes do the same
#    work, so dispatch seconds / passes of the critical path is the time of
#    one pass; flat across the counts means latency-bound.
# 3. The driver's statistics of every hardware pipeline (registers.txt:
#    `pidm info --registers`, NVIDIA's register count at least).
# 4. Every file written under $OUT goes into $OUT/bench.tgz (the per-run logs
#    and scenes only there); table.md, phases.txt, adapter.txt, runs.log,
#    integrating.md and lockstep.md stay beside it.
#
# Knobs: PIDM (the binary, default `pidm`), OUT (default /tmp/pidm-gpu-bench),
# PIDM_BENCH_BUDGET (seconds from the start by which every run has ended,
# default 270), PIDM_BENCH_TIMEOUT (seconds one run may take, default 90),
# PIDM_BENCH_SCENES (default all four), PIDM_BENCH_PASSES (seconds kept at
# the end for the lockstep passes, default 40), PIDM_CACHE_DIR (the pipeline
# cache, default a fresh one per call: the warm-up runs compile). No run
# starts with under 5 s left; such a run shows "skipped", one past its time
# "timeout", one that wrote nothing "failed".
set -uo pipefail
mode=${1:-full}
case $mode in
full | smoke) ;;
*)
    echo "usage: bash results/gpu/bench.sh [full|smoke]" >&2
    exit 2
    ;;
esac
pidm=${PIDM:-pidm}
if ! command -v "$pidm" > /dev/null; then
    echo "bench.sh: no pidm binary ($pidm): put it on PATH (source .devpack/env.sh) or set PIDM" >&2
    exit 2
fi
out=${OUT:-/tmp/pidm-gpu-bench}
budget=${PIDM_BENCH_BUDGET:-270}
passes_kept=${PIDM_BENCH_PASSES:-40}
limit=${PIDM_BENCH_TIMEOUT:-90}
scenes=${PIDM_BENCH_SCENES:-lugre200 coupling1000 random100k twofreq128}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export PIDM_CACHE_DIR=${PIDM_CACHE_DIR:-$work/cache}
# Per-run logs and scenes (archived, then removed); outputs stay in $work.
logs=$out/logs
sc=$out/scenes
rm -rf "$logs" "$sc" "$out/bench.tgz"
mkdir -p "$logs" "$sc"
: > "$out/runs.log"
started=$(date +%s.%N)

if [ "$mode" = full ]; then
    big=1000 count=100000 side=128 sample=32 lugre=200
    alike="32 1024 32768 262144"
else
    big=30 count=400 side=8 sample=4 lugre=6
    alike="32 256 1024"
fi
# The smoke mode's two-frequency runs stop at 20 periods (status 6).
cap=""
[ "$mode" = smoke ] && cap="max_cycles = 20"
# The CPU's two-frequency time is the sample map's times this.
scale=$(((side / sample) * (side / sample)))
declare -A shown=(
    [coupling1000]="coupling $big x $big"
    [random100k]="random $count"
    [twofreq128]="two-frequency $side x $side"
    [lugre200]="LuGre coupling $lugre x $lugre"
)
root=$(cd "$(dirname "$0")/../.." && pwd)
sed -e "s/steps = 61/steps = $big/g" -e "s/^name = \"coupling\"/name = \"coupling$big\"/" \
    "$root/sweeps/coupling.toml" > "$sc/coupling1000.toml"
sed -e "s/steps = 61/steps = $lugre/g" -e "s/^name = \"coupling\"/name = \"lugre$lugre\"/" \
    -e 's/^\[output\]/[mechanism]\nfriction = "lugre"\n\n[output]/' \
    "$root/sweeps/coupling.toml" > "$sc/lugre200.toml"
sed -e "s/steps = $lugre/steps = 2/g" "$sc/lugre200.toml" > "$sc/lugre-warm.toml"
case " $scenes " in *" random100k "*)
    "$pidm" random-scene --seed 7 --count "$count" --cycles 4 --compact > "$sc/random100k.toml" ;;
esac
# The two-frequency map at n x n, named name.
twofreq() {
    cat << EOF
# Both drive frequencies over non-round ranges (sweeps/two_frequency.toml's
# setting: Table 1 at 100 V on both axes, steady), $1 x $1.
name = "$2"
[axis.x]
voltage = 100.0
frequency = { from = 10.03, to = 12.57, steps = $1 }
[axis.y]
voltage = 100.0
frequency = { from = 14.11, to = 17.93, steps = $1 }
[simulation]
measure = "steady"
$cap
EOF
}
twofreq "$side" "twofreq$side" > "$sc/twofreq128.toml"
twofreq "$sample" "twofreq$sample" > "$sc/twofreq128-sample.toml"
# n alike instances: both axes at one voltage, a millivolt apart in all.
lockstep() {
    cat << EOF
name = "alike$1"
[axis.x]
voltage = { from = 100.0, to = 100.001, steps = $1 }
[axis.y]
voltage = { same_as = "axis.x.voltage" }
[simulation]
measure = "window"
cycles = 10
settle = 1
EOF
}
cp "$root/sweeps/paper.toml" "$sc/paper.toml"

# Seconds since the start of the script.
elapsed() {
    awk -v a="$started" -v b="$(date +%s.%N)" 'BEGIN { printf "%.0f", b - a }'
}

# Runs one `pidm run` as label with the given arguments; prints its whole
# wall time [s], or failed, timeout or skipped. Its output is kept in
# $logs/label.log and summed up in runs.log.
timed() {
    local label=$1
    shift
    # It gets what is left of the budget (until $until), at most $limit.
    local left=$((${until:-$budget} - $(elapsed)))
    if [ "$left" -lt 5 ]; then
        echo "== $label: skipped (budget of $budget s spent)" >> "$out/runs.log"
        echo skipped
        return
    fi
    [ "$left" -lt "$limit" ] || left=$limit
    local start end rc wall
    start=$(date +%s.%N)
    timeout "$left" "$pidm" run "$@" --progress none > "$logs/$label.log" 2>&1
    rc=$?
    end=$(date +%s.%N)
    wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.3f", b - a }')
    if [ $rc -eq 124 ]; then
        { echo "== $label: timeout after $left s"; tail -5 "$logs/$label.log"; } >> "$out/runs.log"
        echo timeout
        return
    fi
    # A run whose instances did not all finish exits 1 and still wrote its
    # file: "wrote" says so.
    if [ $rc -ne 0 ] && ! grep -q '^wrote ' "$logs/$label.log"; then
        { echo "== $label: FAILED (exit $rc)"; tail -20 "$logs/$label.log"; } >> "$out/runs.log"
        echo failed
        return
    fi
    {
        echo "== $label: $wall s"
        grep -E '^(pidm: (backend|GPU ready|no hardware)|wrote )' "$logs/$label.log"
    } >> "$out/runs.log"
    echo "$wall"
}

# The phase lines of a run (PIDM_GPU_PHASES=1), or its last lines.
phases() {
    local log="$logs/$1.log"
    [ -f "$log" ] || return
    echo "== $1"
    if grep -qE '^pidm: (phase|GPU batch)' "$log"; then
        grep -E '^pidm: (phase|GPU batch|GPU ready)' "$log"
    else
        tail -8 "$log"
    fi
}

# The first match of an extended regex's first number in a run's log, or -.
figure() {
    grep -oE "$2" "$logs/$1.log" 2> /dev/null | head -1 | grep -oE '[0-9]+(\.[0-9]+)?' | head -1 | grep . || echo -
}

# The integrating seconds of a run's summary ("... of which X s
# integrating"), or -.
integrating() {
    figure "$1" 'of which [0-9.]+ s integrating'
}

# a / b to two decimals, or - where either is not a number.
ratio() {
    awk -v a="$1" -v b="$2" 'BEGIN {
        if (a ~ /^[0-9.]+$/ && b ~ /^[0-9.]+$/ && a + 0 > 0 && b + 0 > 0) printf "%.2f", a / b
        else printf "-" }'
}

{
    echo "== pidm GPU bench, mode $mode, $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "commit: $(git -C "$root" rev-parse --short HEAD 2> /dev/null || echo unknown)"
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2> /dev/null
    echo "CPU cores: $(nproc)"
    "$pidm" info 2>&1 | head -20
} | tee "$out/adapter.txt"

# Fill the pipeline cache (the first run of each precision compiles); these
# runs are not in the tables.
for precision in f64 f32; do
    cold=$(timed "warm-$precision" "$sc/paper.toml" --backend gpu --precision $precision --out "$work/p.h5")
    echo "pipeline cache filled in $precision: $cold s (paper.toml, cold)"
done
case " $scenes " in *" lugre200 "*)
    cold=$(timed "warm-lugre" "$sc/lugre-warm.toml" --backend gpu --out "$work/l.h5")
    echo "pipeline cache filled for LuGre: $cold s (a 2 x 2 LuGre map, cold)" ;;
esac

table="$out/table.md"
inner="$out/integrating.md"
{
    echo "| scene | instances | CPU [s] | GPU f64 [s] | GPU f32 [s] | f64 speed-up | f32 speed-up | target |"
    echo "|---|---|---|---|---|---|---|---|"
} > "$table"
{
    echo "| scene | CPU | GPU f64 | GPU f32 |"
    echo "|---|---|---|---|"
} > "$inner"
# The scenes end by the budget less the lockstep passes' share.
until=$((budget - passes_kept))
for scene in $scenes; do
    toml="$sc/$scene.toml"
    if [ "$scene" = twofreq128 ]; then
        # The CPU on the sample map, scaled to the whole one.
        sampled=$(timed "$scene-cpu" "$sc/$scene-sample.toml" --backend cpu --out "$work/$scene-cpu.h5")
        cpu=$(awk -v t="$sampled" -v k="$scale" 'BEGIN { if (t ~ /^[0-9.]+$/) printf "%.3f", t * k; else print t }')
    else
        cpu=$(timed "$scene-cpu" "$toml" --backend cpu --out "$work/$scene-cpu.h5")
    fi
    f64=$(PIDM_GPU_PHASES=1 timed "$scene-f64" "$toml" --backend gpu --precision f64 --out "$work/$scene-f64.h5")
    if [ "$scene" = lugre200 ]; then
        f32="- (f64 only)"
    else
        f32=$(PIDM_GPU_PHASES=1 timed "$scene-f32" "$toml" --backend gpu --precision f32 --out "$work/$scene-f32.h5")
    fi
    n=$(grep -ho '^wrote [^ ]* ([0-9]* instance' "$logs/$scene-f64.log" "$logs/$scene-f32.log" "$logs/$scene-cpu.log" 2> /dev/null |
        head -1 | grep -o '([0-9]*' | tr -d '(')
    case $scene in
    random100k) target="f64 >= 10x" ;;
    twofreq128) target="f64 >= 20x" ;;
    coupling1000) target="f64 >= 3x" ;;
    *) target="-" ;;
    esac
    shown_cpu=$cpu
    [ "$scene" = twofreq128 ] && [ "$cpu" != "$sampled" ] && shown_cpu="$cpu (x$scale)"
    row="| ${shown[$scene]:-$scene} | ${n:--} | $shown_cpu | $f64 | $f32 | $(ratio "$cpu" "$f64") | $(ratio "$cpu" "$f32") | $target |"
    echo "$row" >> "$table"
    echo "$row"
    echo "| ${shown[$scene]:-$scene} | $(integrating "$scene-cpu") | $(integrating "$scene-f64") | $(integrating "$scene-f32") |" >> "$inner"
done

# The lockstep passes, in the rest of the budget.
until=$budget
passes_table="$out/lockstep.md"
{
    echo "| alike instances | lanes | dispatches [s] | dispatches | lockstep passes | us per pass | warp slots doing work | whole [s] |"
    echo "|---|---|---|---|---|---|---|---|"
} > "$passes_table"
for n in $alike; do
    lockstep "$n" > "$sc/alike$n.toml"
    wall=$(PIDM_GPU_PHASES=1 timed "alike$n" "$sc/alike$n.toml" --backend gpu --precision f64 --out "$work/alike$n.h5")
    log="$logs/alike$n.log"
    seconds=$(figure "alike$n" '^pidm: phase +dispatches +[0-9.]+ s')
    lanes=$(grep -oE 'critical path of batch 0 \([0-9]+ instances, then [0-9]+ lanes' "$log" 2> /dev/null | head -1 | grep -oE '[0-9]+ lanes' | cut -d' ' -f1)
    count=$(grep -oE '[0-9]+ dispatches\)' "$log" 2> /dev/null | head -1 | cut -d' ' -f1)
    warp=$(figure "alike$n" 'dispatch order: [0-9.]+ %')
    # Passes in lockstep of each batch's critical path, summed; more than
    # one batch is said.
    batches=$(grep -cE 'critical path of batch [0-9]+ ' "$log" 2> /dev/null)
    passes=$(grep -oE 'critical path of batch [0-9]+ .*: [0-9]+ passes in lockstep' "$log" 2> /dev/null |
        grep -oE '[0-9]+ passes in lockstep' | awk '{ s += $1 } END { if (NR) print s }')
    per=$(awk -v t="$seconds" -v p="${passes:-}" 'BEGIN {
        if (t ~ /^[0-9.]+$/ && p + 0 > 0) printf "%.1f", t * 1e6 / p; else print "-" }')
    shown_passes=${passes:--}
    [ "${batches:-0}" -gt 1 ] && shown_passes="$shown_passes ($batches batches, summed)"
    [ "$warp" = - ] || warp="$warp %"
    echo "| $n | ${lanes:--} | $seconds | ${count:--} | $shown_passes | $per | $warp | $wall |" >> "$passes_table"
done

# Phases, then the tables last.
{
    echo
    echo "== phases of the GPU runs (PIDM_GPU_PHASES=1)"
    for scene in $scenes; do
        phases "$scene-f64"
        phases "$scene-f32"
    done
    for n in $alike; do
        phases "alike$n"
    done
    echo
    echo "== integrating [s] (the runs' summaries)"
    cat "$inner"
    echo
    echo "== lockstep: time per pass of alike instances (GPU f64, one process each; us per pass = dispatches / passes of the critical path)"
    cat "$passes_table"
    echo
    echo "== whole processes [s], mode $mode, $(elapsed) s in all; speed-up = CPU / GPU"
    cat "$table"
} | tee "$out/phases.txt"

# The driver's own statistics of every hardware pipeline (issue 57: NVIDIA's
# register count and local memory), compiled apart from the runs above, in
# at most PIDM_BENCH_STATS_TIMEOUT seconds (default 90).
timeout "${PIDM_BENCH_STATS_TIMEOUT:-90}" "$pidm" info --registers > "$out/registers.txt" 2>&1 ||
    echo "(pidm info --registers: exit $?)" >> "$out/registers.txt"
head -40 "$out/registers.txt"

# One archive of everything written under $OUT (the device returns at most 8
# files); the logs and scenes live only there.
if tar -czf "$work/bench.tgz" -C "$out" --exclude=bench.tgz . && mv "$work/bench.tgz" "$out/bench.tgz"; then
    rm -rf "$logs" "$sc"
    echo "archive: $out/bench.tgz"
else
    echo "bench.sh: could not archive $out" >&2
fi
