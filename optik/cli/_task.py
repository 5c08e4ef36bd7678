"""The task options of ``optik solve`` and ``optik plan``: --mode, --axis, --weights, --freeze.

They map one to one onto the task keywords of :func:`optik.solve_ik` and
:func:`optik.plan_path` (:mod:`optik.task`), which validate them; this module only reads
them from the command line.
"""

from __future__ import annotations

import argparse
from typing import Any

from optik.cli._common import finite_float, non_negative_float
from optik.errors import OptikError
from optik.task import AXES, MODES, make_task

#: Modes that need a target orientation (a pose, not a point). ``pose`` is not among
#: them: a pose without an orientation option has the identity rotation.
ORIENTED_MODES = ("orientation", "axis")


def joint_value(text: str) -> tuple[str, float]:
    """An argparse type: ``JOINT=VALUE``, a joint name and a finite value (rad or m)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(
            f"expected JOINT=VALUE (a joint name, a value in rad or m), got {text!r:.80}"
        )
    return name.strip(), finite_float(value)


def add_task_arguments(p: argparse.ArgumentParser, mode_default: str) -> Any:
    """Add --mode, --axis, --weights and --freeze to ``p``; return their group."""
    group = p.add_argument_group("task (see docs/tasks.md)")
    group.add_argument(
        "--mode",
        choices=list(MODES),
        help="what the target constrains: the full pose, the position, the orientation, "
        "or the tool axis (position + the direction of --axis, the roll about it free); "
        f"(default: {mode_default})",
    )
    group.add_argument(
        "--axis",
        choices=list(AXES),
        help="the tool axis of --mode axis, which points along the target's same axis (default z)",
    )
    group.add_argument(
        "--weights",
        nargs=6,
        type=non_negative_float,
        metavar=("WX", "WY", "WZ", "WRX", "WRY", "WRZ"),
        help="task weights >= 0 on x, y, z, rx, ry, rz in the target frame, 0 frees that "
        "axis; rotational weights all positive, exactly one zero (= --mode axis) or all "
        "zero (= --mode position); no unit",
    )
    group.add_argument(
        "--freeze",
        action="append",
        type=joint_value,
        metavar="JOINT=VALUE",
        help="hold joint JOINT at VALUE: rad (revolute) or m (prismatic), inside its "
        "limits; repeatable",
    )
    return group


def task_mode(args: argparse.Namespace, mode: str) -> str:
    """The task's mode: ``mode``, or the one that ``--weights`` chooses with it.

    Raises:
        OptikError: weights that do not describe ``mode`` (:func:`optik.task.make_task`).
    """
    if args.weights is None:
        return mode
    return make_task(mode, weights=args.weights).mode


def task_keywords(args: argparse.Namespace, mode: str) -> dict[str, Any]:
    """The ``axis``, ``weights`` and ``frozen`` keywords of the options.

    Raises:
        OptikError: --axis with a mode other than ``axis`` or with weights that free
            another axis, or a joint frozen twice.
    """
    if args.axis is not None:
        if task_mode(args, mode) != "axis":
            raise OptikError(f"--axis {args.axis} is the tool axis of --mode axis, not of {mode}")
        if args.weights is not None and args.weights[3 + AXES.index(args.axis)] != 0.0:
            raise OptikError(
                f"--axis {args.axis} disagrees with --weights: the zero rotational weight "
                "names the free axis"
            )
    frozen: dict[str, float] = {}
    for name, value in args.freeze or []:
        if name in frozen:
            raise OptikError(f"--freeze {name}: the joint is given twice")
        frozen[name] = value
    return {"axis": args.axis or "z", "weights": args.weights, "frozen": frozen or None}
