#!/usr/bin/env bash
# Rewrites the golden files the bit-for-bit tests hold the binary to, from
# the runs of PIDM (default target/release/pidm), exactly as the tests run
# them:
#   zero_load.txt     tests/it/load.rs: every shipped scene of its RUNS on
#                     the CPU (steady ones as single chains, replicas = 1),
#                     digested by dump_digests.py
#   replicas_one.txt  tests/it/replicas.rs: replicas_one.toml with
#                     replicas = 1 on the CPU and on lavapipe in f64
#   window.txt        tests/it/steady.rs: window_random.toml and
#                     window_grid.toml on the CPU, by dump_window.py
# Each file's header names the commit that wrote it. Run it only where the
# integrator's results are meant to change (issue 47 changed its steps),
# from the repository root after `cargo build --release`:
#   WGPU_BACKEND=vulkan bash tests/golden/write_goldens.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
pidm=${PIDM:-$PWD/target/release/pidm}
commit=$(git rev-parse --short HEAD)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
golden=tests/golden

# The scenes of tests/it/load.rs's RUNS: label, scene, precision.
runs="beats:beats:f64 coupling:coupling:f64 extreme:extreme:f64 frequency:frequency:f64
paper:paper:f64 paper_text:paper_text:f64 random:random:f64
refine_coupling:refine_coupling:f64 stress:stress:f64 two_frequency:two_frequency:f64
paper_f32:paper:f32 coupling_f32:coupling:f32 stress_f32:stress:f32"
files=()
for run in $runs; do
    IFS=: read -r label scene precision <<< "$run"
    mkdir -p "$work/$label"
    copy="$work/$label/$scene.toml"
    # As the test's single_chains: a steady scene runs every instance as
    # one chain.
    if grep -q 'measure = "window"' "sweeps/$scene.toml"; then
        cp "sweeps/$scene.toml" "$copy"
    elif grep -q '^\[simulation\]$' "sweeps/$scene.toml"; then
        sed '0,/^\[simulation\]$/s//[simulation]\nreplicas = 1/' "sweeps/$scene.toml" > "$copy"
    else
        { cat "sweeps/$scene.toml"; printf '\n[simulation]\nreplicas = 1\n'; } > "$copy"
    fi
    (cd "$work/$label" && "$pidm" run "$copy" --backend cpu --precision "$precision" \
        --progress none --out "$work/$label.h5" > /dev/null 2>&1) || [ -f "$work/$label.h5" ]
    files+=("$work/$label.h5")
done
{
    echo "# tests/it/load.rs: the shipped scenes at zero load, written by the binary of"
    echo "# $commit (tests/golden/write_goldens.sh; the lines before were 8894696's,"
    echo "# before the load, which the binary matched bit for bit until issue 47"
    echo "# changed the integrator's steps)."
    python3 "$golden/dump_digests.py" "${files[@]}" | grep -v ' /maps/replicas '
} > "$golden/zero_load.txt"

cp "$golden/replicas_one.toml" "$work/replicas_one.toml"
echo "replicas = 1" >> "$work/replicas_one.toml"
"$pidm" run "$work/replicas_one.toml" --backend cpu --precision f64 --progress none \
    --out "$work/cpu_f64_steady.h5" > /dev/null
"$pidm" run "$work/replicas_one.toml" --backend gpu --precision f64 --progress none \
    --out "$work/gpu_f64_steady.h5" > /dev/null
{
    echo "# tests/it/replicas.rs: tests/golden/replicas_one.toml with replicas = 1,"
    echo "# written by the binary of $commit on the CPU and on lavapipe in f64"
    echo "# (tests/golden/write_goldens.sh; 00e0549's, before replicas, until issue 47)."
    python3 "$golden/dump_digests.py" "$work/cpu_f64_steady.h5" "$work/gpu_f64_steady.h5" |
        grep -v '/maps/replicas '
} > "$golden/replicas_one.txt"

for scene in window_random window_grid; do
    "$pidm" run "$golden/$scene.toml" --backend cpu --progress none --out "$work/$scene.h5" > /dev/null
done
{
    echo "# tests/it/steady.rs: window_random.toml and window_grid.toml, written by"
    echo "# the binary of $commit (tests/golden/write_goldens.sh; 7916a32's, before"
    echo "# the steady measurement, until issue 47)."
    python3 "$golden/dump_window.py" "$work/window_random.h5" "$work/window_grid.h5"
} > "$golden/window.txt"
echo "wrote $golden/zero_load.txt, $golden/replicas_one.txt and $golden/window.txt ($commit)"
