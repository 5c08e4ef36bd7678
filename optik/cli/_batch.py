"""``optik batch``: IK for a file of targets, in-process or on Dask, to Parquet."""

from __future__ import annotations

import argparse
import time
from collections import Counter
from typing import Any

from optik.campaign.batch import DEFAULT_CHUNK, solve_batch
from optik.cli._common import (
    EXIT_OK,
    add_engine_arguments,
    add_out_argument,
    add_robot_arguments,
    campaign_keywords,
    command,
    non_negative_int,
    path_text,
    positive_float,
    positive_int,
    problem_from_args,
    seed_int,
)
from optik.ik import DEFAULT_RESTARTS


def _cmd_batch(args: argparse.Namespace) -> int:
    problem = problem_from_args(args)
    robot = problem.robot
    start = time.perf_counter()
    table = solve_batch(robot, args.targets, max_iter=args.max_iter, **campaign_keywords(args))
    wall = time.perf_counter() - start
    n = table.num_rows
    counts = Counter(table.column("status").to_pylist())
    solved = counts.get("converged", 0)
    print(
        f"{problem.name}: {n} targets ({args.mode} mode), {solved} converged, "
        f"{n - solved} not, in {wall:.1f} s ({n / max(wall, 1e-9):.0f} per s)"
    )
    for status, count in sorted(counts.items()):
        print(f"  {status:<16}{count}")
    print(f"  wrote {args.out} (one row per target: status, q, errors in m and rad)")
    return EXIT_OK


def add_batch_command(sub: Any) -> None:
    p = command(
        sub,
        "batch",
        "IK for a file of targets, chunk by chunk, to Parquet",
        "Solve every target of TARGETS (.npy: (N, 4, 4) poses or (N, 3) positions, m; "
        ".parquet: columns x, y, z in m and qw, qx, qy, qz for an orientation) and write "
        "one row per target (index, status, success, q per joint, position and orientation "
        "errors, limit violation, iterations, restarts) to a Parquet folder of part files. "
        "Target k uses the seed SEED + k: the results do not depend on --workers, "
        "--scheduler or --chunk. A progress bar is drawn on a terminal.",
        "  optik batch ur5 targets.npy --out results.parquet\n"
        "  optik batch panda targets.parquet --out results.parquet --workers 2\n"
        "  optik batch ur5 points.npy --mode position --out points.parquet --resume\n",
    )
    add_robot_arguments(p)
    p.add_argument(
        "targets",
        metavar="TARGETS",
        type=path_text,
        help="the targets file, .npy or .parquet (m; no unit for quaternions)",
    )
    p.add_argument(
        "--mode",
        choices=["pose", "position", "orientation", "axis"],
        default="pose",
        help="the task of every target (no unit; default pose)",
    )
    p.add_argument(
        "--axis",
        choices=["x", "y", "z"],
        default="z",
        help="the tool axis of --mode axis (no unit; default z)",
    )
    p.add_argument(
        "--tol", type=positive_float, default=1e-6, help="IK tolerance, m and rad (default 1e-6)"
    )
    p.add_argument(
        "--restarts",
        type=non_negative_int,
        default=DEFAULT_RESTARTS,
        help=f"numeric restarts per target (no unit; default {DEFAULT_RESTARTS})",
    )
    p.add_argument(
        "--max-iter",
        type=positive_int,
        default=100,
        help="iterations per attempt (no unit; default 100)",
    )
    p.add_argument(
        "--seed", type=seed_int, default=0, help="base seed: target k uses SEED + k (no unit)"
    )
    p.add_argument(
        "--chunk",
        type=positive_int,
        default=DEFAULT_CHUNK,
        help=f"targets per chunk (no unit; default {DEFAULT_CHUNK})",
    )
    add_out_argument(
        p, "PATH", "the Parquet folder to write (no unit); it must not exist unless --resume"
    )
    add_engine_arguments(p)
    p.set_defaults(func=_cmd_batch)
