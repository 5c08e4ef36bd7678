"""``optik view``: the robot in the browser, with a target to drag (:mod:`optik.viewer`)."""

from __future__ import annotations

import argparse
import signal
import threading
from typing import Any

from optik.cli._common import (
    EXIT_OK,
    add_path_group,
    add_robot_arguments,
    command,
    finite_float,
    joint_values,
    path_from_args,
    positive_float,
    problem_from_args,
)
from optik.planning import PathPlan, plan_path
from optik.problems import Problem
from optik.solvers import available_solvers
from optik.viewer import VIEW_MODES, Viewer


def _port(text: str) -> int:
    """An argparse type: a TCP port, an integer in [0, 65535] (0: any free port)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a port in [0, 65535], got {text!r:.40}"
        ) from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port in [0, 65535], got {text!r:.40}")
    return value


def _plan(problem: Problem, args: argparse.Namespace) -> PathPlan | None:
    """The plan of ``--path`` or ``--problem-path``, or ``None`` without either."""
    stored = path_from_args(problem, args)
    if stored is None:
        return None
    poses, mode = stored
    return plan_path(
        problem.robot,
        poses if mode == "pose" else poses[:, :3, 3],
        mode=mode,
        max_joint_step=args.max_joint_step,
    )


def _cmd_view(args: argparse.Namespace) -> int:
    problem = problem_from_args(args)
    plan = _plan(problem, args)
    viewer = Viewer(
        problem.robot,
        host=args.host,
        port=args.port,
        q=joint_values(problem.robot, args.q0, "--q0"),
        mode=args.mode,
        solver=args.solver,
        timeout_s=args.timeout_ms / 1000.0,
    )
    stop = threading.Event()
    # SIGTERM (a service manager, `kill`) stops as cleanly as Ctrl-C; only the main
    # thread may set a handler (main() called from another thread keeps the default).
    handles_term = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set()) if handles_term else None
    try:
        if plan is not None:
            viewer.load_plan(plan)
            summary = plan.summary()
            print(
                f"{problem.name}: plan of {summary['waypoints']} waypoints, "
                f"{summary['flagged']} flagged"
            )
        try:
            # Printed inside the try: a Ctrl-C sent as soon as the URL is read can land
            # before the wait begins, and it stops as cleanly there.
            print(f"optik view: {problem.name} at {viewer.url} (Ctrl-C stops)", flush=True)
            while not stop.wait(timeout=0.5):  # a short wait keeps Ctrl-C responsive
                pass
        except KeyboardInterrupt:
            pass
    finally:
        if handles_term:
            signal.signal(signal.SIGTERM, previous)
        viewer.close()
    print("optik view: stopped", flush=True)
    return EXIT_OK


def add_view_command(sub: Any) -> None:
    p = command(
        sub,
        "view",
        "show the robot in the browser; drag a target and IK follows",
        "Serve a local web page (viser) that shows the robot: links, joint axes and frames; "
        "a target gizmo that solve_ik follows live as it is dragged, in the task mode of a "
        "dropdown (pose, axis, position); buttons that step through every closed-form "
        "branch; a plan played back along its path with flagged waypoints coloured "
        "(--path or --problem-path). Binds 127.0.0.1 by default and prints the URL; "
        "Ctrl-C stops it. Needs the viewer extra: pip install 'optik[viewer]'.",
        "  optik view puma560\n"
        "  optik view --urdf problems/panda.urdf --base panda_link0 --tip panda_hand --port 0\n"
        "  optik view dobot_magician --problem-path table2 --mode position\n",
    )
    add_robot_arguments(p)
    server = p.add_argument_group("server")
    server.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to bind (default 127.0.0.1, this machine only; 0.0.0.0 "
        "serves every network interface)",
    )
    server.add_argument(
        "--port",
        type=_port,
        default=8080,
        help="TCP port (no unit; default 8080; 0 picks a free port; a taken port moves to "
        "the next free one, and the URL printed is the one bound)",
    )
    p.add_argument(
        "--mode",
        choices=VIEW_MODES,
        default="pose",
        help="initial task mode of the target (default pose)",
    )
    p.add_argument(
        "--solver",
        choices=["auto", *available_solvers()],
        default="auto",
        help="initial IK solver (default auto); the page's dropdown changes it",
    )
    p.add_argument(
        "--q0",
        nargs="+",
        type=finite_float,
        metavar="Q",
        help="initial configuration, one value per joint: rad (revolute) or m (prismatic); "
        "default mid-limits",
    )
    p.add_argument(
        "--timeout-ms",
        type=positive_float,
        default=250.0,
        help="wall-time budget of each live solve, ms (default 250)",
    )
    plan_group = add_path_group(
        p,
        "plan to play back (one of --path, --problem-path)",
        "path file to plan and play (.csv, .npz, .toml; positions in m, rpy in rad)",
    )
    plan_group.add_argument(
        "--max-joint-step",
        type=positive_float,
        default=0.1,
        help="largest continuous joint step of the plan, rad or m (default 0.1)",
    )
    p.set_defaults(func=_cmd_view)
