"""``optik batch``: IK for a file of targets, in-process or on Dask, to Parquet."""

from __future__ import annotations

import argparse
from collections import Counter
from typing import Any

from optik.campaign.batch import DEFAULT_CHUNK, RESUMED_KEY, solve_batch
from optik.cli._campaign import add_campaign_ik_arguments, add_engine_arguments, run_campaign
from optik.cli._common import (
    EXIT_OK,
    add_out_argument,
    add_robot_arguments,
    command,
    path_text,
)
from optik.ik import DEFAULT_RESTARTS


def _cmd_batch(args: argparse.Namespace) -> int:
    problem, table, wall = run_campaign(args, solve_batch, args.targets, max_iter=args.max_iter)
    n = table.num_rows
    counts = Counter(table.column("status").to_pylist())
    solved = counts.get("converged", 0)
    # The rate counts the targets this run solved, not those a --resume found written.
    resumed = int((table.schema.metadata or {}).get(RESUMED_KEY, b"0"))
    computed = n - resumed
    rate = f"in {wall:.1f} s ({computed / max(wall, 1e-9):.0f} per s)"
    if resumed:
        rate = f"; {computed} computed {rate}, {resumed} resumed from an earlier run"
    else:
        rate = f", {rate}"
    print(
        f"{problem.name}: {n} targets ({args.mode} mode), {solved} converged, "
        f"{n - solved} not{rate}"
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
    add_campaign_ik_arguments(
        p,
        modes=("pose", "position", "orientation", "axis"),
        mode_help="the task of every target",
        axis_help="the tool axis of --mode axis",
        per="target",
        restarts=DEFAULT_RESTARTS,
        seed="base seed: target k uses SEED + k",
        chunk=DEFAULT_CHUNK,
        chunk_help="targets per chunk",
        max_iter=True,
    )
    add_out_argument(p, "PATH", "the Parquet folder to write; it must not exist unless --resume")
    add_engine_arguments(p)
    p.set_defaults(func=_cmd_batch)
