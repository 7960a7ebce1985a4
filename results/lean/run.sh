#!/usr/bin/env bash
# Issue 47's figures (results/lean.md) on the build machine, this build
# against an older one, OLD (a build of 51e74a2: `git worktree add /tmp/old
# 51e74a2 && cd /tmp/old && cargo build --release`):
#   1. what a lane carries: `pidm info --shader` (every variant's footprint,
#      the emulated f64 operations per slip trial on a probe);
#   2. the slip trials rejected and the emulated f64 operations, from
#      `--profile` of random 2,000 (seed 11, 4 cycles) on the CPU (one
#      thread) and on lavapipe in f64, both builds (OLD's CPU does not
#      count its iterations);
#   3. whole processes paired (this build and OLD in turn, wall seconds
#      by /usr/bin/time): the CPU on one thread and lavapipe f64 on
#      random 2,000 (RUNS pairs each, default 5), each pair's ratio;
#   4. accuracy: both builds' CPU maps of random 2,000 against the map at
#      tolerance 1e-8 (results/lean/compare.py).
# From the repository root after `cargo build --release`:
#   bash results/lean/run.sh OLD_PIDM
set -euo pipefail
new=$PWD/target/release/pidm
old=${1:?an older pidm binary}
runs=${RUNS:-5}
export WGPU_BACKEND=vulkan
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
echo "== 1. footprints (this build)"
"$new" info --shader "$work/shaders"
"$new" random-scene --seed 11 --count 2000 --cycles 4 --compact > r2000.toml
sed 's/^settle = 1/settle = 1\ntolerance = 1e-8/' r2000.toml > r2000_ref.toml
echo "== 2. profiles"
for b in new old; do
    bin=${!b}
    echo "-- $b, CPU, one thread"
    "$bin" run r2000.toml --backend cpu --threads 1 --profile --out "cpu_$b.h5" 2>&1 |
        grep -E "^wrote|CPU integrator|rejected trials" || true
    echo "-- $b, lavapipe f64"
    "$bin" run r2000.toml --backend gpu --precision f64 --profile --out "gpu_$b.h5" 2>&1 |
        grep -E "^wrote|GPU ready|slots by kind|rejected trials|emulated|phase   dispatches" || true
done
echo "== 3. whole processes, paired (this build / OLD, wall seconds)"
# Wall seconds of one whole process.
wall() { /usr/bin/time -f %e "$@" 2>&1 > /dev/null | tail -1; }
pairs() {
    for _ in $(seq "$runs"); do
        a=$(wall "$new" "$@" --out n.h5)
        b=$(wall "$old" "$@" --out o.h5)
        echo "$a $b" | awk '{ printf "%7.2f s / %7.2f s = %.3f\n", $1, $2, $1 / $2 }'
    done
}
echo "-- CPU, one thread"
pairs run r2000.toml --backend cpu --threads 1 --progress none
echo "-- lavapipe f64"
pairs run r2000.toml --backend gpu --precision f64 --progress none
echo "== 4. accuracy against tolerance 1e-8 (this build's reference), and lavapipe against the CPU"
"$new" run r2000_ref.toml --backend cpu --progress none --out ref.h5 > /dev/null
python3 "$OLDPWD/results/lean/compare.py" ref.h5 cpu_new.h5 cpu_old.h5
python3 "$OLDPWD/results/lean/compare.py" cpu_new.h5 gpu_new.h5
python3 "$OLDPWD/results/lean/compare.py" cpu_old.h5 gpu_old.h5
