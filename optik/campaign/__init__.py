"""Campaigns: chunked IK work (batches of targets, capability maps, base placement).

Every campaign runs through :func:`optik.campaign.engine.run_chunks`: in-process by
default, or on Dask (a local cluster or any scheduler), with the same answers either way.
The Dask, Zarr, xarray and Parquet packages come with the ``cluster`` extra and are
imported only when a campaign runs.
"""

from optik.campaign.batch import read_targets, solve_batch
from optik.campaign.capability import capability_map, open_map
from optik.campaign.engine import Engine, open_engine, run_chunks
from optik.campaign.placement import BasePlacements, Placement, base_placement
from optik.campaign.plots import plot_map

__all__ = [
    "BasePlacements",
    "Engine",
    "Placement",
    "base_placement",
    "capability_map",
    "open_engine",
    "open_map",
    "plot_map",
    "read_targets",
    "run_chunks",
    "solve_batch",
]
