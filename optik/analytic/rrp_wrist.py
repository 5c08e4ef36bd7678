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
is solved by the compiled wrist of the joint-axis families
(:func:`optik.analytic.pair_wrist.wrist_branches`: Paden-Kahan subproblem 2 on axis 6's
direction, then subproblem 1 for the last angle, joint 4 at its reference where axes 4
and 6 align): up to eight branches.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import PlannedFamily, register
from optik.analytic._compiled import MAX_BRANCHES, mul3, tolerance_block
from optik.analytic._subproblems import rotation
from optik.analytic.geometry import (
    ANGLE_TOL,
    LENGTH_TOL,
    joint_axes,
    joint_kinds_reason,
    point_line_distance,
    wrist_centre,
)
from optik.analytic.pair_wrist import wrist_across, wrist_branches
from optik.analytic.spherical_rrp import RRPPlan, arm_branches, arm_plan, placed_point
from optik.errors import AnalyticIKError
from optik.model import Robot


class WristPlan(NamedTuple):
    """An RRP arm with a spherical wrist, from its axes at ``q = 0`` (world frame).

    Attributes:
        reason: ``""`` when the joints have the structure, else why not (one line).
        arm: the plan placing the wrist centre with joints 1 to 3.
        directions: (6, 3) the joints' unit directions, as the compiled wrist takes them.
        base: (3, 3) the base transform's rotation (frame 0 to world).
        flange_end: (3, 3) ``R_ft M_R^T``: the flange's rotation times it is the world
            rotation ``R1 R2 R4 R5 R6`` of the joints (``R_ft`` the tool's rotation,
            ``M_R`` the tool's at ``q = 0``) once the base's rotation is applied.
        across: a unit direction across axis 6 (3 floats, for the last angle).
    """

    reason: str
    arm: RRPPlan | None = None
    directions: FloatArray | None = None
    base: FloatArray | None = None
    flange_end: FloatArray | None = None
    across: tuple[float, float, float] = (1.0, 0.0, 0.0)


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
    # Where axes 4 and 5 meet (best); axis 6 must pass through it too.
    centre = axes.tool[:3, :3] @ wrist_centre(axes) + axes.tool[:3, 3]
    tol = LENGTH_TOL * axes.size
    for i in (3, 4, 5):
        miss = point_line_distance(z[i], p[i], centre)
        if miss > tol:
            return WristPlan(f"axis {i + 1} misses the wrist centre by {miss:.3g} m")
    arm = arm_plan(robot, axes, centre)
    if arm.reason:
        return WristPlan(arm.reason)
    directions = np.ascontiguousarray(z, dtype=np.float64)
    flange_end = robot.T_flange_tool[:3, :3] @ axes.tool[:3, :3].T
    across = wrist_across(directions)
    return WristPlan(
        "",
        arm,
        directions,
        robot.T_world_base[:3, :3].copy(),
        np.ascontiguousarray(flange_end),
        (float(across[0]), float(across[1]), float(across[2])),
    )


@register
class RRPWrist(PlannedFamily):
    """R, R, P and a spherical wrist (Stanford arm, jumbo drill), from the axes (any source).

    The arm in Python, the wrist by the compiled wrist of the joint-axis families
    (:func:`optik.analytic.pair_wrist.wrist_branches`); robots built from standard DH
    rows that fit ``spherical_wrist`` are solved by that compiled family first. Fits six
    uncoupled joints R, R, P, R, R, R with the structure of the module docstring
    (:func:`wrist_plan`).
    """

    name = "rrp_wrist"
    modes = ("pose",)
    plan = staticmethod(wrist_plan)

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to eight branches: four of the arm, two wrists each.

        Raises:
            AnalyticIKError: ``robot`` does not fit the family (the reason).
        """
        plan = robot.cached(wrist_plan)
        arm, z, base, flange_end = plan.arm, plan.directions, plan.base, plan.flange_end
        if arm is None or z is None or base is None or flange_end is None:
            raise AnalyticIKError(f"robot {robot.name!r} does not fit rrp_wrist: {plan.reason}")
        x, y, w = placed_point(arm, T_0_target[:3].tolist())
        # R1 R2 R4 R5 R6 (world), row-major.
        RG = tuple((base @ T_0_target[:3, :3] @ flange_end).ravel().tolist())
        ref = np.ascontiguousarray(q_ref, dtype=np.float64)
        tols = _tolerances()
        cand = np.empty((MAX_BRANCHES, 6))
        n = 0
        for q1, q2, q3 in arm_branches(arm, x, y, w, ref):
            R12 = mul3(rotation(_vec(z[0]), q1), rotation(_vec(z[1]), q2))
            n = wrist_branches(z, RG, R12, (q1, q2, q3), plan.across, ref, tols, cand, n)
        return [cand[i].copy() for i in range(n)]


def _vec(row: FloatArray) -> tuple[float, float, float]:
    return float(row[0]), float(row[1]), float(row[2])


@functools.cache
def _tolerances() -> FloatArray:
    """The compiled closed forms' tolerance block (read-only, built once)."""
    tols = tolerance_block()
    tols.flags.writeable = False
    return tols
