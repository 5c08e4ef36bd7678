"""Campaigns: chunked IK work (batches of targets, capability maps, base placement).

Every campaign runs through :func:`optik.campaign.engine.run_chunks`: in-process by
default, or on Dask (a local cluster or any scheduler), with the same answers either way.
The Dask, Zarr, xarray and Parquet packages come with the ``cluster`` extra and are
imported only when a campaign runs.
"""

from optik.campaign.batch import read_targets, solve_batch
from optik.campaign.engine import Engine, open_engine, run_chunks

__all__ = ["Engine", "open_engine", "read_targets", "run_chunks", "solve_batch"]
