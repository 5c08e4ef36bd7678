"""The ``optik`` command."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from optik.errors import OptikError
from optik.ik import solve_ik
from optik.paths import line, read_path
from optik.planning import PLAN_STATUSES, plan_path
from optik.problems import Problem, builtin_problems, load_problem
from optik.report import add_report_command
from optik.solvers import available_solvers
from optik.spatial import rpy_to_matrix, transform


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


def _robot_and_problem(name: str) -> Problem:
    return load_problem(name)


def _target_from_args(problem: Problem, args: argparse.Namespace) -> tuple[np.ndarray, str]:
    if args.target is not None:
        if args.target not in problem.targets:
            known = ", ".join(problem.targets) or "none"
            raise OptikError(
                f"problem {problem.name!r} has no target {args.target!r} (targets: {known})"
            )
        target = problem.targets[args.target]
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
            )
        )
        return 0 if result.success else 1
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
    return 0 if result.success else 1


def _cmd_plan(args: argparse.Namespace) -> int:
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
        if args.problem_path not in problem.paths:
            known = ", ".join(problem.paths) or "none"
            raise OptikError(
                f"problem {problem.name!r} has no path {args.problem_path!r} ({known})"
            )
        stored = problem.paths[args.problem_path]
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
    out = Path(args.out)
    written = [plan.save(out / f"plan.{ext}") for ext in ("csv", "npz", "json")]
    try:
        written.append(plan.plot(out / "plan.png", robot))
    except OptikError as exc:  # pragma: no cover - only without matplotlib
        print(f"  (no plot: {exc})")
    print("  wrote " + ", ".join(str(p) for p in written))
    return 0


def _add_solve_command(sub: Any) -> None:
    p = sub.add_parser("solve", help="solve one IK query on a problem's robot")
    p.add_argument("problem", help="problem file or built-in name")
    p.add_argument("--target", help="a named target of the problem")
    p.add_argument("--position", nargs=3, type=float, metavar=("X", "Y", "Z"), help="m")
    p.add_argument("--rpy-deg", nargs=3, type=float, metavar=("R", "P", "Y"), help="deg")
    p.add_argument("--mode", choices=["pose", "position"])
    p.add_argument("--solver", default="auto", choices=["auto", *available_solvers()])
    p.add_argument("--tol", type=float, default=1e-6, help="m and rad (default 1e-6)")
    p.add_argument("--q0", nargs="+", type=float, help="initial guess, rad / m")
    p.add_argument("--timeout-ms", type=float)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=_cmd_solve)


def _add_plan_command(sub: Any) -> None:
    p = sub.add_parser("plan", help="turn a Cartesian path into a joint path inside the limits")
    p.add_argument("problem", help="problem file or built-in name")
    source = p.add_mutually_exclusive_group()
    source.add_argument("--path", help="path file (.csv, .npz, .toml; see docs/planning.md)")
    source.add_argument(
        "--line", nargs=6, type=float, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"), help="m"
    )
    source.add_argument("--problem-path", help="a named path of the problem file")
    p.add_argument("--step", type=float, default=0.01, help="sampling step of --line (m)")
    p.add_argument("--rpy-deg", nargs=3, type=float, help="constant orientation of --line")
    p.add_argument("--max-joint-step", type=float, default=0.1, help="rad or m (default 0.1)")
    p.add_argument("--limit-margin", type=float, default=0.0, help="rad or m (default 0)")
    p.add_argument("--q0", nargs="+", type=float, help="current configuration, rad / m")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="optik-plan", help="output folder (default ./optik-plan)")
    p.set_defaults(func=_cmd_plan)


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
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except OptikError as exc:
        print(f"optik: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
