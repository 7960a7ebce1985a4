#!/usr/bin/env bash
# The restructure's check (issue 48): every shipped scene (sweeps/*.toml) as
# shipped, on the CPU and on lavapipe in f64, digested by dump_digests.py.
#   bash tests/golden/house.sh write   # tests/golden/house.txt from PIDM's runs
#   bash tests/golden/house.sh check   # PIDM's runs against house.txt, bit for bit
# PIDM defaults to target/release/pidm; run from anywhere with
# WGPU_BACKEND=vulkan. house.txt's header names the commit that wrote it.
# PIDM_GPU_TAIL=0: the CPU takes over no batch's tail, whose members depend
# on the lanes' timing, so the device's maps are the same bits every run.
set -euo pipefail
mode=${1:?write or check}
cd "$(dirname "$0")/../.."
pidm=${PIDM:-$PWD/target/release/pidm}
golden=tests/golden/house.txt
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
files=()
for scene in sweeps/*.toml; do
    name=$(basename "$scene" .toml)
    for backend in cpu gpu; do
        out="$work/${name}_$backend.h5"
        start=$(date +%s.%N)
        # Stress scenes exit non-zero by design; the file is what counts.
        PIDM_GPU_TAIL=0 "$pidm" run "$scene" --backend "$backend" --precision f64 --progress none \
            --out "$out" > /dev/null 2>&1 || [ -f "$out" ]
        printf '%-18s %-3s %6.1f s\n' "$name" "$backend" "$(echo "$(date +%s.%N) - $start" | bc)" >&2
        files+=("$out")
    done
done
python3 tests/golden/dump_digests.py "${files[@]}" > "$work/now.txt"
case $mode in
write)
    {
        echo "# tests/golden/house.sh: every shipped scene on the CPU and on lavapipe in f64,"
        echo "# written by the binary of $(git rev-parse --short HEAD) (say in this header what moved the lines that changed)."
        cat "$work/now.txt"
    } > "$golden"
    echo "wrote $golden" ;;
check)
    if diff <(grep -v '^#' "$golden") "$work/now.txt"; then
        echo "every shipped scene bit for bit as in $golden"
    else
        echo "differs from $golden (lines above)" >&2
        exit 1
    fi ;;
*) echo "write or check, not $mode" >&2; exit 2 ;;
esac
