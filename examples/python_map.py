"""Maps the step of a two-axis piezo drive over V_x and V_y with the pidm Python API
and draws it with xarray and matplotlib.

    cargo build --release
    export PIDM_BINARY=$PWD/target/release/pidm
    pip install ./python matplotlib
    python3 examples/python_map.py --steps 21 --out vx_vy.png

Each instance drives both stages of Table 1 at 10 Hz, x from 0 to 150 V and y from
0 to 150 V; the step per drive cycle along x and along y is shown in micrometres
on a diverging scale (red forward, blue backward, white no motion); instances
whose integration did not finish (status != 0) are left blank.
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pidm


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=11, help="voltages per axis")
    parser.add_argument(
        "--max-cycles",
        type=int,
        default=2000,
        help="most scene periods an instance may run (the steady measurement stops earlier)",
    )
    parser.add_argument("--backend", default="auto", help="auto, cpu or gpu")
    parser.add_argument("--out", default="python_map.png", help="PNG to write")
    args = parser.parse_args()

    volts = {"from": 0.0, "to": 150.0, "steps": args.steps}
    scene = {
        "name": "python_map",
        "axis": {"x": {"voltage": volts}, "y": {"voltage": volts}},
        "simulation": {"max_cycles": args.max_cycles},
    }
    print(f"{pidm.check(scene)['instances']} instances")
    ds = pidm.run(scene, backend=args.backend)

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for ax, name in zip(axes, ("step_x", "step_y")):
        step = (ds[name] * 1e6).where(ds.status == 0)
        step.attrs = {"units": "um", "long_name": ds[name].attrs["long_name"]}
        limit = float(np.nanmax(np.abs(step.values))) or 1.0
        step.plot(ax=ax, x="axis.x.voltage", cmap="RdBu_r", vmin=-limit, vmax=limit)
        ax.set_xlabel("V_x [V]")
        ax.set_ylabel("V_y [V]")
        ax.set_title(f"{name} [um per own drive cycle]")
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
