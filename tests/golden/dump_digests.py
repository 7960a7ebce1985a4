#!/usr/bin/env python3
"""Writes a digest of every numeric dataset of result files, one line per
dataset: the file's stem (the test's label of the run), the dataset's path, its element count and the
64-bit FNV-1a hash of its bytes (little-endian, row-major).
tests/it/load.rs and tests/it/replicas.rs compare the current binary's
files with the lines zero_load.txt and replicas_one.txt hold, which
write_goldens.sh writes with this script from a binary's runs of the
scenes those tests run, each run into LABEL.h5:

    python3 tests/golden/dump_digests.py LABEL.h5 ...

The test computes the same digest in Rust, so the two must stay one rule:
FNV-1a 64 (offset 0xcbf29ce484222325, prime 0x100000001b3) over the bytes.
"""

import os
import sys

import h5py
import numpy as np

FNV_OFFSET = 0xCBF29CE484222325
FNV_PRIME = 0x100000001B3
MASK = (1 << 64) - 1
# The groups whose datasets a run computes; /axes, /labels and /shard
# come from the scene.
GROUPS = ("maps", "baseline", "trajectories", "refine")


def fnv1a(data: bytes) -> int:
    h = FNV_OFFSET
    for byte in data:
        h = ((h ^ byte) * FNV_PRIME) & MASK
    return h


def datasets(group, prefix=""):
    for name in sorted(group):
        item = group[name]
        path = f"{prefix}/{name}"
        if isinstance(item, h5py.Group):
            yield from datasets(item, path)
        elif item.dtype.kind in "fiu":
            yield path, item


for path in sys.argv[1:]:
    with h5py.File(path) as f:
        name = os.path.splitext(os.path.basename(path))[0]
        for group in GROUPS:
            if group not in f:
                continue
            for ds_path, ds in datasets(f[group], "/" + group):
                values = np.ascontiguousarray(ds[()])
                values = values.astype(values.dtype.newbyteorder("<"), copy=False)
                print(f"{name} {ds_path} {values.size} {fnv1a(values.tobytes()):016x}")
