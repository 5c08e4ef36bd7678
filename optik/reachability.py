"""Which points a robot reaches inside its limits: :func:`reachability` and its figure.

Every point is solved (position, or with a fixed orientation) by
:func:`optik.solve_ik_batch`, and each answer verified; :func:`reachability_figure`
draws a slice of the reach sphere.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import (
    FloatArray,
    as_float_array,
    check_choice,
    check_int,
    check_length,
    check_length_array,
    check_real,
    finite_array,
)
from optik._files import output_path
from optik._interrupts import surfaces_interrupts
from optik.errors import OptikError, ShapeError
from optik.ik import solve_ik_batch
from optik.model import Robot
from optik.planning import MAX_RESTARTS, MAX_SEED, _check_robot
from optik.spatial import check_rotation
from optik.verify import beyond_reach


@dataclass
class Reachability:
    """Which sampled points the robot reaches inside its limits.

    Attributes:
        points: (N, 3) world positions (m).
        reachable: (N,) reached inside the limits (verified by FK).
        proven_unreachable: (N,) beyond the robot's reach bound (no configuration gets there).
        q: (N, dof) a configuration for each reachable point (NaN elsewhere).
    """

    points: FloatArray
    reachable: np.ndarray
    proven_unreachable: np.ndarray
    q: FloatArray

    def plot_slice(self, path: str | Path, axis: str = "z", value: float | None = None) -> Path:
        """Scatter of the points near a plane ``axis = value`` coloured by reachability."""
        from optik.plots import plot_reachability

        return plot_reachability(self, output_path(path), axis, value)


@surfaces_interrupts
def reachability(
    robot: Robot,
    points: Any,
    *,
    orientation: Any = None,
    tol: float = 1e-6,
    restarts: int = 3,
    seed: int = 0,
) -> Reachability:
    """Batched reachability of workspace points inside the joint limits.

    Points outside :attr:`Robot.reach_sphere` are rejected without solving (proven
    unreachable); the rest are solved in one compiled, multi-threaded batch (position IK,
    or full pose with the given ``orientation``, a 3x3 rotation shared by all points), each
    answer verified by FK. A point the numeric search misses within ``restarts`` is
    reported unreachable without proof: raise ``restarts`` to search harder.

    Args:
        robot: the robot.
        points: workspace points (N, 3), m, in the world frame.
        orientation: tool rotation (3, 3) shared by all points, no unit (default: position
            IK only).
        tol: IK tolerance, m for position and rad for orientation (one value for both).
        restarts: attempts after the first per point, in [0, MAX_RESTARTS]; no unit.
        seed: seed of the restarts, no unit (the same seed gives the same answer).

    Raises:
        OptikError: ``points`` not finite (N, 3) within
            :data:`~optik._checks.MAX_LENGTH_M`, ``orientation`` not a rotation, ``tol``
            not positive and finite, ``restarts`` not in [0, MAX_RESTARTS] or ``seed`` not
            in [0, MAX_SEED].
    """
    _check_robot(robot)
    tol = check_real("tol", tol, positive=True)
    restarts = check_int("restarts", restarts, minimum=0, maximum=MAX_RESTARTS)
    seed = check_int("seed", seed, minimum=0, maximum=MAX_SEED)
    if orientation is not None:
        check_rotation("orientation", finite_array("orientation", orientation, (3, 3)))
    P = as_float_array("points", points)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ShapeError("points", "(N, 3)", P.shape)
    if not np.all(np.isfinite(P)):
        raise OptikError("points: values must be finite")
    check_length_array("points", P)
    far = beyond_reach(robot, P, tol)
    Q = np.full((len(P), robot.dof), np.nan)
    reachable = np.zeros(len(P), dtype=bool)
    candidates = np.flatnonzero(~far)
    if candidates.size:
        if orientation is None:
            result = solve_ik_batch(
                robot,
                P[candidates],
                mode="position",
                tol=tol,
                restarts=restarts,
                seed=seed,
                proofs=False,
            )
        else:
            R = as_float_array("orientation", orientation)
            if R.shape != (3, 3):
                raise ShapeError("orientation", "(3, 3)", R.shape)
            poses = np.broadcast_to(np.eye(4), (candidates.size, 4, 4)).copy()
            poses[:, :3, :3] = R
            poses[:, :3, 3] = P[candidates]
            result = solve_ik_batch(
                robot, poses, mode="pose", tol=tol, restarts=restarts, seed=seed, proofs=False
            )
        reachable[candidates] = result.success
        Q[candidates[result.success]] = result.q[result.success]
    return Reachability(P, reachable, far, Q)


def reachability_figure(
    robot: Robot,
    *,
    axis: str = "z",
    value: float | None = None,
    resolution: int = 41,
    q: Any = None,
    orientation: Any = None,
    seed: int = 0,
) -> tuple[Any, Any]:
    """The arm (at ``q``, default mid-limits) over a reachability slice of its workspace.

    A ``resolution`` x ``resolution`` grid of points on the plane ``axis = value`` (default:
    through the centre of the reach sphere), clipped to the reach sphere, is solved with
    :func:`reachability` (position IK, or full pose with ``orientation``)
    and drawn green (reached inside the limits) or grey (not reached).

    Args:
        robot: the robot.
        axis: the axis normal to the slice: ``"x"``, ``"y"`` or ``"z"``.
        value: the slice's coordinate along ``axis``, m (default: the reach sphere's centre).
        resolution: grid points per side of the slice, in [2, 400]; no unit.
        q: (dof,) joint values of the arm drawn, rad or m (default: mid-limits).
        orientation: tool rotation (3, 3) for full-pose IK, no unit (default: position IK).
        seed: seed of the IK restarts, no unit.

    Returns:
        ``(figure, axes)``; the axes has the :class:`~optik.reachability.Reachability` as
        ``reachability`` attribute.

    Raises:
        OptikError: ``axis`` not x, y or z; ``value`` not a finite length (a ``bool`` or
            a string is no number); ``resolution`` not in [2, 400].
    """
    from optik.drawing import robot_figure, set_equal_3d

    check_choice("axis", axis, ("x", "y", "z"))
    resolution = check_int("resolution", resolution, minimum=2, maximum=400)
    centre, radius = robot.reach_sphere
    k = "xyz".index(axis)
    level = float(centre[k]) if value is None else check_length("value", value)
    a, b = [i for i in range(3) if i != k]
    u = np.linspace(-radius, radius, resolution)
    A, B = np.meshgrid(centre[a] + u, centre[b] + u)
    points = np.zeros((A.size, 3))
    points[:, a], points[:, b], points[:, k] = A.ravel(), B.ravel(), level
    points = points[np.linalg.norm(points - centre, axis=1) <= radius]
    if len(points) == 0:
        raise OptikError(f"value: the plane {axis} = {level:g} m misses the reach sphere")
    result = reachability(robot, points, orientation=orientation, seed=seed)
    title = (
        f"{robot.name}: {int(result.reachable.sum())}/{len(points)} points of the slice "
        f"{axis} = {level:.3g} m reached"
    )
    fig, ax = robot_figure(robot, q, title=title)
    for mask, colour, label in (
        (result.reachable, "tab:green", "reached inside the limits"),
        (~result.reachable, "0.4", "not reached"),
    ):
        P = points[mask]
        ax.scatter(P[:, 0], P[:, 1], P[:, 2], s=8, color=colour, alpha=0.6, label=label)
    arm = robot.frames(robot.mid_limits if q is None else q)[:, :3, 3]
    set_equal_3d(ax, np.concatenate([points, arm]))
    ax.legend(loc="upper left", fontsize=8)
    ax.reachability = result
    return fig, ax
