"""``optik solve``: one IK query from the command line."""

from __future__ import annotations

import argparse
import json
from typing import Any

from optik.cli._common import (
    EXIT_NO_SOLUTION,
    EXIT_OK,
    add_orientation_arguments,
    add_robot_arguments,
    add_seed_argument,
    add_tol_argument,
    command,
    finite_float,
    joint_values,
    json_value,
    length_float,
    orientation_flag,
    positive_float,
    problem_from_args,
    target_from_args,
    target_tolerance,
    value_text,
)
from optik.cli._task import ORIENTED_MODES, add_task_arguments, task_keywords, task_mode
from optik.errors import OptikError
from optik.ik import solve_ik
from optik.problems import Problem
from optik.solvers import available_solvers


def _solve_json(problem: Problem, result: Any, mode: str) -> str:
    robot = problem.robot
    data = {
        "problem": problem.name,
        "success": result.success,
        "status": result.status,
        "mode": mode,
        # No answer for an unsolved target: q is null, the errors say how far it got.
        "q": result.q.tolist() if result.success else None,
        "q_units": ["m" if j.kind == "prismatic" else "rad" for j in robot.joints],
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
    return json.dumps(json_value(data), allow_nan=False)


def _check_oriented(problem: Problem, args: argparse.Namespace, mode: str) -> None:
    """A mode that constrains the orientation needs a target that has one."""
    if mode not in ORIENTED_MODES:
        return
    if args.target is not None:
        if problem.targets[args.target].mode == "position":
            raise OptikError(
                f"--mode {mode} needs an orientation; target {args.target!r} is a point"
            )
    elif orientation_flag(args) is None:
        raise OptikError(
            f"--mode {mode} needs a target orientation: give --rpy, --rpy-deg, --quat-wxyz "
            "or --quat-xyzw"
        )


def _cmd_solve(args: argparse.Namespace) -> int:
    problem = problem_from_args(args)
    robot = problem.robot
    target, mode = target_from_args(problem, args)
    _check_oriented(problem, args, mode)
    result = solve_ik(
        robot,
        target[:3, 3] if mode == "position" else target,
        mode=mode,
        solver=args.solver,
        q0=joint_values(robot, args.q0, "--q0"),
        tol=target_tolerance(problem, args),
        timeout_s=None if args.timeout_ms is None else args.timeout_ms / 1000.0,
        seed=args.seed,
        posture=joint_values(robot, args.posture, "--posture", within_limits=False),
        **task_keywords(args, mode),
    )
    if args.json:
        print(_solve_json(problem, result, task_mode(args, mode)))
        return EXIT_OK if result.success else EXIT_NO_SOLUTION
    solver_time = f"{result.solver}, solver time {result.time_s * 1e3:.3f} ms"
    # In axis mode the orientation error is the angle between the tool axis and the target's.
    angle = "tool-axis angle error" if task_mode(args, mode) == "axis" else "orientation error"
    errors = (
        f"position error {result.position_error:.3e} m, {angle} "
        f"{result.orientation_error:.3e} rad, limit violation {result.limit_violation:.3e} "
        "(rad or m)"
    )
    if not result.success:
        print(f"{problem.name}: no solution: {result.status} ({solver_time})")
        print(f"  best attempt: {errors}")
        if result.message:
            print(f"  {result.message}")
        return EXIT_NO_SOLUTION
    print(f"{problem.name}: {result.status} ({solver_time})")
    for joint, value in zip(robot.joints, result.q, strict=True):
        print(f"  {joint.name:<24}{value_text(float(value), joint.kind)}")
    print(f"  {errors}")
    if result.message:
        print(f"  {result.message}")
    return EXIT_OK


def add_solve_command(sub: Any) -> None:
    p = command(
        sub,
        "solve",
        "solve one IK query on a robot",
        "Solve one IK query and print the joint values (rad, with degrees alongside; m for "
        "prismatic joints), the errors and the solver's own time. An unsolved target prints "
        "its status and the errors of the best attempt, no joint values, and exits 1.",
        "  optik solve dobot_magician --target part1\n"
        "  optik solve planar_2r --position 1 1 0\n"
        "  optik solve panda --position 0.4 0.1 0.5 --rpy-deg 180 0 0 --mode axis\n"
        "  optik solve --urdf problems/panda.urdf --base panda_link0 --tip panda_hand \\\n"
        "      --position 0.4 0.1 0.5 --rpy-deg 180 0 0\n",
    )
    add_robot_arguments(p)
    target = p.add_argument_group("target")
    target.add_argument("--target", metavar="NAME", help="a named target of the problem")
    target.add_argument(
        "--position",
        nargs=3,
        type=length_float,
        metavar=("X", "Y", "Z"),
        help="target position of the tool, m",
    )
    add_orientation_arguments(target, "target orientation (a full pose)")
    task = add_task_arguments(p, "pose with an orientation, else position")
    task.add_argument(
        "--posture",
        nargs="+",
        type=finite_float,
        metavar="Q",
        help="among the answers, one nearest this configuration (a local optimum), one "
        "value per joint: rad (revolute) or m (prismatic)",
    )
    p.add_argument(
        "--solver",
        default="auto",
        choices=["auto", *available_solvers()],
        help="solver name (default auto)",
    )
    add_tol_argument(p, of_target=True)
    p.add_argument(
        "--q0",
        nargs="+",
        type=finite_float,
        metavar="Q",
        help="initial guess, one value per joint: rad (revolute) or m (prismatic)",
    )
    p.add_argument(
        "--timeout-ms", type=positive_float, metavar="MS", help="time budget of the solver, ms"
    )
    add_seed_argument(p, "seed of the restarts")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.set_defaults(func=_cmd_solve)
