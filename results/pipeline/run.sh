#!/usr/bin/env bash
# The pipeline's cost and gain on the 2-core build machine (issue 32):
# whole `pidm run` processes, paired (results/paired.sh), pipelined (the
# default) against chunks one after another (PIDM_PIPELINE=0) and against
# an older build (OLD, default: none), on the CPU and on lavapipe; then one
# profile table of each.
#
#   bash results/pipeline/run.sh [OLD_PIDM]
#
# Run from the repository root after `cargo build --release`.
set -euo pipefail
new=./target/release/pidm
old=${1:-}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed -e 's/steps = 61/steps = 400/g' sweeps/coupling.toml > "$work/c400.toml"
sed -e 's/steps = 61/steps = 200/g' sweeps/coupling.toml > "$work/c200.toml"
export WGPU_BACKEND=vulkan
pair() {
    local label=$1 scene=$2 backend=$3 base=$4
    echo "== $label: A = pipelined, B = $base"
    bash results/paired.sh 5 \
        "$new run $scene --out $work/a.h5 --backend $backend" \
        "$( [ "$base" = unpipelined ] && echo "PIDM_PIPELINE=0 $new" || echo "$old" ) run $scene --out $work/b.h5 --backend $backend" |
        tail -1
}
pair "CPU, coupling 400 x 400" "$work/c400.toml" cpu unpipelined
pair "lavapipe f64, coupling 200 x 200" "$work/c200.toml" gpu unpipelined
if [ -n "$old" ]; then
    pair "CPU, coupling 400 x 400" "$work/c400.toml" cpu "$old"
    pair "lavapipe f64, coupling 200 x 200" "$work/c200.toml" gpu "$old"
fi
echo "== profile, CPU, coupling 400 x 400"
"$new" run "$work/c400.toml" --out "$work/a.h5" --backend cpu --profile 2>&1 | grep "phase"
echo "== profile, lavapipe f64, coupling 200 x 200"
"$new" run "$work/c200.toml" --out "$work/a.h5" --backend gpu --profile 2>&1 | grep "phase"
