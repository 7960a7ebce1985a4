"""Loads a pidm step map with xarray and draws it with matplotlib.

    pip install xarray h5netcdf matplotlib
    cargo run --release -- run sweeps/coupling.toml
    python3 examples/plot_map.py results/coupling.h5 --out coupling_step_x.png

The file follows the netCDF-4 conventions, so `xarray.open_dataset` returns
labelled arrays: the dimensions are the scene's grid axes (for example
`axis.x.voltage`), with their values and units as coordinates.
"""

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import xarray as xr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", help="a pidm result file (.h5)")
    parser.add_argument("--map", default="step_x", help="variable to draw")
    parser.add_argument("--out", default="map.png", help="PNG to write")
    args = parser.parse_args()

    ds = xr.open_dataset(args.file, engine="h5netcdf")
    # Steps are stored in metres per drive cycle; show micrometres, and
    # leave out instances whose integration did not finish (status != 0).
    step = (ds[args.map] * 1e6).where(ds["status"] == 0)
    step.attrs["units"] = "um"
    step.attrs["long_name"] = ds[args.map].attrs["long_name"]

    fig, ax = plt.subplots(figsize=(6, 4.5))
    if step.ndim == 2:
        # A diverging colour scale centred on zero: a reversal of the
        # direction of motion shows as a change of hue.
        limit = float(np.nanmax(np.abs(step.values))) or 1.0
        step.plot(ax=ax, cmap="RdBu_r", vmin=-limit, vmax=limit)
    elif step.ndim == 1:
        step.plot(ax=ax, marker="o")
        ax.axhline(0.0, color="grey", linewidth=0.5)
    else:
        raise SystemExit(f"{args.map} has {step.ndim} dimensions; select a 2-D slice first")
    ax.set_title(f"{ds.attrs['name']}: {args.map} [um per cycle]")
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
