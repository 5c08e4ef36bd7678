"""The options of the campaign commands (``optik map``, ``optik batch``) and how they run."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from typing import Any

from optik.cli._common import (
    add_seed_argument,
    add_tol_argument,
    non_negative_int,
    positive_int,
    problem_from_args,
)
from optik.errors import OptikError
from optik.problems import Problem


def add_engine_arguments(p: argparse.ArgumentParser) -> None:
    """``--workers N`` or ``--scheduler ADDRESS``, and ``--resume``: where a campaign runs."""
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=positive_int,
        metavar="N",
        help="run on a local Dask cluster of N worker processes, 1 thread each (no unit; "
        "default: in this process, on numba's threads)",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on the running Dask scheduler at ADDRESS, e.g. tcp://host:8786",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="finish the run already at --out (same settings), skipping finished chunks",
    )


def add_campaign_ik_arguments(
    p: argparse.ArgumentParser,
    *,
    modes: Sequence[str],
    mode_help: str,
    axis_help: str,
    per: str,
    restarts: int,
    seed: str,
    chunk: int,
    chunk_help: str,
    axis_modes: Sequence[str] = ("axis",),
    max_iter: bool = False,
) -> None:
    """The IK options of a campaign: --mode, --axis, --tol, --restarts, --seed, --chunk.

    The default mode is pose, the default tool axis z.

    Args:
        p: the command's parser.
        modes: the choices of ``--mode``.
        mode_help: what ``--mode`` asks of a query.
        axis_help: what ``--axis`` is.
        per: what one IK query is (``"target"``, ``"sample"``), for ``--restarts``.
        restarts: the default of ``--restarts``.
        seed: what ``--seed`` seeds.
        chunk: the default of ``--chunk``.
        chunk_help: what a chunk is counted in.
        axis_modes: the modes that read ``--axis`` (with another, it is an error).
        max_iter: also ``--max-iter`` (iterations per attempt, after ``--restarts``).
    """
    p.set_defaults(axis_modes=tuple(axis_modes))
    p.add_argument(
        "--mode", choices=list(modes), default="pose", help=f"{mode_help} (default pose)"
    )
    p.add_argument("--axis", choices=["x", "y", "z"], default=None, help=f"{axis_help} (default z)")
    add_tol_argument(p, "IK tolerance")
    p.add_argument(
        "--restarts",
        type=non_negative_int,
        default=restarts,
        help=f"numeric restarts per {per} (no unit; default {restarts})",
    )
    if max_iter:
        p.add_argument(
            "--max-iter",
            type=positive_int,
            default=100,
            help="iterations per attempt (no unit; default 100)",
        )
    add_seed_argument(p, seed)
    p.add_argument(
        "--chunk",
        type=positive_int,
        default=chunk,
        help=f"{chunk_help} (no unit; default {chunk})",
    )


#: The options of ``optik map`` and ``optik batch`` passed as they are to the campaign
#: (the IK options, ``--chunk``, ``--out``, and those of :func:`add_engine_arguments`).
CAMPAIGN_OPTIONS: tuple[str, ...] = (
    *("mode", "axis", "tol", "restarts", "seed", "chunk", "out"),
    *("workers", "scheduler", "resume"),
)


def campaign_keywords(args: argparse.Namespace) -> dict[str, Any]:
    """:data:`CAMPAIGN_OPTIONS` of ``args`` as keywords of a campaign function.

    Raises:
        OptikError: ``--axis`` given with a mode that does not read it (it would be
            ignored).
    """
    keywords = {name: getattr(args, name) for name in CAMPAIGN_OPTIONS}
    if keywords["axis"] is None:
        keywords["axis"] = "z"
    elif args.mode not in args.axis_modes:
        raise OptikError(f"--axis {args.axis} does not apply to --mode {args.mode}")
    return keywords


def run_campaign(
    args: argparse.Namespace, fn: Callable[..., Any], *inputs: Any, **keywords: Any
) -> tuple[Problem, Any, float]:
    """Run the campaign ``fn`` (``solve_batch``, ``capability_map``) on the command's robot.

    Args:
        args: the parsed options; :data:`CAMPAIGN_OPTIONS` are passed to ``fn`` as they are.
        fn: the campaign function, ``fn(robot, *inputs, **keywords, **campaign options)``.
        inputs: its positional inputs after the robot.
        keywords: its other keywords.

    Returns:
        ``(problem, answer, wall)``: the robot's problem, what ``fn`` returned, and the
        wall time of the call in s (the engine's start-up included).
    """
    problem = problem_from_args(args)
    start = time.perf_counter()
    answer = fn(problem.robot, *inputs, **keywords, **campaign_keywords(args))
    return problem, answer, time.perf_counter() - start
