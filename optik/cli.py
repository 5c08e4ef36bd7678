"""The ``optik`` command."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence

from optik.errors import OptikError
from optik.problems import Problem, builtin_problems, load_problem


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
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``optik`` command."""
    parser = argparse.ArgumentParser(
        prog="optik", description="Optimization-based inverse kinematics for robot arms."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("problems", help="list the built-in (or given) problems")
    p.add_argument("problems", nargs="*", help="problem files or built-in names")
    p.set_defaults(func=_cmd_problems)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``optik`` console script."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except OptikError as exc:
        print(f"optik: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
