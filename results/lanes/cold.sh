#!/bin/sh
# One whole `pidm run SCENE --backend gpu` on lavapipe with empty pipeline
# caches, pidm's and Mesa's (a first run on a fresh machine), or, with a
# third argument TAG, with the caches of TAG kept in /tmp between runs
# (warm). Usage: sh results/lanes/cold.sh PIDM SCENE [TAG]
d=$(mktemp -d)
cache=$d
[ -n "$3" ] && cache=/tmp/pidm-warm-$3 && mkdir -p "$cache"
PIDM_CACHE_DIR=$cache/pidm MESA_SHADER_CACHE_DIR=$cache/mesa WGPU_BACKEND=vulkan \
    "$1" run "$2" --backend gpu --out "$d/out.h5" > /dev/null 2>&1
rc=$?
rm -rf "$d"
exit $rc
