"""``optik map``: a capability map of a robot, in-process or on Dask, to Zarr."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from optik._files import check_folder
from optik.campaign import capability_map, plot_map
from optik.campaign.capability import read_variable
from optik.cli._campaign import add_campaign_ik_arguments, add_engine_arguments, run_campaign
from optik.cli._common import (
    EXIT_OK,
    add_out_argument,
    add_robot_arguments,
    command,
    length_float,
    path_text,
    positive_float,
    positive_int,
)
from optik.errors import OptikError


def _cmd_map(args: argparse.Namespace) -> int:
    if args.plots is not None:
        check_folder(args.plots)  # before the map is computed, not after
    bounds = None if args.bounds is None else np.reshape(args.bounds, (3, 2))
    problem, ds, wall = run_campaign(
        args,
        capability_map,
        voxel=args.voxel,
        bounds=bounds,
        orientations=args.orientations,
        rolls=args.rolls,
        keep_q=args.keep_q,
    )
    settings = ds.attrs["settings"]
    where = str(args.out) if args.out is not None else "the map"
    inside = read_variable(ds, "inside", where)
    index = read_variable(ds, "reachability", where)
    samples = int(inside.sum()) * int(settings["samples_per_voxel"])
    print(
        f"{problem.name}: {settings['mode']} map, voxel {settings['voxel_m']:g} m, "
        f"grid {'x'.join(str(n) for n in settings['shape'])}, "
        f"{settings['samples_per_voxel']} samples per voxel ({ds.attrs['engine']})"
    )
    print(
        f"  {int(inside.sum())} voxels inside the reach sphere (radius "
        f"{settings['reach_radius_m']:.4g} m), {int((index > 0).sum())} reached; mean "
        f"reachability index inside {float(index[inside].mean()) if inside.any() else 0:.3f}"
    )
    # The rate counts the samples this run solved, not those a --resume found written.
    resumed = int(ds.attrs.get("resumed_samples", 0))
    computed = samples - resumed
    rate = computed / max(wall, 1e-9)
    line = f"  {computed} IK samples in {wall:.1f} s wall, start-up included ({rate:.0f} per s)"
    print(f"{line}, {resumed} resumed from an earlier run" if resumed else line)
    print(f"  wrote {args.out}")
    if args.plots is not None:
        try:
            files = plot_map(ds, args.plots)
        except OptikError as exc:  # pragma: no cover - only without matplotlib
            print(f"  (no plots: {exc})")
        else:
            print("  wrote " + ", ".join(str(f) for f in files))
    return EXIT_OK


def add_map_command(sub: Any) -> None:
    p = command(
        sub,
        "map",
        "a capability map: where the robot reaches, from how many orientations",
        "Sample every voxel centre inside the robot's reach sphere with orientations on "
        "the Fibonacci sphere, solve every sample (verified by FK and the limits) and write "
        "the map as Zarr, chunk by chunk: the reachability index, best manipulability and "
        "mean limit margin per voxel. Runs in this process, on a local Dask cluster "
        "(--workers) or on a running scheduler (--scheduler), with the same result. A "
        "progress bar is drawn on a terminal.",
        "  optik map ur5 --voxel 0.05 --orientations 50 --out ur5-map.zarr\n"
        "  optik map panda --voxel 0.02 --out panda.zarr --workers 2 --plots panda-plots\n"
        "  optik map ur5 --out ur5-map.zarr --resume --scheduler tcp://10.0.0.5:8786\n",
    )
    add_robot_arguments(p)
    p.add_argument(
        "--voxel", type=positive_float, default=0.02, help="voxel edge, m (default 0.02)"
    )
    p.add_argument(
        "--bounds",
        nargs=6,
        type=length_float,
        metavar=("XMIN", "XMAX", "YMIN", "YMAX", "ZMIN", "ZMAX"),
        help="keep voxel centres in this box, m (default: the reach sphere's box)",
    )
    p.add_argument(
        "--orientations",
        type=positive_int,
        default=100,
        help="tool-axis directions per voxel, on the Fibonacci sphere (no unit; default 100)",
    )
    p.add_argument(
        "--rolls",
        type=positive_int,
        default=1,
        help="rotations about the tool axis per direction, pose mode (no unit; default 1)",
    )
    add_campaign_ik_arguments(
        p,
        modes=("pose", "axis", "position"),
        mode_help="what a sample asks: full pose, tool axis only, or position",
        axis_help="the tool axis (of --mode pose or axis)",
        axis_modes=("pose", "axis"),
        per="sample",
        restarts=3,
        seed="base seed of the samples",
        chunk=4,
        chunk_help="voxel columns per chunk along x and y",
    )
    p.add_argument(
        "--keep-q",
        action="store_true",
        help="also store every reached sample's joint values, rad or m",
    )
    add_out_argument(p, "PATH", "the Zarr folder to write; it must not exist unless --resume")
    p.add_argument(
        "--plots",
        metavar="DIR",
        type=path_text,
        help="also write reachability.png, manipulability.png and map3d.png here",
    )
    add_engine_arguments(p)
    p.set_defaults(func=_cmd_map)
