"""The ``optik`` command: every argument parser of optik lives here.

Exit codes: 0 success; 1 a well-formed query without an answer (``optik solve`` found no
solution); 2 bad input (a usage error, and every :class:`~optik.errors.OptikError` raised
by the input, printed as one ``optik: error: ...`` line); 3 an internal error (a bug: the
traceback is printed).

Units: SI everywhere, in files, arrays and options (m, rad, s); an option in another
unit names it (``--rpy-deg``, ``--timeout-ms``), and every option's help states its unit
or "no unit". Output prints every value with its unit (revolute joints in rad, with
degrees alongside).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import textwrap
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from optik import __version__
from optik._checks import MAX_LENGTH_M
from optik._files import prepare_folder
from optik._progress import Progress
from optik.compare import AGREEMENT_TOL, RunConfig
from optik.errors import OptikError
from optik.ik import solve_ik
from optik.model import Robot
from optik.paths import line, read_path
from optik.planning import PLAN_STATUSES, plan_path
from optik.poses import pose
from optik.problems import PROBLEMS_DIR, Problem, builtin_problems, load_problem, load_robot
from optik.report import (
    DEFAULT_N,
    DEFAULT_TIMEOUT_S,
    default_solvers,
    make_report,
    quick_config,
)
from optik.robot_text import read_urdf_tree, robot_text
from optik.solvers import available_solvers

__all__ = ["EXIT_BAD_INPUT", "EXIT_INTERNAL", "EXIT_NO_SOLUTION", "EXIT_OK", "build_parser", "main"]

#: Exit codes of the ``optik`` command.
EXIT_OK = 0
EXIT_NO_SOLUTION = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3

URDF_SUFFIXES = (".urdf", ".xml")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one ``optik: error: ...`` line (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"optik: error: {message} (see '{self.prog} --help')\n")


# ---------------------------------------------------------------------------- numbers
def _number(text: str, kind: type, check: Any, what: str) -> Any:
    try:
        value = kind(text)
    except (ValueError, OverflowError):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r:.40}") from None
    # An int is always finite (and math.isfinite of a huge int would overflow).
    if not ((kind is int or math.isfinite(value)) and check(value)):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r:.40}")
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


#: Largest ``--seed`` (the planner's bound, so that one seed works for every command).
MAX_SEED = 2**32 - 1
#: Largest ``-n`` of ``optik report`` (targets per robot).
MAX_TARGETS = 1_000_000


def length_float(text: str) -> float:
    """An argparse type: a finite length within +-MAX_LENGTH_M (m)."""
    return float(
        _number(
            text,
            float,
            lambda v: abs(v) <= MAX_LENGTH_M,
            f"a length in m within +-{MAX_LENGTH_M:g}",
        )
    )


def path_text(text: str) -> str:
    """An argparse type: a file or folder path the system can look up (it may not exist).

    A path with a NUL byte, a name too long for the file system or a symlink loop is a
    usage error here, rather than an ``OSError`` deep in a reader.
    """
    if not text:
        raise argparse.ArgumentTypeError("expected a path or name, got ''")
    try:
        os.stat(text)
    except (FileNotFoundError, NotADirectoryError):
        pass  # a missing file is reported by the command, with what it expected
    except ValueError as exc:  # an embedded NUL byte
        raise argparse.ArgumentTypeError(f"not a usable path {text!r:.80}: {exc}") from None
    except OSError as exc:
        raise argparse.ArgumentTypeError(
            f"not a usable path {text!r:.80}: {exc.strerror or exc}"
        ) from None
    return text


def seed_int(text: str) -> int:
    """An argparse type: a seed, an integer in [0, :data:`MAX_SEED`]."""
    return int(_number(text, int, lambda v: 0 <= v <= MAX_SEED, f"an integer in [0, {MAX_SEED}]"))


def count_int(text: str) -> int:
    """An argparse type: a number of targets, an integer in [0, :data:`MAX_TARGETS`]."""
    return int(
        _number(text, int, lambda v: 0 <= v <= MAX_TARGETS, f"an integer in [0, {MAX_TARGETS}]")
    )


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


def _value_text(value: float, kind: str) -> str:
    """A joint value in SI with its unit (revolute: rad, with degrees alongside)."""
    if kind == "prismatic":
        return f"{value:.6f} m"
    return f"{value:+.6f} rad  ({math.degrees(value):+.4f}°)"


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


# ---------------------------------------------------------------------------- robots
def _builtin_names() -> str:
    return ", ".join(p.stem for p in builtin_problems())


def _exists(path: Path) -> bool:
    """Whether ``path`` exists; a name the system cannot look up (too long) does not."""
    try:
        return path.exists()
    except (OSError, ValueError):
        return False


def named_problem(name: str) -> Problem:
    """A built-in problem by name, or a problem file; an unknown name lists the built-ins.

    Raises:
        OptikError: neither a file nor a built-in name (the message lists the built-ins),
            or any :class:`~optik.errors.ProblemFileError` of the file.
    """
    file = Path(name)
    if _exists(file) or (file.suffix == "" and _exists(PROBLEMS_DIR / f"{name}.toml")):
        return load_problem(name)
    if file.suffix or len(file.parts) > 1:  # a path, not a name
        raise OptikError(f"{name}: file not found (built-in problems: {_builtin_names()})")
    raise OptikError(
        f"no problem file or built-in problem named {name!r:.200} "
        f"(built-in problems: {_builtin_names()}; or give --urdf FILE or --dh FILE)"
    )


def _chains_hint(urdf: Path) -> str:
    tree = read_urdf_tree(urdf)
    chains = "; ".join(c.text() for c in tree.chains) or "none"
    return f"chains of {urdf} (root -> leaf): {chains}"


def urdf_problem(urdf: str, base: str | None, tip: str | None) -> Problem:
    """The chain ``base -> tip`` of a URDF file as a problem without targets.

    Raises:
        OptikError: a missing ``base`` or ``tip`` (the message lists the file's chains), or
            any :class:`~optik.errors.URDFError` of the file.
    """
    path = Path(urdf)
    if base is None or tip is None:
        missing = " and ".join(f for f, v in (("--base", base), ("--tip", tip)) if v is None)
        raise OptikError(f"--urdf needs {missing} LINK; {_chains_hint(path)}")
    robot = Robot.from_urdf(path, base, tip)  # a Path: never read as XML text
    return Problem(name=robot.name, robot=robot, source=f"URDF {path}: {base} -> {tip}", path=path)


def dh_problem(file: str) -> Problem:
    """The robot of a DH table (a ``[robot]`` table in the ``dh`` or ``mdh`` convention).

    Raises:
        OptikError: not a file, a ``urdf``-convention robot, or any
            :class:`~optik.errors.ProblemFileError` of the file.
    """
    if not Path(file).is_file():
        raise OptikError(f"--dh {file!r:.200}: file not found (a DH table is a .toml file)")
    problem = load_robot(file)
    if problem.robot.convention not in ("dh", "mdh"):
        raise OptikError(
            f"--dh {file}: convention {problem.robot.convention!r} is not a DH table "
            "(give a urdf-convention file as PROBLEM, or the URDF itself with --urdf)"
        )
    return problem


def _robot_choice(args: argparse.Namespace, positional: str = "PROBLEM") -> list[str]:
    named = args.problems if positional == "--problems" else args.problem
    given = [
        flag
        for flag, value in (
            (positional, named),
            ("--urdf", args.urdf),
            ("--dh", args.dh),
        )
        if value
    ]
    if (args.base is not None or args.tip is not None) and args.urdf is None:
        raise OptikError("--base and --tip name the links of a --urdf chain; give --urdf FILE")
    if len(given) > 1:
        raise OptikError(f"give one robot, not {' and '.join(given)}")
    return given


def problem_from_args(args: argparse.Namespace) -> Problem:
    """The robot of a command: exactly one of PROBLEM, ``--urdf`` or ``--dh``.

    Raises:
        OptikError: none or more than one given, ``--base``/``--tip`` without ``--urdf``,
            or an error of the file.
    """
    if not _robot_choice(args):
        raise OptikError(
            "give a robot: a PROBLEM (a built-in name or a problem file), "
            f"--urdf FILE --base LINK --tip LINK, or --dh FILE (built-in problems: "
            f"{_builtin_names()})"
        )
    if args.urdf is not None:
        return urdf_problem(args.urdf, args.base, args.tip)
    if args.dh is not None:
        return dh_problem(args.dh)
    return named_problem(args.problem)


def _add_robot_arguments(p: argparse.ArgumentParser, *, positional: bool = True) -> None:
    if positional:
        p.add_argument(
            "problem",
            nargs="?",
            metavar="PROBLEM",
            type=path_text,
            help="a built-in problem name or a problem file (.toml); no unit (the file "
            "names its units). Or give --urdf or --dh instead",
        )
    group = p.add_argument_group("your own robot (instead of a problem)")
    group.add_argument(
        "--urdf",
        metavar="FILE",
        type=path_text,
        help="a URDF file (its lengths in m, angles in rad), with --base and --tip",
    )
    group.add_argument(
        "--base", metavar="LINK", help="base link of the --urdf chain (a link name; no unit)"
    )
    group.add_argument(
        "--tip", metavar="LINK", help="tip link of the --urdf chain (a link name; no unit)"
    )
    group.add_argument(
        "--dh",
        metavar="FILE",
        type=path_text,
        help="a DH table: a .toml [robot] table with [[robot.joints]] rows (convention dh "
        "or mdh); units as the file names them (length_unit, angle_unit; default m, rad)",
    )


# ---------------------------------------------------------------------------- poses
def _add_orientation_arguments(p: Any, what: str) -> None:
    """One of --rpy, --rpy-deg, --quat-wxyz, --quat-xyzw on ``p`` (a parser or a group)."""
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--rpy",
        nargs=3,
        type=finite_float,
        metavar=("R", "P", "Y"),
        help=f"{what}: roll, pitch, yaw in rad, R = Rz(Y) Ry(P) Rx(R) (URDF convention)",
    )
    group.add_argument(
        "--rpy-deg",
        nargs=3,
        type=finite_float,
        metavar=("R", "P", "Y"),
        help=f"{what}: roll, pitch, yaw in deg, R = Rz(Y) Ry(P) Rx(R) (URDF convention)",
    )
    group.add_argument(
        "--quat-wxyz",
        nargs=4,
        type=finite_float,
        metavar=("W", "X", "Y", "Z"),
        help=f"{what}: a unit quaternion, scalar first (no unit)",
    )
    group.add_argument(
        "--quat-xyzw",
        nargs=4,
        type=finite_float,
        metavar=("X", "Y", "Z", "W"),
        help=f"{what}: a unit quaternion, scalar last, as scipy and ROS (no unit)",
    )


def _orientation_flag(args: argparse.Namespace) -> str | None:
    for flag in ("rpy", "rpy_deg", "quat_wxyz", "quat_xyzw"):
        if getattr(args, flag) is not None:
            return "--" + flag.replace("_", "-")
    return None


def _pose_from_args(position: Sequence[float], args: argparse.Namespace) -> np.ndarray:
    """The 4x4 pose of ``position`` (m) and the orientation options (identity if none)."""
    if args.rpy is not None:
        return pose(position, rpy=args.rpy, rpy_convention="urdf")
    if args.rpy_deg is not None:
        return pose(position, rpy=args.rpy_deg, rpy_convention="urdf", degrees=True)
    return pose(position, quat_wxyz=args.quat_wxyz, quat_xyzw=args.quat_xyzw)


def _named(problem: Problem, table: dict[str, Any], kind: str, name: str) -> Any:
    """``table[name]``, or an error naming the problem and listing the known names."""
    if name not in table:
        known = ", ".join(table) or "none"
        raise OptikError(f"problem {problem.name!r} has no {kind} {name!r} ({kind}s: {known})")
    return table[name]


def _target_from_args(problem: Problem, args: argparse.Namespace) -> tuple[np.ndarray, str]:
    orientation = _orientation_flag(args)
    if args.target is not None:
        if args.position is not None or orientation is not None:
            given = "--position" if args.position is not None else orientation
            raise OptikError(f"--target NAME takes its pose from the problem; drop {given}")
        target = _named(problem, problem.targets, "target", args.target)
        return target.pose, args.mode or target.mode
    if args.position is None:
        raise OptikError(
            "give --target NAME or --position X Y Z (m), with an orientation "
            "(--rpy, --rpy-deg, --quat-wxyz or --quat-xyzw) for a full pose"
        )
    mode = args.mode or ("pose" if orientation is not None else "position")
    if mode == "position" and orientation is not None:
        raise OptikError(f"--mode position ignores the orientation: drop {orientation}")
    return _pose_from_args(args.position, args), mode


# ---------------------------------------------------------------------------- commands
def _cmd_problems(args: argparse.Namespace) -> int:
    paths = args.problems or builtin_problems()
    print(problems_table([named_problem(str(p)) for p in paths]))
    return EXIT_OK


def _cmd_robot(args: argparse.Namespace) -> int:
    file = Path(args.file)
    is_urdf = file.suffix.lower() in URDF_SUFFIXES
    if (args.base is not None or args.tip is not None) and not is_urdf:
        raise OptikError(f"--base and --tip name links of a URDF (.urdf, .xml), not of {file}")
    if not is_urdf:
        return _describe_robot_file(args.file)
    return _describe_urdf(file, args.base, args.tip)


def _describe_robot_file(name: str) -> int:
    problem = named_problem(name) if not Path(name).is_file() else load_robot(name)
    robot = problem.robot
    details = robot_text(robot)  # fails (a declared family that does not fit) first
    print(f"robot {robot.name} ({robot.convention} convention, {problem.path})")
    if problem.source:
        print(f"source: {problem.source}")
    if robot.convention == "urdf":
        print("links: see the URDF file the problem names (optik robot FILE.urdf)")
    else:
        print(f"links: a {robot.convention.upper()} table names no links (frames 0..{robot.dof})")
    print(f"chain: base -> tool  ({robot.dof} joints)")
    print(details)
    return EXIT_OK


def _describe_urdf(file: Path, base: str | None, tip: str | None) -> int:
    tree = read_urdf_tree(file)
    robot: Robot | None = None
    if base is not None or tip is not None:
        if base is None or tip is None:
            raise OptikError("give both --base LINK and --tip LINK (or neither)")
    elif len(tree.chains) == 1:
        base, tip = tree.chains[0].base, tree.chains[0].tip
    if base is not None and tip is not None:
        robot = Robot.from_urdf(file, base, tip)  # fails before anything is printed
    details = robot_text(robot) if robot is not None else ""
    print(f"robot {tree.name} (URDF {file})")
    print(f"links ({len(tree.links)}): " + ", ".join(tree.links))
    print("chains (root -> leaf):")
    for chain in tree.chains:
        print(f"  {chain.text()}")
    if robot is None:
        print("pick a chain with --base LINK --tip LINK to see its joints")
        return EXIT_OK
    print(f"chain {base} -> {tip}: {robot.dof} moving joints")
    print(details)
    return EXIT_OK


def _solve_json(problem: Problem, result: Any) -> str:
    robot = problem.robot
    data = {
        "problem": problem.name,
        "success": result.success,
        "status": result.status,
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
    return json.dumps(_json_value(data), allow_nan=False)


def _cmd_solve(args: argparse.Namespace) -> int:
    problem = problem_from_args(args)
    robot = problem.robot
    target, mode = _target_from_args(problem, args)
    result = solve_ik(
        robot,
        target if mode == "pose" else target[:3, 3],
        mode=mode,
        solver=args.solver,
        q0=args.q0,
        tol=args.tol,
        timeout_s=None if args.timeout_ms is None else args.timeout_ms / 1000.0,
        seed=args.seed,
    )
    if args.json:
        print(_solve_json(problem, result))
        return EXIT_OK if result.success else EXIT_NO_SOLUTION
    solver_time = f"{result.solver}, solver time {result.time_s * 1e3:.3f} ms"
    errors = (
        f"position error {result.position_error:.3e} m, orientation error "
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
        print(f"  {joint.name:<24}{_value_text(float(value), joint.kind)}")
    print(f"  {errors}")
    if result.message:
        print(f"  {result.message}")
    return EXIT_OK


def _plan_poses(problem: Problem, args: argparse.Namespace) -> tuple[np.ndarray, str]:
    orientation = _orientation_flag(args)
    if orientation is not None and args.line is None:
        source = "--path" if args.path is not None else "--problem-path"
        raise OptikError(
            f"{orientation} sets the orientation of --line only; a {source} gives its own "
            "orientations (in rad) or none"
        )
    if args.path is not None:
        return read_path(args.path)
    if args.line is not None:
        mode = "pose" if orientation is not None else "position"
        return line(
            _pose_from_args(args.line[:3], args), _pose_from_args(args.line[3:], args), args.step
        ), mode
    if args.problem_path is not None:
        stored = _named(problem, problem.paths, "path", args.problem_path)
        return stored.poses, stored.mode
    raise OptikError("give --path FILE, --line X0 Y0 Z0 X1 Y1 Z1 (m) or --problem-path NAME")


def _cmd_plan(args: argparse.Namespace) -> int:
    out = prepare_folder(args.out)  # fail before the work, not after it
    problem = problem_from_args(args)
    robot = problem.robot
    poses, mode = _plan_poses(problem, args)
    with Progress(len(poses)) as bar:
        plan = plan_path(
            robot,
            poses if mode == "pose" else poses[:, :3, 3],
            mode=mode,
            max_joint_step=args.max_joint_step,
            limit_margin=args.limit_margin,
            q_start=args.q0,
            seed=args.seed,
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
    written = [plan.save(out / f"plan.{ext}") for ext in ("csv", "npz", "json")]
    try:
        written.append(plan.plot(out / "plan.png", robot))
    except OptikError as exc:  # pragma: no cover - only without matplotlib
        print(f"  (no plot: {exc})")
    print("  wrote " + ", ".join(str(p) for p in written))
    return EXIT_OK


def _command(sub: Any, name: str, summary: str, description: str, examples: str) -> Any:
    return sub.add_parser(
        name,
        help=summary,
        description=textwrap.fill(description, 88),
        epilog="examples:\n" + examples,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def _add_solve_command(sub: Any) -> None:
    p = _command(
        sub,
        "solve",
        "solve one IK query on a robot",
        "Solve one IK query and print the joint values (rad, with degrees alongside; m for "
        "prismatic joints), the errors and the solver's own time. An unsolved target prints "
        "its status and the errors of the best attempt, no joint values, and exits 1.",
        "  optik solve dobot_magician --target part1\n"
        "  optik solve planar_2r --position 1 1 0\n"
        "  optik solve --urdf problems/panda.urdf --base panda_link0 --tip panda_hand \\\n"
        "      --position 0.4 0.1 0.5 --rpy-deg 180 0 0\n",
    )
    _add_robot_arguments(p)
    target = p.add_argument_group("target")
    target.add_argument("--target", metavar="NAME", help="a named target of the problem (no unit)")
    target.add_argument(
        "--position",
        nargs=3,
        type=length_float,
        metavar=("X", "Y", "Z"),
        help="target position of the tool, m",
    )
    _add_orientation_arguments(target, "target orientation (a full pose)")
    p.add_argument(
        "--mode",
        choices=["pose", "position"],
        help="pose or position (no unit; default: pose with an orientation, else position)",
    )
    p.add_argument(
        "--solver",
        default="auto",
        choices=["auto", *available_solvers()],
        help="solver name (no unit; default auto)",
    )
    p.add_argument(
        "--tol", type=positive_float, default=1e-6, help="tolerance, m and rad (default 1e-6)"
    )
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
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the restarts (no unit)")
    p.add_argument(
        "--json", action="store_true", help="print the result as one JSON object (no unit)"
    )
    p.set_defaults(func=_cmd_solve)


def _add_plan_command(sub: Any) -> None:
    p = _command(
        sub,
        "plan",
        "turn a Cartesian path into a joint path inside the limits",
        "Plan a continuous joint path inside the limits along a Cartesian path, print a "
        "summary and write OUT/plan.csv, plan.npz, plan.json and plan.png. Path files are "
        "SI (m, rad) unless a TOML path file names its units. A progress bar is drawn on a "
        "terminal.",
        "  optik plan planar_2r --line 1.5 -0.5 0 1.5 0.5 0 --step 0.05\n"
        "  optik plan --urdf problems/panda.urdf --base panda_link0 --tip panda_hand \\\n"
        "      --line 0.4 -0.2 0.5 0.4 0.2 0.5 --rpy-deg 180 0 0 --out panda-plan\n",
    )
    _add_robot_arguments(p)
    path_group = p.add_argument_group("path (one of --path, --line, --problem-path)")
    source = path_group.add_mutually_exclusive_group()
    source.add_argument(
        "--path",
        metavar="FILE",
        type=path_text,
        help="path file (.csv, .npz, .toml; positions in m, rpy in rad; see docs/planning.md)",
    )
    source.add_argument(
        "--line",
        nargs=6,
        type=length_float,
        metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
        help="a straight line between two positions, m",
    )
    source.add_argument(
        "--problem-path", metavar="NAME", help="a named path of the problem file (no unit)"
    )
    p.add_argument(
        "--step",
        type=positive_float,
        default=0.01,
        help="sampling step of --line, m (default 0.01)",
    )
    _add_orientation_arguments(path_group, "constant orientation along --line (a pose path)")
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
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the restarts (no unit)")
    p.add_argument(
        "--out",
        default="optik-plan",
        metavar="DIR",
        type=path_text,
        help="output folder (no unit; default ./optik-plan)",
    )
    p.set_defaults(func=_cmd_plan)


def _add_robot_command(sub: Any) -> None:
    p = _command(
        sub,
        "robot",
        "describe a robot: links, chains, joints with limits, closed form",
        "Print a robot's links, its candidate chains (root -> leaf, with their joint counts; "
        "pick one for --urdf with --base and --tip), its joints with their limits in rad "
        "(degrees alongside) or m, and the closed-form family found.",
        "  optik robot problems/panda.urdf\n"
        "  optik robot problems/panda.urdf --base panda_link0 --tip panda_hand\n"
        "  optik robot puma560\n",
    )
    p.add_argument(
        "file",
        metavar="FILE",
        type=path_text,
        help="a URDF (.urdf, .xml), a problem file or DH table (.toml), or a built-in "
        "problem name; no unit",
    )
    p.add_argument("--base", metavar="LINK", help="base link of a URDF chain (no unit)")
    p.add_argument("--tip", metavar="LINK", help="tip link of a URDF chain (no unit)")
    p.set_defaults(func=_cmd_robot)


# ---------------------------------------------------------------------------- report
def _caps(values: Sequence[str] | None) -> dict[str, int]:
    caps: dict[str, int] = {}
    for value in values or ():
        name, sep, count = value.rpartition("=")
        if not sep or not name or not count.isdigit() or not count.isascii():
            raise OptikError(f"--cap expects SOLVER=N, got {value!r:.80}")
        caps[name] = int(count)
    return caps


def _report_problems(args: argparse.Namespace) -> tuple[str | Problem, ...] | None:
    given = _robot_choice(args, positional="--problems")
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
    p = _command(
        subparsers,
        "report",
        "compare the IK solvers and write an HTML / Markdown report",
        "Run the solver comparison (closed-form agreement, full IK per robot on random "
        "in-limit targets, the seeds' examples), append every result to OUT/results.csv "
        "and write OUT/index.html, OUT/summary.md, OUT/summary.csv and OUT/summary.json. "
        "The robots are the built-in problems, the --problems given, or your own robot "
        "(--urdf with --base and --tip, or --dh). A progress bar is drawn on a terminal.",
        "  optik report --quick\n"
        "  optik report --quick --problems puma560 ur5 --solvers auto dls\n"
        "  optik report --quick --urdf problems/panda.urdf --base panda_link0 \\\n"
        "      --tip panda_hand --out panda-report\n",
    )
    p.add_argument(
        "--problems",
        nargs="+",
        metavar="PROBLEM",
        type=path_text,
        help="problem names or files (no unit; default: all built-ins)",
    )
    _add_robot_arguments(p, positional=False)
    names = list(default_solvers())
    p.add_argument(
        "--solvers",
        nargs="+",
        metavar="SOLVER",
        choices=names,
        help="solvers (no unit; default: all of them); choices: " + ", ".join(names),
    )
    p.add_argument(
        "-n",
        type=count_int,
        default=None,
        help=f"targets per robot (no unit; default {DEFAULT_N}; quick 5)",
    )
    p.add_argument(
        "--seed",
        type=seed_int,
        default=0,
        help="seed of the targets (no unit; default 0)",
    )
    p.add_argument(
        "--timeout-ms",
        type=positive_float,
        default=None,
        metavar="MS",
        help=f"time limit per IK call, ms (default {DEFAULT_TIMEOUT_S * 1e3:g}; quick 100)",
    )
    p.add_argument(
        "--tol", type=positive_float, default=1e-6, help="tolerance, m and rad (default 1e-6)"
    )
    p.add_argument(
        "--cap",
        action="append",
        metavar="SOLVER=N",
        help="run SOLVER on at most N targets per robot (no unit; repeatable)",
    )
    p.add_argument(
        "--out",
        default="optik-report",
        metavar="DIR",
        type=path_text,
        help="output folder (no unit; default optik-report)",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="a small run (4 robots, 5 targets, fast solvers, 100 ms per call; no unit)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue OUT/results.csv, skipping rows present (no unit)",
    )
    p.set_defaults(func=_cmd_report)
    return p


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``optik`` command."""
    parser = _Parser(
        prog="optik",
        description=textwrap.fill(
            "Optimization-based inverse kinematics for robot arms. Units: SI (m, rad, s) in "
            "files, arrays and options; an option in another unit names it (--rpy-deg, "
            "--timeout-ms).",
            88,
        ),
        epilog="examples:\n  optik problems\n  optik robot problems/panda.urdf\n"
        "  optik solve planar_2r --position 1 1 0\n  optik report --quick\n",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version",
        action="version",
        version=f"optik {__version__}",
        help="print the version and exit (no unit)",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = _command(
        sub,
        "problems",
        "list the built-in (or given) problems",
        "A table of robots: degrees of freedom, joint types, closed-form family, the tool "
        "position at mid-limits (m) and every joint's limits (deg, or m).",
        "  optik problems\n  optik problems puma560 problems/ur5.toml\n",
    )
    p.add_argument(
        "problems",
        nargs="*",
        metavar="PROBLEM",
        type=path_text,
        help="problem files or built-in names (no unit)",
    )
    p.set_defaults(func=_cmd_problems)
    _add_robot_command(sub)
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
