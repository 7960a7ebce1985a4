#!/usr/bin/env bash
# GPU against CPU on one machine: the measurements behind results/gpu.md.
#
#   bash results/gpu_bench.sh [quick|full]
#
# Run from the repository root with `pidm` on PATH (on the lent GPU machine:
# `source .devpack/env.sh` first). Every timing is the wall time of a whole
# `pidm run` process (adapter, pipeline from the cache, self-test, the run,
# the HDF5 file), warm unless it says cold, with the GPU and `--backend cpu`
# (all cores) measured in the same invocation. Results and logs go to
# ${OUT:-/tmp/pidm-gpu-bench}; the table is printed last.
set -uo pipefail
mode=${1:-quick}
out=${OUT:-/tmp/pidm-gpu-bench}
mkdir -p "$out"
work=$(mktemp -d)
table="$out/table.md"
: > "$table"
: > "$out/runs.log"

# Scenes derived from the shipped ones.
sed -e 's/steps = 61/steps = 200/g' -e 's/^baselines = true/baselines = false/' \
    sweeps/coupling.toml > "$work/coupling200.toml"
sed -e 's/steps = 61/steps = 1000/g' sweeps/coupling.toml > "$work/coupling1000b.toml"
cat > "$work/onedof200.toml" <<'EOF'
name = "onedof200"
[axis.x]
voltage = { from = 1.0, to = 150.0, steps = 200 }
frequency = { from = 5.0, to = 40.0, steps = 200 }
[axis.y]
voltage = 0.0
EOF
cp sweeps/paper.toml "$work/paper.toml"
# Heterogeneous scenes: every parameter drawn at random per instance.
pidm random-scene --seed 3 --count 4096 --cycles 4 > "$work/rand4096.toml"
pidm random-scene --seed 7 --count 20000 --cycles 4 > "$work/rand20k.toml"

# Runs one `pidm run` and prints its whole wall time [s]; the log is kept.
timed() {
    local label=$1
    shift
    local start end
    start=$(date +%s.%N)
    if ! pidm run "$@" > "$work/$label.log" 2>&1; then
        echo "FAILED: $label" >&2
        tail -5 "$work/$label.log" >&2
        { echo "== $label (FAILED)"; cat "$work/$label.log"; } >> "$out/runs.log"
        echo "nan"
        return
    fi
    end=$(date +%s.%N)
    { echo "== $label: $(python3 -c "print(f'{$end - $start:.3f}')") s"; grep -E "ready|backend|wrote|status [1-9]" "$work/$label.log"; } >> "$out/runs.log"
    python3 -c "print(f'{$end - $start:.3f}')"
}

row() {
    echo "| $* |" | tee -a "$table"
}

echo "== adapter"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null | tee "$out/adapter.txt"
pidm info 2>&1 | tee -a "$out/adapter.txt"

# Cold: an empty driver shader cache and an empty pidm pipeline cache, so
# the driver compiles; then warm (both caches filled); then the pidm cache
# alone (a fresh driver cache), which shows what the pipeline cache saves.
echo "== compile"
for precision in f32 f64; do
    export PIDM_CACHE_DIR="$work/pidm-cache-$precision"
    export __GL_SHADER_DISK_CACHE_PATH="$work/nv-cache-$precision"
    mkdir -p "$__GL_SHADER_DISK_CACHE_PATH"
    cold=$(timed "cold-$precision" "$work/paper.toml" --backend gpu --precision $precision --out "$work/p.h5")
    warm=$(timed "warm-$precision" "$work/paper.toml" --backend gpu --precision $precision --out "$work/p.h5")
    export __GL_SHADER_DISK_CACHE_PATH="$work/nv-cache-$precision-fresh"
    mkdir -p "$__GL_SHADER_DISK_CACHE_PATH"
    cached=$(timed "pidmcache-$precision" "$work/paper.toml" --backend gpu --precision $precision --out "$work/p.h5")
    row "paper.toml $precision: cold (no caches) $cold s, warm $warm s, pidm pipeline cache only $cached s"
done
unset __GL_SHADER_DISK_CACHE_PATH
export PIDM_CACHE_DIR="$work/pidm-cache"
# Fill the caches used below.
pidm run "$work/paper.toml" --backend gpu --precision f32 --out "$work/p.h5" > /dev/null 2>&1
pidm run "$work/paper.toml" --backend gpu --precision f64 --out "$work/p.h5" > /dev/null 2>&1

echo "== timings (warm)"
row "scene | instances | GPU f32 [s] | GPU f64 [s] | CPU, all cores [s] | f32 speed-up | f64 speed-up | auto [s] | auto ran on"
row "---|---|---|---|---|---|---|---|---"
scenes="paper coupling200 onedof200 rand4096"
if [ "$mode" = full ]; then
    scenes="$scenes coupling1000b rand20k"
fi
for scene in $scenes; do
    f32=$(timed "$scene-f32" "$work/$scene.toml" --backend gpu --precision f32 --out "$work/$scene-f32.h5")
    f64=$(timed "$scene-f64" "$work/$scene.toml" --backend gpu --precision f64 --out "$work/$scene-f64.h5")
    cpu=$(timed "$scene-cpu" "$work/$scene.toml" --backend cpu --out "$work/$scene-cpu.h5")
    n=$(grep -o '([0-9]* instances' "$work/$scene-cpu.log" | head -1 | tr -dc 0-9)
    auto=$(timed "$scene-auto" "$work/$scene.toml" --out "$work/$scene-auto.h5")
    ran=$(grep -o '^pidm: backend [a-z]*' "$work/$scene-auto.log" | head -1 | cut -d' ' -f3)
    sp32=$(python3 -c "print(f'{$cpu / $f32:.1f}')" 2>/dev/null || echo nan)
    sp64=$(python3 -c "print(f'{$cpu / $f64:.1f}')" 2>/dev/null || echo nan)
    row "$scene | $n | $f32 | $f64 | $cpu | $sp32 | $sp64 | $auto | $ran"
    # Agreement of the maps with the CPU's [um].
    python3 - "$work/$scene-cpu.h5" "$work/$scene-f32.h5" "$work/$scene-f64.h5" <<'EOF' | tee -a "$out/agreement.txt"
import sys, os
import h5py, numpy as np
cpu = h5py.File(sys.argv[1])
for path in sys.argv[2:]:
    if not os.path.exists(path):
        continue
    gpu = h5py.File(path)
    worst = max(float(np.max(np.abs(gpu["maps"][k][...] - cpu["maps"][k][...]))) * 1e6
                for k in ("step_x", "step_y"))
    bad = int(np.sum(gpu["maps/status"][...] != cpu["maps/status"][...]))
    print(f"{os.path.basename(path)}: max |GPU - CPU| {worst:.3e} um, statuses differing {bad}")
EOF
done
echo "== table"
cat "$table"
rm -rf "$work"
