#!/usr/bin/env python3
"""Writes the bits of a result file's window maps, one line per instance:
step_x step_y velocity_x velocity_y baseline_step_x baseline_step_y as f64
bits in hex, then status, steps and baseline_status. tests/it/steady.rs
compares the current binary's maps with the lines window.txt holds, which
write_goldens.sh writes with this script from a binary's maps of the
scenes beside it (7916a32's, before the steady measurement, until issue 47
changed the integrator's steps):

    python3 tests/golden/dump_window.py A.h5 ...
"""

import struct
import sys

import h5py

FLOATS = [
    "maps/step_x",
    "maps/step_y",
    "maps/velocity_x",
    "maps/velocity_y",
    "baseline/step_x",
    "baseline/step_y",
]
INTS = ["maps/status", "maps/steps", "baseline/status"]

for path in sys.argv[1:]:
    with h5py.File(path) as f:
        name = f.attrs["name"]
        name = name.decode() if isinstance(name, bytes) else name
        floats = [f[d][...].ravel() for d in FLOATS]
        ints = [f[d][...].ravel() for d in INTS]
    for k in range(floats[0].size):
        bits = [struct.pack(">d", float(c[k])).hex() for c in floats]
        print(name, k, *bits, *(int(c[k]) for c in ints))
