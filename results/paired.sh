#!/usr/bin/env bash
# Paired whole-process timings: runs command A and command B in turn, N
# times each (A B A B ...), after one warm-up run of each, and prints each
# pair's wall seconds, then the medians of A, B and of the ratio A/B taken
# pair by pair (pairing keeps the ratio meaningful on a machine whose speed
# drifts). Usage:
#   bash results/paired.sh N 'COMMAND A' 'COMMAND B'
# Each command is run by `sh -c`, its output thrown away.
set -euo pipefail
n=${1:?runs of each}
a=${2:?command A}
b=${3:?command B}
wall() {
    local start end
    start=$(date +%s.%N)
    sh -c "$1" > /dev/null 2>&1
    end=$(date +%s.%N)
    awk -v s="$start" -v e="$end" 'BEGIN { printf "%.3f", e - s }'
}
wall "$a" > /dev/null
wall "$b" > /dev/null
pairs=()
for _ in $(seq "$n"); do
    ta=$(wall "$a")
    tb=$(wall "$b")
    echo "A $ta s  B $tb s  A/B $(awk -v x="$ta" -v y="$tb" 'BEGIN { printf "%.4f", x / y }')"
    pairs+=("$ta $tb")
done
printf '%s\n' "${pairs[@]}" | awk '
    { a[NR] = $1; b[NR] = $2; r[NR] = $1 / $2 }
    function median(x, n,   i, j, t) {
        for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (x[j] < x[i]) { t = x[i]; x[i] = x[j]; x[j] = t }
        return n % 2 ? x[(n + 1) / 2] : (x[n / 2] + x[n / 2 + 1]) / 2
    }
    END { printf "medians over %d pairs: A %.3f s, B %.3f s, A/B %.4f\n", NR, median(a, NR), median(b, NR), median(r, NR) }'
