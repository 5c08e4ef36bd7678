"""Six joints R, R, P and a spherical wrist (the Stanford arm, the jumbo drill), from the axes.

Found from the joint axes at ``q = 0`` (:func:`optik.analytic.geometry.joint_axes`), so
an arm loaded from URDF or modified DH fits as well as one from standard DH rows (which
the compiled ``spherical_wrist`` family solves first, :mod:`optik.analytic.spherical_wrist`):
six joints without coupling, revolute, revolute, prismatic, then three revolute joints
whose axes meet in one point ``W`` (within ``LENGTH_TOL`` times the arm's size), with
axis 5 parallel to neither 4 nor 6; the arm's axes as :mod:`optik.analytic.spherical_rrp`
takes them (axes 1 and 2 not parallel, the slide normal to axis 2).

The wrist's rotations leave ``W`` where it is, so the target places it by the first
three joints alone (``W_t = T M^-1 W``, ``M`` the tool at ``q = 0``): up to four arm
branches of :func:`optik.analytic.spherical_rrp.arm_branches`. For each, the wrist
rotation ``R4 R5 R6 = (R1 R2)^T R_T M_R^T`` (world rotations about the axes at ``q = 0``)
follows from two rotations taking ``z6`` to ``v = R4 R5 R6 z6`` (Paden-Kahan subproblem
2: ``c = R5 z6 = R4^-1 v`` has ``z5 . c = z5 . z6`` and ``z4 . c = z4 . v``, two
solutions) and the last angle from a vector normal to ``z6`` (subproblem 1): up to
eight branches. With axes 4 and 6 aligned the wrist's angles 4 and 6 are one: joint 4
keeps its reference value.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import AnalyticFamily, register
from optik.analytic.geometry import (
    ANGLE_TOL,
    LENGTH_TOL,
    joint_axes,
    joint_kinds_reason,
    point_line_distance,
)
from optik.analytic.spherical_rrp import RRPPlan, arm_branches, arm_plan, placed_point
from optik.model import Robot


class WristPlan(NamedTuple):
    """An RRP arm with a spherical wrist, from its axes at ``q = 0`` (world frame).

    Attributes:
        reason: ``""`` when the joints have the structure, else why not (one line).
        arm: the plan placing the wrist centre with joints 1 to 3.
        directions: the joints' unit directions (six triples of floats).
        wrist_end: (3, 3) ``M_R^T`` applied after the target's world rotation: the tool's
            rotation at ``q = 0``, transposed.
        normal6: a unit vector normal to axis 6 (3 floats, for the last angle).
    """

    reason: str
    arm: RRPPlan | None = None
    directions: tuple[tuple[float, float, float], ...] = ()
    wrist_end: FloatArray | None = None
    normal6: tuple[float, float, float] = (0.0, 0.0, 1.0)


def wrist_plan(robot: Robot) -> WristPlan:
    """The plan of an RRP arm with a spherical wrist, or why ``robot`` does not fit."""
    reason = joint_kinds_reason(robot, "RRPRRR")
    if reason is not None:
        return WristPlan(reason)
    axes = joint_axes(robot)
    z, p = axes.directions, axes.points
    for i, j in ((3, 4), (4, 5)):
        if float(np.linalg.norm(np.cross(z[i], z[j]))) <= ANGLE_TOL:
            return WristPlan(f"axes {i + 1} and {j + 1} are parallel: no spherical wrist")
    # Where axes 4 and 5 come closest; axis 6 must pass through it too.
    k = float(z[3] @ z[4])
    r = p[4] - p[3]
    a, b = float(r @ z[3]), float(r @ z[4])
    den = 1.0 - k * k
    on4 = p[3] + (a - k * b) / den * z[3]
    on5 = p[4] + (k * a - b) / den * z[4]
    centre = 0.5 * (on4 + on5)
    tol = LENGTH_TOL * axes.size
    for i in (3, 4, 5):
        miss = point_line_distance(z[i], p[i], centre)
        if miss > tol:
            return WristPlan(f"axis {i + 1} misses the wrist centre by {miss:.3g} m")
    arm = arm_plan(robot, axes, centre)
    if arm.reason:
        return WristPlan(arm.reason)
    helper = np.eye(3)[int(np.argmin(np.abs(z[5])))]
    normal6 = np.cross(z[5], helper)
    normal6 /= np.linalg.norm(normal6)
    directions = tuple((float(d[0]), float(d[1]), float(d[2])) for d in z)
    n6 = (float(normal6[0]), float(normal6[1]), float(normal6[2]))
    return WristPlan("", arm, directions, axes.tool[:3, :3].T.copy(), n6)


Vec = tuple[float, float, float]
Mat = tuple[Vec, Vec, Vec]


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _apply(M: Mat, v: Vec) -> Vec:
    return (_dot(M[0], v), _dot(M[1], v), _dot(M[2], v))


def _turn(axis: Vec, angle: float, v: Vec) -> Vec:
    """``v`` turned by ``angle`` (rad) about the unit ``axis`` (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    k = _dot(axis, v) * (1.0 - c)
    w = _cross(axis, v)
    return (
        c * v[0] + s * w[0] + k * axis[0],
        c * v[1] + s * w[1] + k * axis[1],
        c * v[2] + s * w[2] + k * axis[2],
    )


def _angle_about(axis: Vec, a: Vec, b: Vec, free: float) -> float:
    """The angle (rad) about the unit ``axis`` that turns ``a`` towards ``b`` (subproblem 1).

    ``free`` when ``a`` or ``b`` lies along the axis (every angle turns it onto itself).
    """
    ka, kb = _dot(axis, a), _dot(axis, b)
    a_n = (a[0] - ka * axis[0], a[1] - ka * axis[1], a[2] - ka * axis[2])
    b_n = (b[0] - kb * axis[0], b[1] - kb * axis[1], b[2] - kb * axis[2])
    if _dot(a_n, a_n) <= 1e-24 or _dot(b_n, b_n) <= 1e-24:
        return free
    return math.atan2(_dot(axis, _cross(a_n, b_n)), _dot(a_n, b_n))


def _two_rotations(z4: Vec, z5: Vec, start: Vec, goal: Vec) -> list[Vec]:
    """The vectors ``c = R5 start = R4^-1 goal`` (subproblem 2): zero, one or two."""
    k = _dot(z4, z5)
    den = 1.0 - k * k
    a4, a5 = _dot(z4, goal), _dot(z5, start)
    alpha = (a4 - k * a5) / den
    beta = (a5 - k * a4) / den
    base = (
        alpha * z4[0] + beta * z5[0],
        alpha * z4[1] + beta * z5[1],
        alpha * z4[2] + beta * z5[2],
    )
    normal = _cross(z4, z5)
    square = (1.0 - _dot(base, base)) / _dot(normal, normal)
    if square < -1e-12:
        return []
    g = math.sqrt(max(square, 0.0))
    if g == 0.0:
        return [base]
    return [
        (base[0] + g * normal[0], base[1] + g * normal[1], base[2] + g * normal[2]),
        (base[0] - g * normal[0], base[1] - g * normal[1], base[2] - g * normal[2]),
    ]


@register
class RRPWrist(AnalyticFamily):
    """R, R, P and a spherical wrist (Stanford arm, jumbo drill), from the axes (any source).

    Solved in Python; robots built from standard DH rows that fit ``spherical_wrist``
    are solved by that compiled family first.
    """

    name = "rrp_wrist"
    modes = ("pose",)

    def fits(self, robot: Robot) -> bool:
        """Six uncoupled joints R, R, P, R, R, R with the structure of the module docstring."""
        return not robot.cached(wrist_plan).reason

    def explain(self, robot: Robot) -> str | None:
        """Why the joints do not have the structure, or ``None`` when they do."""
        return robot.cached(wrist_plan).reason or None

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to eight branches: four of the arm, two wrists each."""
        plan = robot.cached(wrist_plan)
        arm, z = plan.arm, plan.directions
        assert arm is not None and plan.wrist_end is not None
        x, y, w = placed_point(arm, T_0_target[:3].tolist())
        T_world = robot.T_world_base @ T_0_target @ robot.T_flange_tool
        # R1 R2 R4 R5 R6 (world), as rows of floats.
        r0, r1, r2 = (T_world[:3, :3] @ plan.wrist_end).tolist()
        R_goal: Mat = ((r0[0], r0[1], r0[2]), (r1[0], r1[1], r1[2]), (r2[0], r2[1], r2[2]))
        goal6_world = _apply(R_goal, z[5])
        goal_n_world = _apply(R_goal, plan.normal6)
        out = []
        for q1, q2, q3 in arm_branches(arm, x, y, w, q_ref):
            # R_wrist v = R2^T R1^T R_goal v: turn back about axis 1, then about axis 2.
            goal6 = _turn(z[1], -q2, _turn(z[0], -q1, goal6_world))
            goal_n = _turn(z[1], -q2, _turn(z[0], -q1, goal_n_world))
            for c in _two_rotations(z[3], z[4], z[5], goal6):
                q5 = _angle_about(z[4], z[5], c, float(q_ref[4]))
                q4 = _angle_about(z[3], c, goal6, float(q_ref[3]))
                # R6 n = R5^T R4^T R_wrist n
                seen = _turn(z[4], -q5, _turn(z[3], -q4, goal_n))
                q6 = _angle_about(z[5], plan.normal6, seen, 0.0)
                out.append(np.array([q1, q2, q3, q4, q5, q6]))
        return out
