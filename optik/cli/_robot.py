"""``optik problems`` and ``optik robot``: tables and descriptions of robots."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from optik.cli._common import (
    EXIT_OK,
    URDF_SUFFIXES,
    add_chain_links,
    command,
    named_problem,
    path_text,
    problems_table,
)
from optik.errors import OptikError, URDFError
from optik.model import Robot
from optik.problems import builtin_problems, load_robot
from optik.robot_text import read_urdf_tree, robot_text


def _cmd_problems(args: argparse.Namespace) -> int:
    paths = args.problems or builtin_problems()
    print(problems_table([named_problem(str(p), other_sources=False) for p in paths]))
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
    unloadable = ""  # why the file's one chain, picked here, cannot be a robot
    if base is not None or tip is not None:
        if base is None or tip is None:
            raise OptikError("give both --base LINK and --tip LINK (or neither)")
        robot = Robot.from_urdf(file, base, tip)  # the chain asked for: fails at once
    elif len(tree.chains) == 1:
        base, tip = tree.chains[0].base, tree.chains[0].tip
        try:
            robot = Robot.from_urdf(file, base, tip)
        except URDFError as exc:  # a mimic joint, no moving joint: the links still print
            unloadable = str(exc).removeprefix(f"{file}: ")
    details = robot_text(robot) if robot is not None else ""
    print(f"robot {tree.name} (URDF {file})")
    print(f"links ({len(tree.links)}): " + ", ".join(tree.links))
    print("chains (root -> leaf):")
    for chain in tree.chains:
        print(f"  {chain.text()}")
    if unloadable:
        print(f"chain {base} -> {tip}: cannot be loaded ({unloadable})")
        return EXIT_OK
    if robot is None:
        print("pick a chain with --base LINK --tip LINK to see its joints")
        return EXIT_OK
    print(f"chain {base} -> {tip}: {robot.dof} moving joints")
    print(details)
    return EXIT_OK


def add_robot_command(sub: Any) -> None:
    p = command(
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
        help="a URDF (.urdf, .xml), a problem file or DH table (.toml), or a built-in problem name",
    )
    add_chain_links(p, "a URDF chain")
    p.set_defaults(func=_cmd_robot)


def add_problems_command(sub: Any) -> None:
    p = command(
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
        help="problem files or built-in names",
    )
    p.set_defaults(func=_cmd_problems)
