"""Draws results/waveform/backward.png from the backward-travel map of
results/waveform/backward.toml (`pidm run results/waveform/backward.toml
--out wb.h5 && python3 results/waveform/backward_plot.py wb.h5`): the step
and the backward ratio over the trapezoid's rise and fall fractions."""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import xarray as xr

ds = xr.open_dataset(sys.argv[1], engine="h5netcdf")
fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
for ax, (name, scale, label, cmap) in zip(
    axes,
    [
        ("step_x", 1e6, "step_x [um per cycle]", "RdBu"),
        ("backward_ratio_x", 1.0, "backward_ratio_x = B / (|step| + B)", "viridis"),
    ],
):
    values = ds[name] * scale
    limit = float(abs(values).max()) if name == "step_x" else None
    values.plot(
        ax=ax,
        x="axis.x.fall",
        y="axis.x.rise",
        cmap=cmap,
        vmin=-limit if limit else 0.0,
        vmax=limit if limit else 1.0,
        cbar_kwargs={"label": label},
    )
    ax.set_title(label)
fig.suptitle("Table 1, 100 V, 10 Hz, trapezoid (rise, 0, fall): results/waveform/backward.toml")
out = Path(__file__).with_name("backward.png")
fig.savefig(out, dpi=90)
print(out)
