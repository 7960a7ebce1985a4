#!/usr/bin/env bash
# Unpacks Mesa >= 25's RADV (Debian bookworm-backports' mesa-vulkan-drivers)
# into a private folder, beside the system's Mesa: lavapipe stays as it is,
# and only pidm's RADV probe (`pidm isa-probe`, a child of `pidm info
# --shader` and of tests/it/registers.rs) loads it, through LD_LIBRARY_PATH
# and VK_ICD_FILENAMES. RADV_FORCE_FAMILY then opens an AMD GPU that is not
# there and compiles pipelines with ACO (issue 57). Runs as root; about 12 MB.
#   bash .ci/radv.sh [DEST]   (default: $PIDM_RADV, else /opt/mesa-backports)
set -euo pipefail
dest=${1:-${PIDM_RADV:-/opt/mesa-backports}}
if [ -f "$dest/radeon.json" ] && [ -f "$dest/root/usr/lib/x86_64-linux-gnu/libvulkan_radeon.so" ]; then
    echo "RADV already in $dest"
    exit 0
fi
# The backports suite of the archive this machine already uses (its first
# deb822 stanza), for `apt-get download` only: nothing is installed from it.
if [ ! -f /etc/apt/sources.list.d/backports.sources ]; then
    awk 'BEGIN{RS=""} NR==1' /etc/apt/sources.list.d/debian.sources \
        | sed -e 's/^Suites:.*/Suites: bookworm-backports/' -e '/^#/d' \
        > /etc/apt/sources.list.d/backports.sources
fi
apt-get update -qq
mkdir -p "$dest/debs"
(cd "$dest/debs" && apt-get download -t bookworm-backports mesa-vulkan-drivers libdrm2 libdrm-amdgpu1)
for d in "$dest"/debs/*.deb; do dpkg -x "$d" "$dest/root"; done
python3 - "$dest" <<'PY'
import json, sys
d = sys.argv[1]
j = json.load(open(f"{d}/root/usr/share/vulkan/icd.d/radeon_icd.json"))
j["ICD"]["library_path"] = f"{d}/root/usr/lib/x86_64-linux-gnu/libvulkan_radeon.so"
json.dump(j, open(f"{d}/radeon.json", "w"))
PY
echo "RADV unpacked into $dest"
