"""``optik show``: a picture of the robot in 3-D."""

from __future__ import annotations

import argparse
import sys
import warnings
from typing import Any

from optik._files import check_folder
from optik.cli._common import (
    EXIT_OK,
    add_out_argument,
    add_robot_arguments,
    command,
    finite_float,
    joint_values,
    problem_from_args,
)
from optik.errors import OptikError

_FORMATS = (".png", ".svg", ".pdf")


def _cmd_show(args: argparse.Namespace) -> int:
    from pathlib import Path

    from optik.drawing import MeshWarning, show_robot, visual_meshes

    if args.view is not None:
        if args.view_deg is not None:
            raise OptikError("give --view-deg only (--view is its deprecated name)")
        print(
            "optik: note: --view is deprecated; give --view-deg ELEV AZIM (the same deg)",
            file=sys.stderr,
        )
        args.view_deg = args.view
    out = Path(args.out)
    if out.suffix.lower() not in _FORMATS:
        raise OptikError(f"--out {out}: expected a {', '.join(_FORMATS)} file")
    if out.is_dir():
        raise OptikError(f"--out {out}: a folder, not an image file")
    check_folder(out.parent)  # before the robot is loaded and drawn, not after
    problem = problem_from_args(args)
    robot = problem.robot
    given = joint_values(robot, args.q, "--q", within_limits=False)
    q = robot.mid_limits if given is None else robot.check_q(given, "--q")
    values = ", ".join(f"{v:.4g}" for v in q)
    outside = "" if robot.within_limits(q) else " (outside the joint limits)"
    print(f"{robot.name} at q = ({values}) rad or m{outside}")
    meshes: list[Any] = []
    if args.urdf is not None and not args.no_meshes:
        try:
            with warnings.catch_warnings(record=True) as missing:
                warnings.simplefilter("always", MeshWarning)
                meshes = visual_meshes(args.urdf, robot, q, args.base)
            print(f"  {len(meshes)} visual meshes from {args.urdf}")
            for note in missing:
                print(f"  {note.message}")
        except OptikError as exc:  # a picture without meshes is still a picture
            print(f"  no meshes drawn: {' '.join(str(exc).split())}")
    view = (args.view_deg[0], args.view_deg[1]) if args.view_deg else (22.0, -58.0)
    print(f"  wrote {show_robot(robot, out, q, meshes=meshes, view=view)}")
    return EXIT_OK


def add_show_command(sub: Any) -> None:
    p = command(
        sub,
        "show",
        "draw the robot in 3-D to an image file",
        "Draw the arm in 3-D at a configuration (default: mid-limits): links between the "
        "joint origins, each joint's axis as an arrow, the base and tool frames as RGB "
        "triads (x red, y green, z blue) and, for a --urdf robot whose visual meshes load "
        "(package:// names resolved against the folders above the file), the meshes.",
        "  optik show puma560 --out puma.png\n"
        "  optik show ur5 --q 0 -1.2 1.5 -1 -1.4 0 --out ur5.png\n"
        "  optik show --urdf problems/panda.urdf --base panda_link0 --tip panda_hand\n",
    )
    add_robot_arguments(p)
    p.add_argument(
        "--q",
        nargs="+",
        type=finite_float,
        metavar="Q",
        help="the configuration, one value per joint: rad (revolute) or m (prismatic); "
        "default mid-limits",
    )
    p.add_argument(
        "--view-deg",
        nargs=2,
        type=finite_float,
        metavar=("ELEV", "AZIM"),
        help="camera elevation and azimuth, deg (default 22 -58)",
    )
    # The name before the units rule (a non-SI option names its unit): kept for scripts.
    p.add_argument("--view", nargs=2, type=finite_float, help=argparse.SUPPRESS)
    p.add_argument(
        "--no-meshes",
        action="store_true",
        help="do not draw the --urdf file's visual meshes",
    )
    add_out_argument(p, "FILE", "image file, .png, .svg or .pdf (default ./robot.png)", "robot.png")
    p.set_defaults(func=_cmd_show)


__all__ = ["add_show_command"]
