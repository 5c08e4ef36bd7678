"""The ``optik`` command: every argument parser of optik lives here.

Exit codes: 0 success; 1 a well-formed query without an answer (``optik solve`` found no
solution); 2 bad input (argparse's usage errors, and every :class:`~optik.errors.OptikError`
raised by the input, printed as one ``optik: error: ...`` line); 3 an internal error (a
bug: the traceback is printed).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import traceback
from collections.abc import Sequence
from typing import Any

import numpy as np

from optik._files import prepare_folder
from optik.compare import AGREEMENT_TOL, RunConfig
from optik.errors import OptikError
from optik.ik import solve_ik
from optik.paths import line, read_path
from optik.planning import PLAN_STATUSES, plan_path
from optik.problems import Problem, builtin_problems, load_problem
from optik.report import (
    DEFAULT_N,
    DEFAULT_TIMEOUT_S,
    default_solvers,
    make_report,
    quick_config,
)
from optik.solvers import available_solvers
from optik.spatial import rpy_to_matrix, transform

__all__ = ["EXIT_BAD_INPUT", "EXIT_INTERNAL", "EXIT_NO_SOLUTION", "EXIT_OK", "build_parser", "main"]

#: Exit codes of the ``optik`` command.
EXIT_OK = 0
EXIT_NO_SOLUTION = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3


# ---------------------------------------------------------------------------- numbers
def _number(text: str, kind: type, check: Any, what: str) -> Any:
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if not (math.isfinite(value) and check(value)):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value


def finite_float(text: str) -> float:
    """An argparse type: a finite real number."""
    return float(_number(text, float, lambda v: True, "a finite number"))


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    return float(_number(text, float, lambda v: v > 0, "a finite number > 0"))


def non_negative_float(text: str) -> float:
    """An argparse type: a finite number >= 0."""
    return float(_number(text, float, lambda v: v >= 0, "a finite number >= 0"))


def non_negative_int(text: str) -> int:
    """An argparse type: an integer >= 0."""
    return int(_number(text, int, lambda v: v >= 0, "an integer >= 0"))


def _json_value(value: Any) -> Any:
    """``value`` with every non-finite float as ``None`` (JSON has no inf or NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _json_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_value(v) for v in value]
    return value


def _limit_text(lower: float, upper: float, kind: str) -> str:
    if not math.isfinite(lower):
        return "continuous"
    if kind == "prismatic":
        return f"{lower:g}..{upper:g} m"
    return f"{math.degrees(lower):g}..{math.degrees(upper):g}°"


def problems_table(problems: Sequence[Problem]) -> str:
    """A plain-text table of robots: dof, joint types, limits and FK at mid-limits."""
    lines = []
    header = (
        f"{'problem':<22}{'dof':>4}  {'joints':<8}{'analytic':<17}{'tool at mid-limits (m)':<30}"
    )
    lines.append(header)
    lines.append("-" * len(header))
    for problem in problems:
        robot = problem.robot
        kinds = "".join("P" if j.kind == "prismatic" else "R" for j in robot.joints)
        p = robot.fk(robot.mid_limits)[:3, 3]
        position = "(" + ", ".join(f"{v:+.4f}" for v in p) + ")"
        lines.append(
            f"{problem.name:<22}{robot.dof:>4}  {kinds:<8}{robot.analytic or '-':<17}{position:<30}"
        )
        limits = ", ".join(
            f"{j.name} {_limit_text(j.lower, j.upper, j.kind)}" for j in robot.joints
        )
        lines.append(f"{'':<26}limits: {limits}")
    return "\n".join(lines)


def _cmd_problems(args: argparse.Namespace) -> int:
    paths = args.problems or builtin_problems()
    print(problems_table([load_problem(p) for p in paths]))
    return EXIT_OK


def _robot_and_problem(name: str) -> Problem:
    return load_problem(name)


def _named(problem: Problem, table: dict[str, Any], kind: str, name: str) -> Any:
    """``table[name]``, or an error naming the problem and listing the known names."""
    if name not in table:
        known = ", ".join(table) or "none"
        raise OptikError(f"problem {problem.name!r} has no {kind} {name!r} ({kind}s: {known})")
    return table[name]


def _target_from_args(problem: Problem, args: argparse.Namespace) -> tuple[np.ndarray, str]:
    if args.target is not None:
        target = _named(problem, problem.targets, "target", args.target)
        return target.pose, args.mode or target.mode
    if args.position is None:
        raise OptikError("give --target NAME or --position X Y Z (m)")
    rotation = None if args.rpy_deg is None else rpy_to_matrix(*np.radians(args.rpy_deg))
    mode = args.mode or ("pose" if rotation is not None else "position")
    return transform(rotation, args.position), mode


def _cmd_solve(args: argparse.Namespace) -> int:
    problem = _robot_and_problem(args.problem)
    robot = problem.robot
    pose, mode = _target_from_args(problem, args)
    result = solve_ik(
        robot,
        pose if mode == "pose" else pose[:3, 3],
        mode=mode,
        solver=args.solver,
        q0=args.q0,
        tol=args.tol,
        timeout_s=None if args.timeout_ms is None else args.timeout_ms / 1000.0,
        seed=args.seed,
    )
    if args.json:
        print(
            json.dumps(
                _json_value(
                    {
                        "problem": problem.name,
                        "success": result.success,
                        "status": result.status,
                        "q": result.q.tolist(),
                        "joint_names": list(robot.joint_names),
                        "position_error": result.position_error,
                        "orientation_error": result.orientation_error,
                        "limit_violation": result.limit_violation,
                        "iterations": result.iterations,
                        "restarts": result.restarts,
                        "time_s": result.time_s,
                        "solver": result.solver,
                        "message": result.message,
                    }
                ),
                allow_nan=False,
            )
        )
        return EXIT_OK if result.success else EXIT_NO_SOLUTION
    print(f"{problem.name}: {result.status} ({result.solver}, {result.time_s * 1e3:.3f} ms)")
    for joint, value in zip(robot.joints, result.q, strict=True):
        shown = f"{value:.6f} m" if joint.kind == "prismatic" else f"{math.degrees(value):.4f}°"
        print(f"  {joint.name:<24}{shown}")
    print(
        f"  position error {result.position_error:.3e} m, orientation error "
        f"{result.orientation_error:.3e} rad, limit violation {result.limit_violation:.3e}"
    )
    if result.message:
        print(f"  {result.message}")
    return EXIT_OK if result.success else EXIT_NO_SOLUTION


def _cmd_plan(args: argparse.Namespace) -> int:
    out = prepare_folder(args.out)  # fail before the work, not after it
    problem = _robot_and_problem(args.problem)
    robot = problem.robot
    if args.path is not None:
        poses, mode = read_path(args.path)
    elif args.line is not None:
        rotation = None if args.rpy_deg is None else rpy_to_matrix(*np.radians(args.rpy_deg))
        mode = "pose" if rotation is not None else "position"
        start = transform(rotation, args.line[:3])
        end = transform(rotation, args.line[3:])
        poses = line(start, end, args.step)
    elif args.problem_path is not None:
        stored = _named(problem, problem.paths, "path", args.problem_path)
        poses, mode = stored.poses, stored.mode
    else:
        raise OptikError("give --path FILE, --line X0 Y0 Z0 X1 Y1 Z1 or --problem-path NAME")
    plan = plan_path(
        robot,
        poses if mode == "pose" else poses[:, :3, 3],
        mode=mode,
        max_joint_step=args.max_joint_step,
        limit_margin=args.limit_margin,
        q_start=args.q0,
        seed=args.seed,
    )
    summary = plan.summary()
    print(
        f"{problem.name}: {summary['solved']}/{summary['waypoints']} waypoints solved, "
        f"{summary['flagged']} flagged, largest joint step {summary['largest_step']:.4g} "
        f"(bound {plan.max_joint_step:g})"
    )
    for status in PLAN_STATUSES:
        if summary[status]:
            print(f"  {status:<16}{summary[status]}")
    written = [plan.save(out / f"plan.{ext}") for ext in ("csv", "npz", "json")]
    try:
        written.append(plan.plot(out / "plan.png", robot))
    except OptikError as exc:  # pragma: no cover - only without matplotlib
        print(f"  (no plot: {exc})")
    print("  wrote " + ", ".join(str(p) for p in written))
    return EXIT_OK


def _add_solve_command(sub: Any) -> None:
    p = sub.add_parser("solve", help="solve one IK query on a problem's robot")
    p.add_argument("problem", help="problem file or built-in name")
    p.add_argument("--target", help="a named target of the problem")
    p.add_argument("--position", nargs=3, type=finite_float, metavar=("X", "Y", "Z"), help="m")
    p.add_argument("--rpy-deg", nargs=3, type=finite_float, metavar=("R", "P", "Y"), help="deg")
    p.add_argument("--mode", choices=["pose", "position"])
    p.add_argument("--solver", default="auto", choices=["auto", *available_solvers()])
    p.add_argument("--tol", type=positive_float, default=1e-6, help="m and rad (default 1e-6)")
    p.add_argument("--q0", nargs="+", type=finite_float, help="initial guess, rad / m")
    p.add_argument("--timeout-ms", type=positive_float)
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=_cmd_solve)


def _add_plan_command(sub: Any) -> None:
    p = sub.add_parser("plan", help="turn a Cartesian path into a joint path inside the limits")
    p.add_argument("problem", help="problem file or built-in name")
    source = p.add_mutually_exclusive_group()
    source.add_argument("--path", help="path file (.csv, .npz, .toml; see docs/planning.md)")
    source.add_argument(
        "--line",
        nargs=6,
        type=finite_float,
        metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
        help="m",
    )
    source.add_argument("--problem-path", help="a named path of the problem file")
    p.add_argument("--step", type=positive_float, default=0.01, help="sampling step of --line (m)")
    p.add_argument("--rpy-deg", nargs=3, type=finite_float, help="constant orientation of --line")
    p.add_argument(
        "--max-joint-step", type=positive_float, default=0.1, help="rad or m (default 0.1)"
    )
    p.add_argument(
        "--limit-margin", type=non_negative_float, default=0.0, help="rad or m (default 0)"
    )
    p.add_argument("--q0", nargs="+", type=finite_float, help="current configuration, rad / m")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--out", default="optik-plan", help="output folder (default ./optik-plan)")
    p.set_defaults(func=_cmd_plan)


# ---------------------------------------------------------------------------- report
def _caps(values: Sequence[str] | None) -> dict[str, int]:
    caps: dict[str, int] = {}
    for value in values or ():
        name, sep, count = value.rpartition("=")
        if not sep or not name or not count.isdigit():
            raise OptikError(f"--cap expects SOLVER=N, got {value!r}")
        caps[name] = int(count)
    return caps


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """The :class:`~optik.compare.RunConfig` of ``optik report``'s arguments."""
    timeout = None if args.timeout_ms is None else args.timeout_ms / 1000.0
    problems = tuple(args.problems) if args.problems else None
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
        )
    return RunConfig(
        problems=problems or tuple(p.stem for p in builtin_problems()),
        solvers=solvers or default_solvers(),
        n=DEFAULT_N if args.n is None else args.n,
        seed=args.seed,
        tol=args.tol,
        timeout_s=DEFAULT_TIMEOUT_S if timeout is None else timeout,
        caps=caps,
    )


def _cmd_report(args: argparse.Namespace) -> int:
    config = config_from_args(args)
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
    p = subparsers.add_parser(
        "report",
        help="compare the IK solvers and write an HTML / Markdown report",
        description=(
            "Run the solver comparison (closed-form agreement, full IK per robot, the seeds' "
            "examples), append every result to OUT/results.csv and write OUT/index.html, "
            "OUT/summary.md, OUT/summary.csv and OUT/summary.json."
        ),
    )
    p.add_argument(
        "--problems", nargs="+", metavar="PROBLEM", help="problem names or files (default: all)"
    )
    names = list(default_solvers())
    p.add_argument(
        "--solvers",
        nargs="+",
        metavar="SOLVER",
        choices=names,
        help="solvers (default: all of them); choices: " + ", ".join(names),
    )
    p.add_argument(
        "-n",
        type=non_negative_int,
        default=None,
        help=f"targets per robot (default {DEFAULT_N}; quick 5)",
    )
    p.add_argument(
        "--seed", type=non_negative_int, default=0, help="seed of the targets (default 0)"
    )
    p.add_argument(
        "--timeout-ms",
        type=positive_float,
        default=None,
        help=f"time limit per IK call, ms (default {DEFAULT_TIMEOUT_S * 1e3:g}; quick 100)",
    )
    p.add_argument("--tol", type=positive_float, default=1e-6, help="m and rad (default 1e-6)")
    p.add_argument(
        "--cap",
        action="append",
        metavar="SOLVER=N",
        help="run SOLVER on at most N targets per robot (repeatable)",
    )
    p.add_argument("--out", default="optik-report", help="output folder (default optik-report)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="a small run (4 robots, 5 targets, fast solvers, 100 ms): under a minute",
    )
    p.add_argument(
        "--resume", action="store_true", help="continue OUT/results.csv, skipping rows present"
    )
    p.set_defaults(func=_cmd_report)
    return p


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``optik`` command."""
    parser = argparse.ArgumentParser(
        prog="optik", description="Optimization-based inverse kinematics for robot arms."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("problems", help="list the built-in (or given) problems")
    p.add_argument("problems", nargs="*", help="problem files or built-in names")
    p.set_defaults(func=_cmd_problems)
    _add_solve_command(sub)
    _add_plan_command(sub)
    add_report_command(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``optik`` console script."""
    args = build_parser().parse_args(argv)  # a usage error exits with 2
    try:
        return int(args.func(args))
    except OptikError as exc:  # bad input: one line, no traceback
        message = " ".join(str(exc).split())
        print(f"optik: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("optik: interrupted", file=sys.stderr)
        return 130
    except Exception:  # a bug, not the user's input: keep the traceback for the report
        traceback.print_exc()
        print("optik: internal error (a bug; please report it)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
