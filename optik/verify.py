"""One verification of IK answers, from forward kinematics and the limits.

Every result optik reports (:func:`optik.solve_ik`, :func:`optik.solve_ik_batch`, the
closed forms' callers, the comparison runs, planning and the benchmarks) is judged here,
never by a backend's own claim: the position error ``||p(q) - p*||`` (m), the
orientation error ``angle(R*^T R(q))`` (rad; 0 in position mode) and the limit violation
(rad or m), all computed by :func:`optik._kernels.pose_errors_into` from the robot's chain.
Success means both errors at most ``tol`` and the violation at most
:data:`optik.limits.LIMIT_TOLERANCE`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik._kernels import pose_errors_into
from optik.limits import LIMIT_TOLERANCE
from optik.model import Robot
from optik.task import Task, as_task

#: Relative slack of the reach sphere's proof (:func:`beyond_reach`): forward kinematics
#: rounds a tool position by some ulps of the arm's length per joint, so a stretched arm's
#: own pose can lie 1e-15 m outside the sphere's radius.
REACH_SLACK = 1e-9


def beyond_reach(robot: Robot, points: FloatArray, tol: float = 0.0) -> np.ndarray:
    """Whether each point lies provably beyond every tool position of ``robot``.

    A point farther than ``radius (1 + REACH_SLACK) + tol`` from the centre of
    :attr:`optik.Robot.reach_sphere` is out of reach (within ``tol``) for every
    configuration inside the limits (the sphere counts a prismatic joint's stroke up to
    its limits): the one test of every "unreachable" that the sphere proves.

    Args:
        robot: the robot.
        points: (N, 3) or (3,) world points (m), finite.
        tol: position tolerance (m), >= 0.

    Returns:
        (N,) booleans, or one numpy boolean for a single point.
    """
    centre, radius = robot.reach_sphere
    return _beyond(np.asarray(points, dtype=float) - centre, radius * (1.0 + REACH_SLACK) + tol)


def beyond_reach_task(robot: Robot, poses: FloatArray, task: Task) -> np.ndarray:
    """:func:`beyond_reach` for a task whose weights may free position axes.

    A zero position weight frees that axis of the target frame: the tool may lie anywhere
    on the line (or plane) through the target along the free axes, and the target is out
    of reach when that line or plane misses the reach sphere, i.e. when the sphere
    centre's offset over the constrained axes (target frame) exceeds the bound. With
    every axis constrained this is :func:`beyond_reach`; with none, nothing is proven.

    Args:
        robot: the robot.
        poses: (N, 4, 4) or (4, 4) world targets (m); their rotations are the frames of
            the weights (identity for a point target).
        task: the task (its weights and position tolerance).

    Returns:
        (N,) booleans, or one numpy boolean for a single pose.
    """
    constrained = task.weights[:3] > 0.0
    T = np.asarray(poses, dtype=float)
    if not constrained.any():
        return np.zeros(T.shape[:-2], dtype=bool)
    centre, radius = robot.reach_sphere
    world = T[..., :3, 3] - centre
    # R^T (p - c): the offset in the target frame; a product, no square, overflows nothing
    # a coordinate alone would not.
    local = np.einsum("...ji,...j->...i", T[..., :3, :3], world)
    return _beyond(
        np.where(constrained, local, 0.0), radius * (1.0 + REACH_SLACK) + task.position_tol
    )


def _beyond(offset: np.ndarray, bound: float) -> np.ndarray:
    """Whether each offset (..., 3) is longer than ``bound``, without squaring a large one."""
    # One coordinate beyond the bound is enough, and squares nothing: a point 1e155 m
    # away is ruled out without an overflow. The distance of the others is then finite.
    largest = np.max(np.abs(offset), axis=-1)
    far = largest > bound
    near = np.where(far[..., None], 0.0, offset)
    # Scaled by the largest coordinate: a robot whose radius is 1e300 m (a prismatic
    # mimic of a large multiplier) squares nothing beyond the float range either.
    scale = np.where(far | (largest == 0.0), 1.0, largest)
    distance = np.linalg.norm(near / scale[..., None], axis=-1) * scale
    return far | (distance > bound)


class Verdict(NamedTuple):
    """Errors of a batch of answers, each (N,), and the verified success mask."""

    position_error: FloatArray
    orientation_error: FloatArray
    limit_violation: FloatArray
    success: np.ndarray


def pose_errors(robot: Robot, Q: FloatArray, targets: FloatArray, mode: str | Task) -> FloatArray:
    """(N, 3) position error (m), orientation error (rad) and limit violation of ``Q``.

    Args:
        robot: the robot.
        Q: (N, dof) or (dof,) configurations (rad, m); a row with NaN or inf gets inf.
        targets: (N, 4, 4) or one (4, 4) world pose of the tool for every row.
        mode: a :class:`optik.task.Task` or a mode name; the errors are the task's judged
            errors (:mod:`optik.task`: e.g. 0 orientation error for a point).
    """
    Q2 = np.ascontiguousarray(np.asarray(Q, dtype=np.float64).reshape(-1, robot.dof))
    T = np.ascontiguousarray(np.asarray(targets, dtype=np.float64).reshape(-1, 4, 4))
    out = np.empty((Q2.shape[0], 3))
    pose_errors_into(robot.chain.kernel_args(), Q2, T, as_task(mode).packed, out)
    return out


def verify(
    robot: Robot, Q: FloatArray, targets: FloatArray, mode: str | Task, tol: float = 1e-6
) -> Verdict:
    """:func:`pose_errors` and the success mask.

    Success: both errors within the task's tolerances and inside the limits; ``tol``
    applies when ``mode`` is a name.
    """
    task = as_task(mode, tol)
    errors = pose_errors(robot, Q, targets, task)
    position, orientation, violation = errors[:, 0], errors[:, 1], errors[:, 2]
    success = (
        (position <= task.position_tol)
        & (orientation <= task.orientation_tol)
        & (violation <= LIMIT_TOLERANCE)
    )
    return Verdict(position, orientation, violation, success)


def verify_one(
    robot: Robot, q: FloatArray, target: FloatArray, mode: str | Task, tol: float = 1e-6
) -> tuple[float, float, float, bool]:
    """:func:`verify` of one configuration: ``(position, orientation, violation, success)``."""
    task = as_task(mode, tol)
    errors = pose_errors(robot, q, target, task)[0]
    position, orientation, violation = float(errors[0]), float(errors[1]), float(errors[2])
    success = (
        position <= task.position_tol
        and orientation <= task.orientation_tol
        and violation <= LIMIT_TOLERANCE
    )
    return position, orientation, violation, success


__all__ = ["Verdict", "pose_errors", "verify", "verify_one"]
