"""``optik report``: solver comparison runs and their reports."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from typing import Any

from optik.cli._common import (
    EXIT_OK,
    add_out_argument,
    add_robot_arguments,
    add_seed_argument,
    add_tol_argument,
    command,
    count_int,
    dh_problem,
    named_problem,
    path_text,
    positive_float,
    robot_choice,
    urdf_problem,
)
from optik.compare import AGREEMENT_TOL, RunConfig
from optik.compare.config import MAX_TIMEOUT_S
from optik.errors import OptikError
from optik.peers import peer_names
from optik.problems import Problem, builtin_problems
from optik.report import (
    DEFAULT_N,
    DEFAULT_TIMEOUT_S,
    default_solvers,
    make_report,
    quick_config,
)


def timeout_ms(text: str) -> float:
    """``--timeout-ms``: a finite number of ms in (0, a day] (the run's bound, in its unit)."""
    value = positive_float(text)
    if value > MAX_TIMEOUT_S * 1e3:
        raise argparse.ArgumentTypeError(
            f"expected at most {MAX_TIMEOUT_S * 1e3:.0f} ms (a day), got {text!r:.40}"
        )
    return value


def _caps(values: Sequence[str] | None) -> dict[str, int]:
    caps: dict[str, int] = {}
    for value in values or ():
        name, sep, count = value.rpartition("=")
        if not sep or not name or not count.isdigit() or not count.isascii():
            raise OptikError(f"--cap expects SOLVER=N, got {value!r:.80}")
        caps[name] = int(count)
    return caps


def peer_list(text: str) -> tuple[str, ...]:
    """``--peers``: comma-separated peer names, each one of :func:`optik.peers.peer_names`.

    Raises:
        argparse.ArgumentTypeError: an empty list or an unknown name (the valid names are
            listed; argparse exits with code 2).
    """
    names = tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    valid = peer_names()
    unknown = [n for n in names if n not in valid]
    if unknown or not names:
        what = f"unknown peer(s) {', '.join(repr(n[:40]) for n in unknown)}" if unknown else "empty"
        raise argparse.ArgumentTypeError(f"{what}; valid names: {','.join(valid)}")
    return names


def _report_problems(args: argparse.Namespace) -> tuple[str | Problem, ...] | None:
    given = robot_choice(args, positional="--problems")
    if not given:
        return None
    if args.urdf is not None:
        return (urdf_problem(args.urdf, args.base, args.tip),)
    if args.dh is not None:
        return (dh_problem(args.dh),)
    for name in args.problems:
        named_problem(name)  # an unknown name lists the built-ins before any work
    return tuple(args.problems)


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """The :class:`~optik.compare.RunConfig` of ``optik report``'s arguments."""
    timeout = None if args.timeout_ms is None else args.timeout_ms / 1000.0
    problems = _report_problems(args)
    solvers = tuple(args.solvers) if args.solvers else None
    caps = _caps(args.cap)
    if args.quick:
        quick = quick_config()
        return quick_config(
            problems=problems,
            solvers=solvers,
            n=args.n,
            seed=args.seed,
            tol=args.tol,
            timeout_s=timeout,
            caps={**quick.caps, **caps},
            closed_form_problems=problems,
            peers=args.peers,
            seeds=problems is None,
        )
    return RunConfig(
        problems=problems or tuple(p.stem for p in builtin_problems()),
        solvers=solvers or default_solvers(),
        n=DEFAULT_N if args.n is None else args.n,
        seed=args.seed,
        tol=args.tol,
        timeout_s=DEFAULT_TIMEOUT_S if timeout is None else timeout,
        caps=caps,
        peers=args.peers or (),
        # The textbook sections (seed 001's DOBOT, seed 003's two links) belong to the
        # built-ins' report; a report on chosen robots is about those robots.
        seeds=problems is None,
    )


def _check_caps(config: RunConfig, caps: Mapping[str, int]) -> None:
    """Each ``--cap`` names a solver of the run (or ``peer:NAME``): a typo is an error."""
    known = {*config.solvers, *(f"peer:{name}" for name in config.peers)}
    unknown = sorted(name for name in caps if name not in known)
    if unknown:
        raise OptikError(
            f"--cap names {unknown}, not solvers of this run (solvers: {sorted(known)})"
        )


def _cmd_report(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    _check_caps(config, _caps(args.cap))
    command = "optik " + " ".join(sys.argv[1:]) if sys.argv and sys.argv[0] else ""
    report = make_report(config, args.out, resume=args.resume, command=command)
    print(report.summary_text())
    if report.seed001 is not None:
        verdict = "holds" if report.seed001.finding_holds else "does not hold"
        print(f"\nseed 001: the chapter's finding (pinv needs fewer iterations) {verdict}")
    agree = sum(s.agree for s in report.closed_form)
    total = sum(s.cases for s in report.closed_form)
    if total:
        print(f"closed forms: {agree}/{total} step programs agree to {AGREEMENT_TOL:g}")
    print(f"\nreport written in {report.elapsed_s:.1f} s: {report.index.resolve()}")
    return EXIT_OK


def add_report_command(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``optik report`` to the ``optik`` command's subparsers.

    Args:
        subparsers: the object returned by ``ArgumentParser.add_subparsers``.

    Returns:
        The ``report`` subparser (its handler is set as ``func``).
    """
    p = command(
        subparsers,
        "report",
        "compare the IK solvers and write an HTML / Markdown report",
        "Run the solver comparison (closed-form agreement, full IK per robot on random "
        "in-limit targets, the seeds' examples), append every result to OUT/results.csv "
        "and write OUT/index.html, OUT/summary.md, OUT/summary.csv and OUT/summary.json. "
        "The robots are the built-in problems, the --problems given, or your own robot "
        "(--urdf with --base and --tip, or --dh); --peers runs peer IK libraries beside "
        "optik's solvers, verified the same way. A progress bar is drawn on a terminal.",
        "  optik report --quick\n"
        "  optik report --quick --problems puma560 ur5 --solvers auto dls\n"
        "  optik report --quick --urdf problems/panda.urdf --base panda_link0 \\\n"
        "      --tip panda_hand --out panda-report\n"
        "  optik report --quick --problems ur5 panda --peers rtb,ikpy,pink,eaik,pybullet\n",
    )
    p.add_argument(
        "--problems",
        nargs="+",
        metavar="PROBLEM",
        type=path_text,
        help="problem names or files (default: all built-ins)",
    )
    add_robot_arguments(p, positional=False)
    names = list(default_solvers())
    p.add_argument(
        "--solvers",
        nargs="+",
        metavar="SOLVER",
        choices=names,
        help="solvers (default: all of them); choices: " + ", ".join(names),
    )
    p.add_argument(
        "--peers",
        type=peer_list,
        default=None,
        metavar="NAMES",
        help="also run these peer IK libraries, comma-separated, on the same targets; "
        f"names: {','.join(peer_names())}; one not installed or unable to model the "
        "robot is listed with the reason",
    )
    p.add_argument(
        "-n",
        type=count_int,
        default=None,
        help=f"targets per robot (no unit; default {DEFAULT_N}; quick 5)",
    )
    add_seed_argument(p, "seed of the targets", show_default=True)
    p.add_argument(
        "--timeout-ms",
        type=timeout_ms,
        default=None,
        metavar="MS",
        help=f"time limit per IK call, ms, at most a day (default {DEFAULT_TIMEOUT_S * 1e3:g}; "
        "quick 100)",
    )
    add_tol_argument(p)
    p.add_argument(
        "--cap",
        action="append",
        metavar="SOLVER=N",
        help="run SOLVER on at most N targets per robot (no unit; repeatable)",
    )
    add_out_argument(p, "DIR", "output folder (default optik-report)", "optik-report")
    p.add_argument(
        "--quick",
        action="store_true",
        help="a small run (4 robots, 5 targets, fast solvers, 100 ms per call)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue OUT/results.csv, skipping rows present",
    )
    p.set_defaults(func=_cmd_report)
    return p
