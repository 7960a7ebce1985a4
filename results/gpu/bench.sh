#!/usr/bin/env bash
# The one device script (issue 32): the CPU path on every core, the GPU in
# f64 and in f32, and `--backend auto`, on the scenes of the GPU targets,
# each timed as a whole `pidm run` process; one table of seconds and
# speed-ups beside the targets, then the GPU runs' phase lines.
#
#   ../shared/gpu/pack                        # here, then on the lent machine:
#   source .devpack/env.sh && bash results/gpu/bench.sh      # at most 8 minutes
#   WGPU_BACKEND=vulkan bash results/gpu/bench.sh smoke      # here, on lavapipe
#
# Scenes (full; smoke: 20 x 20 and 30 x 30 maps, 400 random instances, an
# 8 x 8 two-frequency map of at most 20 periods):
#   coupling200   sweeps/coupling.toml at steps = 200 (steady, with baselines)
#   coupling1000  the same at steps = 1000
#   random100k    pidm random-scene --seed 7 --count 100000 --cycles 4 --compact
#                 (the instances of the points scene, as a [random] table)
#   twofreq128    a 128 x 128 map of both drive frequencies, 10.03-12.57 Hz by
#                 14.11-17.93 Hz (non-round ratios) at 100 V, steady to the
#                 phase-resolved estimate (hundreds to thousands of periods an
#                 instance). Its CPU run would take about 10 minutes on 16
#                 cores, beyond the budget: the CPU runs the same ranges at
#                 32 x 32 (a sixteenth of the instances, spread over the same
#                 plane) and its time times 16 is the CPU column, marked "(x16)".
#                 The GPU and auto run the whole map.
# Per scene, in this order: --backend cpu, --backend gpu --precision f64, the
# same in f32, and --backend auto (which weighs the GPU costs the runs before
# it recorded). GPU and auto runs run with PIDM_GPU_PHASES=1: their phase
# lines carry the lanes' figures (issue 38: warp efficiency by kind of
# iteration, each batch's critical path and how well the first dispatch
# ranked it, the bytes a lane keeps and moves).
# Then the saturation curve (issue 38): random instances of 4 cycles, 1k,
# 4k, 16k, 64k, 256k and 1M (smoke: 100, 400, 1,600), each one GPU f64
# process, in the last PIDM_BENCH_SATURATION seconds of the budget (default
# 100): integrating seconds, instances and simulated seconds per wall
# second, and the warp efficiency, against the instances in flight.
#
# Knobs (environment): PIDM (the binary, default `pidm`), OUT (results and
# logs, default /tmp/pidm-gpu-bench), PIDM_BENCH_BUDGET (seconds from the
# start by which every run has ended, default 420: 8 minutes less a minute
# for unpacking and starting), PIDM_BENCH_TIMEOUT (seconds one run may take,
# default 150), PIDM_BENCH_SCENES (the scenes to run, default all four),
# PIDM_BENCH_SATURATION (seconds kept for the saturation curve, default 100),
# PIDM_CACHE_DIR (the pipeline cache and auto's GPU costs, default
# $OUT/cache: fresh on a fresh machine). A run that fails, runs out of time
# or is skipped for the budget shows as "failed", "timeout" or "skipped".
#
# Budget, estimated from the 2-core build machine (results/gpu.md, "The
# device script"): about 3-5 minutes on the H100 machine, most of it the
# random scene's CPU run and the two-frequency map's GPU runs.
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
budget=${PIDM_BENCH_BUDGET:-420}
saturation=${PIDM_BENCH_SATURATION:-100}
limit=${PIDM_BENCH_TIMEOUT:-150}
scenes=${PIDM_BENCH_SCENES:-coupling200 coupling1000 random100k twofreq128}
mkdir -p "$out"
export PIDM_CACHE_DIR=${PIDM_CACHE_DIR:-$out/cache}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
: > "$out/runs.log"
started=$(date +%s.%N)

if [ "$mode" = full ]; then
    small=200 big=1000 count=100000 side=128 sample=32
    curve="1000 4000 16000 64000 256000 1000000"
else
    small=20 big=30 count=400 side=8 sample=4
    curve="100 400 1600"
fi
# The smoke mode's two-frequency runs stop at 20 periods (status 6), for a
# quick pass on lavapipe; the full map runs to its estimate.
cap=""
[ "$mode" = smoke ] && cap="max_cycles = 20"
# The CPU's two-frequency time is the sample map's times this.
scale=$(( (side / sample) * (side / sample) ))
# What each scene is called in the table.
declare -A shown=(
    [coupling200]="coupling $small x $small"
    [coupling1000]="coupling $big x $big"
    [random100k]="random $count"
    [twofreq128]="two-frequency $side x $side"
)
root=$(cd "$(dirname "$0")/../.." && pwd)
sed -e "s/steps = 61/steps = $small/g" -e "s/^name = \"coupling\"/name = \"coupling$small\"/" \
    "$root/sweeps/coupling.toml" > "$work/coupling200.toml"
sed -e "s/steps = 61/steps = $big/g" -e "s/^name = \"coupling\"/name = \"coupling$big\"/" \
    "$root/sweeps/coupling.toml" > "$work/coupling1000.toml"
"$pidm" random-scene --seed 7 --count "$count" --cycles 4 --compact > "$work/random100k.toml"
# The two-frequency map at n x n, named name.
twofreq() {
    cat <<EOF
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
twofreq "$side" "twofreq$side" > "$work/twofreq128.toml"
twofreq "$sample" "twofreq$sample" > "$work/twofreq128-sample.toml"
cp "$root/sweeps/paper.toml" "$work/paper.toml"

# Seconds since the start of the script.
elapsed() {
    awk -v a="$started" -v b="$(date +%s.%N)" 'BEGIN { printf "%.0f", b - a }'
}

# Runs one `pidm run` as label with the given arguments; prints its whole
# wall time [s], or failed, timeout or skipped. The stderr and stdout are
# kept in $work/label.log and summed up in runs.log.
timed() {
    local label=$1
    shift
    # No run goes past the budget: it gets what is left of it, at most
    # $limit, and none starts with under 5 s left.
    local left=$((${until:-$budget} - $(elapsed)))
    if [ "$left" -lt 5 ]; then
        echo "== $label: skipped (budget of $budget s spent)" >> "$out/runs.log"
        echo skipped
        return
    fi
    [ "$left" -lt "$limit" ] || left=$limit
    local start end rc
    start=$(date +%s.%N)
    timeout "$left" "$pidm" run "$@" --progress none > "$work/$label.log" 2>&1
    rc=$?
    end=$(date +%s.%N)
    local wall
    wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.3f", b - a }')
    if [ $rc -eq 124 ]; then
        { echo "== $label: timeout after $left s"; tail -5 "$work/$label.log"; } >> "$out/runs.log"
        echo timeout
        return
    fi
    if [ $rc -ne 0 ]; then
        # A run whose instances did not all finish exits 1 and still wrote its
        # file: "wrote" says so.
        if ! grep -q '^wrote ' "$work/$label.log"; then
            { echo "== $label: FAILED (exit $rc)"; tail -20 "$work/$label.log"; } >> "$out/runs.log"
            echo failed
            return
        fi
    fi
    {
        echo "== $label: $wall s"
        grep -E '^(pidm: (auto|backend|GPU ready|no hardware)|wrote )' "$work/$label.log"
    } >> "$out/runs.log"
    echo "$wall"
}

# The phase lines of a run's stderr (PIDM_GPU_PHASES=1), or what ran where
# there are none.
phases() {
    local log="$work/$1.log"
    [ -f "$log" ] || return
    echo "== $1"
    if grep -qE '^pidm: (phase|GPU batch)' "$log"; then
        grep -E '^pidm: (phase|GPU batch|GPU ready)' "$log"
    elif grep -q '^pidm: backend ' "$log"; then
        grep -E '^pidm: backend ' "$log"
    else
        tail -8 "$log"
    fi
}

# The integrating seconds of a run's summary ("... of which X s
# integrating"), or -.
integrating() {
    grep -o 'of which [0-9.]* s integrating' "$work/$1.log" 2>/dev/null | head -1 | awk '{print $3}' | grep . || echo -
}

# a / b to one decimal, or - where either is not a number.
ratio() {
    awk -v a="$1" -v b="$2" 'BEGIN {
        if (a + 0 > 0 && b + 0 > 0 && a ~ /^[0-9.]+$/ && b ~ /^[0-9.]+$/) printf "%.2f", a / b
        else printf "-" }'
}

# The smaller of two times, or the one that is a number.
least() {
    awk -v a="$1" -v b="$2" 'BEGIN {
        an = (a ~ /^[0-9.]+$/); bn = (b ~ /^[0-9.]+$/)
        if (an && bn) print (a + 0 < b + 0 ? a : b); else if (an) print a; else if (bn) print b; else print "-" }'
}

{
    echo "== pidm GPU bench, mode $mode, $(date -u +%Y-%m-%dT%H:%M:%SZ)"
    echo "commit: $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null
    echo "CPU cores: $(nproc)"
    "$pidm" info 2>&1 | head -20
} | tee "$out/adapter.txt"

# Fill the pipeline cache (the first run of each precision compiles); these
# runs are not in the table.
for precision in f64 f32; do
    cold=$(timed "warm-$precision" "$work/paper.toml" --backend gpu --precision $precision --out "$work/p.h5")
    echo "pipeline cache filled in $precision: $cold s (paper.toml, cold)"
done

table="$out/table.md"
inner="$out/integrating.md"
{
    echo "| scene | instances | CPU [s] | GPU f64 [s] | GPU f32 [s] | auto [s] | auto ran | f64 speed-up | f32 speed-up | target | auto / faster of CPU and GPU f64 |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|"
} > "$table"
{
    echo "| scene | CPU | GPU f64 | GPU f32 | auto |"
    echo "|---|---|---|---|---|"
} > "$inner"
# The scenes end by the budget less the saturation curve's share.
until=$((budget - saturation))
for scene in $scenes; do
    toml="$work/$scene.toml"
    if [ "$scene" = twofreq128 ]; then
        # The CPU on the sample map, scaled to the whole one.
        sampled=$(timed "$scene-cpu" "$work/$scene-sample.toml" --backend cpu --out "$work/$scene-cpu.h5")
        cpu=$(awk -v t="$sampled" -v k="$scale" 'BEGIN { if (t ~ /^[0-9.]+$/) printf "%.3f", t * k; else print t }')
    else
        cpu=$(timed "$scene-cpu" "$toml" --backend cpu --out "$work/$scene-cpu.h5")
    fi
    f64=$(PIDM_GPU_PHASES=1 timed "$scene-f64" "$toml" --backend gpu --precision f64 --out "$work/$scene-f64.h5")
    f32=$(PIDM_GPU_PHASES=1 timed "$scene-f32" "$toml" --backend gpu --precision f32 --out "$work/$scene-f32.h5")
    auto=$(PIDM_GPU_PHASES=1 timed "$scene-auto" "$toml" --out "$work/$scene-auto.h5")
    ran=$(grep -o '^pidm: backend [a-z]*' "$work/$scene-auto.log" 2>/dev/null | head -1 | cut -d' ' -f3)
    n=$(grep -ho '^wrote [^ ]* ([0-9]* instance' "$work/$scene-f64.log" "$work/$scene-cpu.log" 2>/dev/null | head -1 | grep -o '([0-9]*' | tr -d '(')
    case $scene in
    random100k) target="f64 >= 10x" ;;
    twofreq128) target="f64 >= 20x" ;;
    coupling1000) target="f64 >= 3x" ;;
    *) target="-" ;;
    esac
    best=$(least "$cpu" "$f64")
    shown_cpu=$cpu
    [ "$scene" = twofreq128 ] && shown_cpu="$cpu (x$scale)"
    row="| ${shown[$scene]} | ${n:--} | $shown_cpu | $f64 | $f32 | $auto | ${ran:--} | $(ratio "$cpu" "$f64") | $(ratio "$cpu" "$f32") | $target | $(ratio "$auto" "$best") (target <= 1.10) |"
    echo "$row" >> "$table"
    echo "$row"
    echo "| ${shown[$scene]} | $(integrating "$scene-cpu") | $(integrating "$scene-f64") | $(integrating "$scene-f32") | $(integrating "$scene-auto") |" >> "$inner"
done
# The saturation curve, in the rest of the budget.
until=$budget
curve_table="$out/saturation.md"
{
    echo "| random instances (4 cycles) | GPU f64 integrating [s] | instances per s | simulated s per wall s | warp efficiency |"
    echo "|---|---|---|---|---|"
} > "$curve_table"
for n in $curve; do
    "$pidm" random-scene --seed 7 --count "$n" --cycles 4 --compact > "$work/curve$n.toml"
    wall=$(PIDM_GPU_PHASES=1 timed "curve$n" "$work/curve$n.toml" --backend gpu --precision f64 --out "$work/curve$n.h5")
    seconds=$(integrating "curve$n")
    rate=$(grep -o '[0-9.]* simulated s per wall s' "$work/curve$n.log" 2>/dev/null | head -1 | cut -d' ' -f1)
    warp=$(grep -o 'dispatch order: [0-9.]* %' "$work/curve$n.log" 2>/dev/null | head -1 | cut -d' ' -f3)
    per=$(awk -v n="$n" -v t="$seconds" 'BEGIN { if (t + 0 > 0) printf "%.0f", n / t; else print "-" }')
    echo "| $n | ${seconds} ($wall whole) | $per | ${rate:--} | ${warp:+$warp %} |" >> "$curve_table"
done

# Phases, then the tables last.
{
    echo
    echo "== phases of the GPU runs (PIDM_GPU_PHASES=1)"
    for scene in $scenes; do
        for run in f64 f32 auto; do
            phases "$scene-$run"
        done
    done
    echo
    echo "== auto's lines"
    for scene in $scenes; do
        grep -hE '^pidm: (auto|[0-9]+ integration)' "$work/$scene-auto.log" 2>/dev/null | sed "s/^/${shown[$scene]}: /"
    done
    echo
    echo "== GPU costs recorded for auto ($PIDM_CACHE_DIR/gpu-costs.txt)"
    cat "$PIDM_CACHE_DIR/gpu-costs.txt" 2>/dev/null || echo "(none: no hardware GPU run)"
    echo
    echo "== integrating [s] (the runs' summaries)"
    cat "$inner"
    echo
    echo "== saturation: throughput against the instances in flight (GPU f64, one process each)"
    cat "$curve_table"
    echo
    echo "== whole processes [s], mode $mode, $(elapsed) s in all; speed-up = CPU / GPU"
    cat "$table"
} | tee "$out/phases.txt"
