"""Writes a nudged twin of a random scene (results/gpu.md, "Band grazes"):
every point's slider mass, velocity band, and each axis' stage mass,
stiffness, damping and voltage scaled by
1 + side * s * DELTA, and the friction pair by one such factor, with a sign
s per parameter drawn from SEED (the same draws for both sides, so side +1
and -1 are opposite nudges).

    python3 results/twins/nudge.py SCENE DELTA SEED OUT SIDE
"""

import random
import re
import sys

KEYS = [
    "slider_mass",
    "static_friction",
    "coulomb_friction",
    "velocity_band",
    "stage_mass",
    "stiffness",
    "damping",
    "voltage",
]
PATTERN = re.compile(r"\b(" + "|".join(KEYS) + r") = ([-0-9.eE+]+)")


def main():
    src, delta, seed, out, side = sys.argv[1:6]
    delta, side = float(delta), int(side)
    rng = random.Random(int(seed))

    def nudge_line(line):
        friction = rng.choice((-1, 1))

        def nudge(m):
            s = friction if m.group(1).endswith("friction") else rng.choice((-1, 1))
            return f"{m.group(1)} = {float(m.group(2)) * (1 + side * delta * s)!r}"

        return PATTERN.sub(nudge, line)

    with open(src) as f, open(out, "w") as g:
        g.writelines(
            nudge_line(line) if line.startswith(("mechanism", "axis")) else line for line in f
        )


if __name__ == "__main__":
    main()
