"""The ``optik`` command: shared argument types, robot and target options, exit codes.

The exit codes and the unit conventions of every command are stated once, in
:mod:`optik.cli`; the constants and argument types here implement them.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from optik._checks import MAX_LENGTH_M, FloatArray, not_a_file, read_number
from optik.compare.config import MAX_SEED, MAX_TARGETS
from optik.diffik import clip_into_limits
from optik.errors import OptikError
from optik.model import Robot
from optik.paths import read_path
from optik.poses import pose
from optik.problems import PROBLEMS_DIR, Problem, builtin_problems, load_problem, load_robot
from optik.robot_text import read_urdf_tree

#: Exit codes of the ``optik`` command.
EXIT_OK = 0
EXIT_NO_SOLUTION = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_OUTPUT_CLOSED = 141
"""Standard output closed before the command finished (a pipe's reader, such as ``head``,
quit): the shell's code for a process ended by SIGPIPE (128 + 13)."""

URDF_SUFFIXES = (".urdf", ".xml")


#: A negative number as an argument: argparse's own pattern (``-3``, ``-0.3``) plus an
#: exponent (``-3e-1``), which it would otherwise take for an unknown option, and ``-inf``
#: and ``-nan``, which then reach the number checks and are refused as not finite (taken
#: for options, they gave "expected 3 arguments").
NEGATIVE_NUMBER = re.compile(r"^-((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf|infinity|nan)$", re.I)


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one ``optik: error: ...`` line (exit 2).

    Arguments such as ``-3e-1`` are read as negative numbers, not options. Subparsers
    are made of this class too (``add_subparsers`` uses the parent's class).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse sets its matcher per instance in __init__, so a class attribute would
        # be shadowed; set it before any option is added (add_argument consults it).
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"optik: error: {message} (see '{self.prog} --help')\n")


# ---------------------------------------------------------------------------- numbers
def _number(text: str, kind: type, check: Any, what: str) -> Any:
    try:
        value = read_number(text, kind)
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


def positive_int(text: str) -> int:
    """An argparse type: an integer >= 1 (a bad value is told so, -3 and 0 alike)."""
    return int(_number(text, int, lambda v: v >= 1, "an integer >= 1"))


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


def json_value(value: Any) -> Any:
    """``value`` with every non-finite float as ``None`` (JSON has no inf or NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_value(v) for v in value]
    return value


def limit_text(lower: float, upper: float, kind: str) -> str:
    if not math.isfinite(lower):
        return "continuous"
    if kind == "prismatic":
        return f"{lower:g}..{upper:g} m"
    return f"{math.degrees(lower):g}..{math.degrees(upper):g}°"


def value_text(value: float, kind: str) -> str:
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
        limits = ", ".join(f"{j.name} {limit_text(j.lower, j.upper, j.kind)}" for j in robot.joints)
        lines.append(f"{'':<26}limits: {limits}")
    return "\n".join(lines)


# ---------------------------------------------------------------------------- robots
def builtin_names() -> str:
    return ", ".join(p.stem for p in builtin_problems())


def exists(path: Path) -> bool:
    """Whether ``path`` exists; a name the system cannot look up (too long) does not."""
    try:
        return path.exists()
    except (OSError, ValueError):
        return False


def joint_values(
    robot: Robot, values: Sequence[float] | None, option: str, within_limits: bool = True
) -> FloatArray | None:
    """``values`` of an option such as ``--q0`` with one value per joint (rad or m), or None.

    ``within_limits``: the values are a configuration, inside the limits as
    :func:`optik.diffik.clip_into_limits` takes one (a posture need not be).

    Raises:
        OptikError: not ``robot.dof`` values (the message counts them, and names the
            joints), or (``within_limits``) a value beyond its joint's limits; the
            message names the option.
    """
    if values is None:
        return None
    if len(values) != robot.dof:
        names = ", ".join(robot.joint_names)
        raise OptikError(
            f"{option}: expected {robot.dof} values, one per joint ({names}), got {len(values)}"
        )
    q = np.array(values, dtype=np.float64)
    return clip_into_limits(robot, option, q) if within_limits else q


def named_problem(name: str, other_sources: bool = True) -> Problem:
    """A built-in problem by name, or a problem file; an unknown name lists the built-ins.

    ``other_sources``: the command also takes ``--urdf`` and ``--dh`` (the message says so).

    Raises:
        OptikError: neither a file nor a built-in name (the message lists the built-ins),
            or any :class:`~optik.errors.ProblemFileError` of the file.
    """
    file = Path(name)
    if exists(file) or (file.suffix == "" and exists(PROBLEMS_DIR / f"{name}.toml")):
        return load_problem(name)
    if file.suffix or len(file.parts) > 1:  # a path, not a name
        reason = not_a_file(file)
        raise OptikError(f"{name}: {reason} (built-in problems: {builtin_names()})")
    others = "; or give --urdf FILE or --dh FILE" if other_sources else ""
    raise OptikError(
        f"no problem file or built-in problem named {name!r:.200} "
        f"(built-in problems: {builtin_names()}{others})"
    )


def chains_hint(urdf: Path) -> str:
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
        raise OptikError(f"--urdf needs {missing} LINK; {chains_hint(path)}")
    robot = Robot.from_urdf(path, base, tip)  # a Path: never read as XML text
    return Problem(name=robot.name, robot=robot, source=f"URDF {path}: {base} -> {tip}", path=path)


def dh_problem(file: str) -> Problem:
    """The robot of a DH table (a ``[robot]`` table in the ``dh`` or ``mdh`` convention).

    Raises:
        OptikError: not a file, a ``urdf``-convention robot, or any
            :class:`~optik.errors.ProblemFileError` of the file.
    """
    if not Path(file).is_file():
        reason = not_a_file(Path(file))
        raise OptikError(f"--dh {file!r:.200}: {reason} (a DH table is a .toml file)")
    problem = load_robot(file)
    if problem.robot.convention not in ("dh", "mdh"):
        raise OptikError(
            f"--dh {file}: convention {problem.robot.convention!r} is not a DH table "
            "(give a urdf-convention file as PROBLEM, or the URDF itself with --urdf)"
        )
    return problem


def robot_choice(args: argparse.Namespace, positional: str = "PROBLEM") -> list[str]:
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
    if not robot_choice(args):
        raise OptikError(
            "give a robot: a PROBLEM (a built-in name or a problem file), "
            f"--urdf FILE --base LINK --tip LINK, or --dh FILE (built-in problems: "
            f"{builtin_names()})"
        )
    if args.urdf is not None:
        return urdf_problem(args.urdf, args.base, args.tip)
    if args.dh is not None:
        return dh_problem(args.dh)
    return named_problem(args.problem)


def add_chain_links(p: argparse.ArgumentParser | argparse._ArgumentGroup, chain: str) -> None:
    """``--base LINK`` and ``--tip LINK``: the ends of ``chain`` (as the help names it)."""
    p.add_argument("--base", metavar="LINK", help=f"base link of {chain}")
    p.add_argument("--tip", metavar="LINK", help=f"tip link of {chain}")


def add_robot_arguments(p: argparse.ArgumentParser, *, positional: bool = True) -> None:
    if positional:
        p.add_argument(
            "problem",
            nargs="?",
            metavar="PROBLEM",
            type=path_text,
            help="a built-in problem name or a problem file (.toml; the file names its "
            "units). Or give --urdf or --dh instead",
        )
    group = p.add_argument_group("your own robot (instead of a problem)")
    group.add_argument(
        "--urdf",
        metavar="FILE",
        type=path_text,
        help="a URDF file (its lengths in m, angles in rad), with --base and --tip",
    )
    add_chain_links(group, "the --urdf chain (a link name)")
    group.add_argument(
        "--dh",
        metavar="FILE",
        type=path_text,
        help="a DH table: a .toml [robot] table with [[robot.joints]] rows (convention dh "
        "or mdh); units as the file names them (length_unit, angle_unit; default m, rad)",
    )


# ---------------------------------------------------------------------------- poses
ORIENTATION_FLAGS = (
    ("--rpy", ("R", "P", "Y"), "roll, pitch, yaw in rad, R = Rz(Y) Ry(P) Rx(R) (URDF convention)"),
    (
        "--rpy-deg",
        ("R", "P", "Y"),
        "roll, pitch, yaw in deg, R = Rz(Y) Ry(P) Rx(R) (URDF convention)",
    ),
    ("--quat-wxyz", ("W", "X", "Y", "Z"), "a unit quaternion, scalar first (no unit)"),
    (
        "--quat-xyzw",
        ("X", "Y", "Z", "W"),
        "a unit quaternion, scalar last, as scipy and ROS (no unit)",
    ),
)
"""The orientation options: flag, the names of its numbers, and what they are."""


def add_orientation_arguments(p: Any, what: str) -> None:
    """One of --rpy, --rpy-deg, --quat-wxyz, --quat-xyzw on ``p`` (a parser or a group)."""
    group = p.add_mutually_exclusive_group()
    for flag, metavar, meaning in ORIENTATION_FLAGS:
        group.add_argument(
            flag, nargs=len(metavar), type=finite_float, metavar=metavar, help=f"{what}: {meaning}"
        )


def orientation_flag(args: argparse.Namespace) -> str | None:
    for flag, _, _ in ORIENTATION_FLAGS:
        if getattr(args, flag[2:].replace("-", "_")) is not None:
            return flag
    return None


def pose_from_args(position: Sequence[float], args: argparse.Namespace) -> np.ndarray:
    """The 4x4 pose of ``position`` (m) and the orientation options (identity if none)."""
    if args.rpy is not None:
        return pose(position, rpy=args.rpy, rpy_convention="urdf")
    if args.rpy_deg is not None:
        return pose(position, rpy=args.rpy_deg, rpy_convention="urdf", degrees=True)
    return pose(position, quat_wxyz=args.quat_wxyz, quat_xyzw=args.quat_xyzw)


def named(problem: Problem, table: dict[str, Any], kind: str, name: str) -> Any:
    """``table[name]``, or an error naming the problem and listing the known names."""
    if name not in table:
        known = ", ".join(table) or "none"
        raise OptikError(f"problem {problem.name!r} has no {kind} {name!r} ({kind}s: {known})")
    return table[name]


def add_path_group(
    p: argparse.ArgumentParser, title: str, path_help: str, *, line: bool = False
) -> Any:
    """The group ``title`` of a command's path: one of ``--path FILE``, ``--problem-path NAME``.

    Args:
        p: the command's parser.
        title: the group's title in the help.
        path_help: what ``--path`` is, for this command.
        line: also offer ``--line X0 Y0 Z0 X1 Y1 Z1`` (m), a straight line.

    Returns:
        The argument group, for the command's own options of the path.
    """
    group = p.add_argument_group(title)
    source = group.add_mutually_exclusive_group()
    source.add_argument("--path", metavar="FILE", type=path_text, help=path_help)
    if line:
        source.add_argument(
            "--line",
            nargs=6,
            type=length_float,
            metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
            help="a straight line between two positions, m",
        )
    source.add_argument("--problem-path", metavar="NAME", help="a named path of the problem file")
    return group


def path_from_args(problem: Problem, args: argparse.Namespace) -> tuple[np.ndarray, str] | None:
    """The (N, 4, 4) poses and mode of ``--path FILE`` or ``--problem-path NAME``.

    Returns:
        ``(poses, mode)`` (``mode`` ``"pose"`` for a path with orientations, else
        ``"position"``), or ``None`` when neither option is given.

    Raises:
        OptikError: an unreadable path file, or a name the problem has no path of.
    """
    if args.path is not None:
        return read_path(args.path)
    if args.problem_path is not None:
        stored = named(problem, problem.paths, "path", args.problem_path)
        return stored.poses, stored.mode
    return None


def target_from_args(problem: Problem, args: argparse.Namespace) -> tuple[np.ndarray, str]:
    orientation = orientation_flag(args)
    if args.target is not None:
        if args.position is not None or orientation is not None:
            given = "--position" if args.position is not None else orientation
            raise OptikError(f"--target NAME takes its pose from the problem; drop {given}")
        target = named(problem, problem.targets, "target", args.target)
        return target.pose, args.mode or target.mode
    if args.position is None:
        raise OptikError(
            "give --target NAME or --position X Y Z (m), with an orientation "
            "(--rpy, --rpy-deg, --quat-wxyz or --quat-xyzw) for a full pose"
        )
    mode = args.mode or ("pose" if orientation is not None else "position")
    if mode == "position" and orientation is not None:
        raise OptikError(f"--mode position ignores the orientation: drop {orientation}")
    return pose_from_args(args.position, args), mode


# ---------------------------------------------------------------------------- outputs
def add_out_argument(
    p: argparse.ArgumentParser, metavar: str, help: str, default: str | None = None
) -> None:
    """``--out``, where a command writes (a :func:`path_text`; required without a default)."""
    p.add_argument(
        "--out",
        required=default is None,
        default=default,
        metavar=metavar,
        type=path_text,
        help=help,
    )


def add_tol_argument(
    p: Any, what: str = "tolerance", *, of_target: bool = False, own: str | None = None
) -> None:
    """``--tol``: one tolerance for the position (m) and the orientation (rad), 1e-6 by default.

    With ``of_target`` the default is ``None``: the named target's own tolerances
    (:func:`target_tolerance`), else 1e-6. ``own`` names another source of that default
    (e.g. ``"a --problem-path's own tolerance"``), read by the command.
    """
    if of_target:
        own = "the --target's own tolerances"
    if own is not None:
        p.add_argument(
            "--tol",
            type=positive_float,
            default=None,
            help=f"{what}, m and rad (default: {own}, else 1e-6)",
        )
        return
    p.add_argument(
        "--tol", type=positive_float, default=1e-6, help=f"{what}, m and rad (default 1e-6)"
    )


def target_tolerance(problem: Problem, args: argparse.Namespace) -> float | tuple[float, float]:
    """``--tol``, else the ``--target``'s ``(tolerance, angle_tolerance)``, else 1e-6."""
    if args.tol is not None:
        return float(args.tol)
    if args.target is not None:
        target = problem.targets[args.target]
        return (target.tolerance, target.angle_tolerance)
    return 1e-6


def add_seed_argument(p: Any, what: str, *, show_default: bool = False) -> None:
    """``--seed``: a :func:`seed_int`, 0 by default; ``what`` says what it seeds."""
    default = "; default 0" if show_default else ""
    p.add_argument("--seed", type=seed_int, default=0, help=f"{what} (no unit{default})")


def command(sub: Any, name: str, summary: str, description: str, examples: str) -> Any:
    return sub.add_parser(
        name,
        help=summary,
        description=textwrap.fill(description, 88),
        epilog="examples:\n" + examples,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
