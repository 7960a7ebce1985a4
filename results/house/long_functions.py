#!/usr/bin/env python3
"""Functions in src/ longer than a screen (issue 48's count): every `fn`
from its line to the closing brace at its own indentation, past LIMIT
lines (default 120), longest first.

    python3 results/house/long_functions.py [DIR] [LIMIT]
"""

import pathlib
import re
import sys

FN = re.compile(r"^(\s*)(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?fn\s+(\w+)")


def long_functions(root: pathlib.Path, limit: int):
    for path in sorted(root.rglob("*.rs")):
        lines = path.read_text().split("\n")
        for i, line in enumerate(lines):
            m = FN.match(line)
            if not m:
                continue
            indent = len(m.group(1))
            closing = m.group(1) + "}"
            for j in range(i + 1, len(lines)):
                if lines[j] == closing:
                    if j - i + 1 > limit:
                        yield j - i + 1, f"{path}:{i + 1}", m.group(7)
                    break
                # A `fn` in a string (generated WGSL) has no closing brace
                # of its own at its indentation: the next item ends it.
                later = FN.match(lines[j])
                if later and len(later.group(1)) <= indent:
                    break


def main() -> int:
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "src")
    limit = int(sys.argv[2]) if len(sys.argv) > 2 else 120
    rows = sorted(long_functions(root, limit), reverse=True)
    for n, where, name in rows:
        print(f"{n:5} {where} {name}")
    print(f"{len(rows)} functions past {limit} lines in {root}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
