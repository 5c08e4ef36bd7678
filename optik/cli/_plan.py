"""``optik plan``: limit-aware preprocessing of a Cartesian path."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from optik._files import check_folder, prepare_folder
from optik._progress import Progress
from optik.cli._common import (
    EXIT_NO_SOLUTION,
    EXIT_OK,
    add_orientation_arguments,
    add_out_argument,
    add_path_group,
    add_robot_arguments,
    add_seed_argument,
    add_tol_argument,
    command,
    finite_float,
    joint_values,
    non_negative_float,
    orientation_flag,
    path_from_args,
    pose_from_args,
    positive_float,
    problem_from_args,
)
from optik.cli._task import ORIENTED_MODES, add_task_arguments, task_keywords
from optik.errors import OptikError
from optik.paths import line
from optik.planning import PLAN_STATUSES, plan_path
from optik.problems import Problem
from optik.trajectory import rate_limits, require_toppra

DEFAULT_STEP = 0.01
"""Sampling step of ``--line`` (m)."""

#: Files of an earlier run that this one may not write (a stale trajectory would sit
#: beside the new plan): removed when this run does not write them.
_OPTIONAL_OUTPUTS = ("trajectory.csv", "trajectory.json")


def _plan_poses(problem: Problem, args: argparse.Namespace) -> tuple[np.ndarray, str]:
    orientation = orientation_flag(args)
    if orientation is not None and args.line is None:
        source = "--path" if args.path is not None else "--problem-path"
        raise OptikError(
            f"{orientation} sets the orientation of --line only; a {source} gives its own "
            "orientations (in rad) or none"
        )
    if args.line is not None:
        if args.mode == "position" and orientation is not None:
            raise OptikError(f"--mode position ignores the orientation: drop {orientation}")
        mode = "pose" if orientation is not None else "position"
        step = DEFAULT_STEP if args.step is None else args.step
        return line(
            pose_from_args(args.line[:3], args), pose_from_args(args.line[3:], args), step
        ), mode
    if args.step is not None:
        raise OptikError(
            "--step samples --line only: a --path or --problem-path keeps its waypoints"
        )
    stored = path_from_args(problem, args)
    if stored is not None:
        return stored
    raise OptikError("give --path FILE, --line X0 Y0 Z0 X1 Y1 Z1 (m) or --problem-path NAME")


def _task_mode(args: argparse.Namespace, path_mode: str) -> str:
    """--mode, or the path's own (``pose`` with orientations, else ``position``)."""
    mode = args.mode or path_mode
    if mode in ORIENTED_MODES and path_mode == "position":
        raise OptikError(
            f"--mode {mode} needs orientations: give --line with --rpy, --rpy-deg, "
            "--quat-wxyz or --quat-xyzw, or a path with orientations"
        )
    return str(mode)


def _cmd_plan(args: argparse.Namespace) -> int:
    check_folder(args.out)  # fail before the work; the folder is made when written to
    problem = problem_from_args(args)
    robot = problem.robot
    if args.trajectory:  # the extra and the limits are checked before the work, not after it
        require_toppra()
        _trajectory_limits(robot, args)
    elif (
        args.velocity_limits is not None
        or args.acceleration_limits is not None
        or args.dt is not None
    ):
        raise OptikError(
            "--velocity-limits, --acceleration-limits and --dt apply with --trajectory"
        )
    poses, mode = _plan_poses(problem, args)
    mode = _task_mode(args, mode)
    with Progress(len(poses)) as bar:
        plan = plan_path(
            robot,
            poses[:, :3, 3] if mode == "position" else poses,
            mode=mode,
            **task_keywords(args, mode),
            max_joint_step=args.max_joint_step,
            limit_margin=args.limit_margin,
            q_start=joint_values(robot, args.q0, "--q0"),
            seed=args.seed,
            tol=_path_tolerance(problem, args),
            progress=lambda done, total: bar.advance(note=f"plan {problem.name}"),
        )
    summary = plan.summary()
    print(
        f"{problem.name}: {summary['solved']}/{summary['waypoints']} waypoints solved, "
        f"{summary['flagged']} flagged, largest joint step {summary['largest_step']:.4g} "
        f"(bound {plan.max_joint_step:g}; rad or m)"
    )
    for status in PLAN_STATUSES:
        if summary[status]:
            print(f"  {status:<16}{summary[status]}")
    # The trajectory before any file: a limit it cannot meet leaves the folder untouched.
    trajectory = _trajectory(plan, robot, args) if args.trajectory else None
    out = prepare_folder(args.out)
    for name in _OPTIONAL_OUTPUTS if trajectory is None else ():
        (out / name).unlink(missing_ok=True)
    written = [plan.save(out / f"plan.{ext}") for ext in ("csv", "npz", "json")]
    if trajectory is not None:
        written += [
            trajectory.save(out / "trajectory.csv"),
            trajectory.save(out / "trajectory.json"),
        ]
    try:
        written.append(plan.plot(out / "plan.png", robot))
    except OptikError as exc:  # pragma: no cover - only without matplotlib
        print(f"  (no plot: {exc})")
    print("  wrote " + ", ".join(str(p) for p in written))
    # A plan with unsolved waypoints cannot be run whole: a script sees it in the code.
    return EXIT_OK if summary["solved"] == summary["waypoints"] else EXIT_NO_SOLUTION


def _path_tolerance(problem: Problem, args: argparse.Namespace) -> float:
    """``--tol``, else a ``--problem-path``'s own tolerance (m and rad), else 1e-6."""
    if args.tol is not None:
        return float(args.tol)
    if args.problem_path is not None:
        return float(problem.paths[args.problem_path].tolerance)
    return 1e-6


def _trajectory(plan: Any, robot: Any, args: argparse.Namespace) -> Any:
    """``--trajectory``: the time-optimal trajectory (written as OUT/trajectory.csv, .json)."""
    sampling = {} if args.dt is None else {"dt": args.dt}
    trajectory = plan.to_trajectory(*_trajectory_limits(robot, args), robot=robot, **sampling)
    print(
        f"  trajectory: {len(trajectory.segments)} segment(s), {trajectory.duration:.4g} s "
        "(each from rest to rest)"
    )
    for seg in trajectory.segments:
        print(
            f"    waypoints {seg.first}-{seg.last}: {seg.duration:.4g} s, tool within "
            f"{seg.position_deviation:.3g} m / {seg.orientation_deviation:.3g} rad of the path"
        )
    return trajectory


def _trajectory_limits(robot: Any, args: argparse.Namespace) -> tuple[Any, Any]:
    """The velocity and acceleration limits (dof,) of ``--trajectory``, or a clear error."""
    out = []
    for flag, given, known in (
        ("--velocity-limits", args.velocity_limits, robot.velocity_limits),
        ("--acceleration-limits", args.acceleration_limits, robot.acceleration_limits),
    ):
        values = None if given is None else (given[0] if len(given) == 1 else given)
        try:
            out.append(rate_limits(flag, values, known, robot.joint_names))
        except OptikError as exc:
            raise OptikError(str(exc).replace(f"give {flag}=", f"give {flag}")) from exc
    return out[0], out[1]


def add_plan_command(sub: Any) -> None:
    p = command(
        sub,
        "plan",
        "turn a Cartesian path into a joint path inside the limits",
        "Plan a continuous joint path inside the limits along a Cartesian path, print a "
        "summary and write OUT/plan.csv, plan.npz, plan.json and plan.png (with --trajectory, "
        "also trajectory.csv and trajectory.json). Path files are "
        "SI (m, rad) unless a TOML path file names its units. A progress bar is drawn on a "
        "terminal.",
        "  optik plan planar_2r --line 1.5 -0.5 0 1.5 0.5 0 --step 0.05\n"
        "  optik plan --urdf problems/panda.urdf --base panda_link0 --tip panda_hand \\\n"
        "      --line 0.4 -0.2 0.5 0.4 0.2 0.5 --rpy-deg 180 0 0 --out panda-plan \\\n"
        "      --trajectory --acceleration-limits 5\n",
    )
    add_robot_arguments(p)
    path_group = add_path_group(
        p,
        "path (one of --path, --line, --problem-path)",
        "path file (.csv, .npz, .toml; positions in m, rpy in rad; see docs/planning.md)",
        line=True,
    )
    p.add_argument(
        "--step",
        type=positive_float,
        default=None,
        help=f"sampling step of --line, m (default {DEFAULT_STEP:g})",
    )
    add_orientation_arguments(path_group, "constant orientation along --line (a pose path)")
    add_task_arguments(p, "pose for a path with orientations, else position")
    p.add_argument(
        "--max-joint-step",
        type=positive_float,
        default=0.1,
        help="largest continuous joint step, rad or m (default 0.1)",
    )
    p.add_argument(
        "--limit-margin",
        type=non_negative_float,
        default=0.0,
        help="keep joints this far inside their limits, rad or m (default 0)",
    )
    p.add_argument(
        "--q0",
        nargs="+",
        type=finite_float,
        metavar="Q",
        help="current configuration, one value per joint: rad (revolute) or m (prismatic)",
    )
    add_tol_argument(p, "IK tolerance of every waypoint", own="a --problem-path's own tolerance")
    add_seed_argument(p, "seed of the restarts")
    timing = p.add_argument_group("trajectory (time-optimal, TOPP-RA)")
    timing.add_argument(
        "--trajectory",
        action="store_true",
        help="also write OUT/trajectory.csv and trajectory.json (a ROS JointTrajectory per "
        "segment; times in s). Needs the trajectory extra: pip install 'optik[trajectory]'",
    )
    timing.add_argument(
        "--velocity-limits",
        nargs="+",
        type=positive_float,
        metavar="V",
        help="joint speed limits, one for all or one per joint: rad/s or m/s (default: the "
        "URDF's or problem file's)",
    )
    timing.add_argument(
        "--acceleration-limits",
        nargs="+",
        type=positive_float,
        metavar="A",
        help="joint acceleration limits, one for all or one per joint: rad/s^2 or m/s^2 "
        "(default: the problem file's)",
    )
    timing.add_argument(
        "--dt",
        type=positive_float,
        default=None,
        metavar="S",
        help="sampling step of trajectory.csv, s (default 0.01)",
    )
    add_out_argument(p, "DIR", "output folder (default ./optik-plan)", "optik-plan")
    p.set_defaults(func=_cmd_plan)
