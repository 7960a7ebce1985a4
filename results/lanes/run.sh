#!/usr/bin/env bash
# The lanes' figures (issue 38) of one scene on the GPU path, change by
# change: a lane per instance without packing (the dispatch of 00e0549),
# then packing the busy lanes, then the queue on the adapter's lanes in
# index order, then in cost order (the default). Prints each run's
# integration time and its phase-table lines on lanes, warps and the
# critical path. Usage (lavapipe: WGPU_BACKEND=vulkan):
#   bash results/lanes/run.sh PIDM SCENE INSTANCES
set -euo pipefail
pidm=${1:?the pidm binary}
scene=${2:?a scene}
n=${3:?its instance count (a lane per instance)}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() {
    echo "== $1"
    shift
    env "$@" "$pidm" run "$scene" --backend gpu --out "$out/map.h5" --profile 2>&1 |
        grep -E "s integrating|phase   dispatches|phase lanes:|warps of|slots by kind|together|critical path|keeps"
}
run "a lane per instance, not packed" PIDM_GPU_LANES="$n" PIDM_GPU_COMPACT=0 PIDM_GPU_ORDER=index
run "a lane per instance, packed" PIDM_GPU_LANES="$n" PIDM_GPU_COMPACT=1 PIDM_GPU_ORDER=index
run "the queue on the adapter's lanes, index order" PIDM_GPU_COMPACT=1 PIDM_GPU_ORDER=index
run "the queue on the adapter's lanes, cost order (default)" PIDM_GPU_COMPACT=1 PIDM_GPU_ORDER=cost
