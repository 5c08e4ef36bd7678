"""Pictures of a capability map (matplotlib): slices of the reachability index, a 3-D view.

Every function writes PNG files whole (a temporary file renamed into place) and returns
their paths; figures are closed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from optik._files import prepare_folder, write_atomic_with
from optik.errors import OptikError
from optik.plots import pyplot


def _save(fig: Any, path: str | Path) -> Path:
    plt = pyplot()
    try:
        return write_atomic_with(
            path, lambda handle: fig.savefig(handle, format="png", dpi=110), binary=True
        )
    finally:
        plt.close(fig)


def plot_slices(ds: Any, path: str | Path, value: str = "reachability") -> Path:
    """Three slices through the reach sphere's centre (z, y and x planes) of ``value``.

    Args:
        ds: a map from :func:`optik.capability_map`.
        path: the PNG file to write.
        value: the per-voxel variable to show (``reachability``, ``manipulability``,
            ``limit_margin``).

    Raises:
        OptikError: ``value`` is not a per-voxel variable of the map.
    """
    if value not in ds or ds[value].dims != ("x", "y", "z"):
        raise OptikError(f"value: {value!r} is not a per-voxel variable of the map")
    plt = pyplot()
    centre = ds.attrs["settings"]["reach_centre_m"]
    data = ds[value]
    # Constrained: each slice's y label stands clear of its neighbour's ticks.
    fig, axes = plt.subplots(1, 3, figsize=(15.0, 4.8), layout="constrained")
    top = float(np.nanmax(data.values)) if np.any(np.isfinite(data.values)) else 1.0
    planes = (("z", "x", "y"), ("y", "x", "z"), ("x", "y", "z"))
    for ax, (plane, a, b) in zip(axes, planes, strict=True):
        level = float(ds[plane].sel({plane: centre["xyz".index(plane)]}, method="nearest"))
        layer = data.sel({plane: level}).transpose(b, a)
        image = ax.pcolormesh(
            ds[a].values, ds[b].values, layer.values, shading="nearest", vmin=0.0,
            vmax=max(top, 1e-12), cmap="viridis",
        )  # fmt: skip
        ax.set_aspect("equal")
        ax.set_xlabel(f"{a} (m)")
        ax.set_ylabel(f"{b} (m)")
        ax.set_title(f"{value}, {plane} = {level:.3g} m")
    fig.colorbar(image, ax=list(axes), shrink=0.85, label=value)
    settings = ds.attrs["settings"]
    fig.suptitle(
        f"{settings['robot']}: {settings['mode']} map, voxel {settings['voxel_m']:g} m, "
        f"{settings['samples_per_voxel']} samples per voxel"
    )
    return _save(fig, path)


def plot_scatter(ds: Any, path: str | Path, most: int = 20_000) -> Path:
    """A 3-D scatter of the reached voxels coloured by their reachability index.

    At most ``most`` voxels are drawn (every k-th, in grid order) so a fine map stays
    quick to draw.
    """
    plt = pyplot()
    index = ds["reachability"].values
    ix, iy, iz = np.nonzero(index > 0)
    step = max(len(ix) // most, 1)
    ix, iy, iz = ix[::step], iy[::step], iz[::step]
    fig = plt.figure(figsize=(7.0, 6.0))
    ax = fig.add_subplot(projection="3d")
    points = ax.scatter(
        ds["x"].values[ix], ds["y"].values[iy], ds["z"].values[iz], c=index[ix, iy, iz],
        s=4, cmap="viridis", vmin=0.0, vmax=1.0,
    )  # fmt: skip
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    # Padded: the z label sits between the axes and the colour bar.
    fig.colorbar(points, ax=ax, shrink=0.7, pad=0.12, label="reachability index")
    ax.set_title(f"{ds.attrs['settings']['robot']}: reached voxels")
    return _save(fig, path)


def plot_map(ds: Any, folder: str | Path) -> list[Path]:
    """``reachability.png``, ``manipulability.png`` (slices) and ``map3d.png`` in ``folder``.

    Args:
        ds: a map from :func:`optik.capability_map` (or :func:`open_map`).
        folder: the folder to write the three PNG files in (created if missing).
    """
    out = prepare_folder(folder)
    return [
        plot_slices(ds, out / "reachability.png", "reachability"),
        plot_slices(ds, out / "manipulability.png", "manipulability"),
        plot_scatter(ds, out / "map3d.png"),
    ]


__all__ = ["plot_map", "plot_scatter", "plot_slices"]
