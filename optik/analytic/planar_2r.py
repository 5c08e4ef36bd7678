"""Two parallel revolute axes (seed 003's planar arm): both elbow branches, from the axes.

Found from the joint axes at ``q = 0`` (:func:`optik.analytic.geometry.joint_axes`), so
an arm loaded from URDF, modified DH or standard DH fits alike: two revolute joints
without coupling whose axes are parallel (within :data:`~optik.analytic.geometry.ANGLE_TOL`)
and distinct (more than ``LENGTH_TOL`` times the arm's size apart). The tool point then
moves in a plane perpendicular to the axes. With ``z`` the direction of axis 1, ``A`` the
in-plane vector from axis 1 to axis 2, ``B`` the in-plane vector from axis 2 to the tool
point at ``q = 0`` and ``X`` the target's in-plane offset from axis 1,
``X = R(q1) (A + R(s q2) B)`` (``R`` turns about ``z``; ``s = +-1`` when axis 2 is
written the same way or the other way), so with ``phi = s q2``::

    |X|^2 = |A|^2 + |B|^2 + 2 (A . B) cos phi - 2 z . (A x B) sin phi

the trig equation ``a cos phi + b sin phi = c`` (two elbow branches), and ``q1`` is the
angle about ``z`` from ``V = A + R(phi) B`` to ``X`` (free, kept at its reference, when the
arm folds onto axis 1). For the DH arm of seed 003 (``A = (a1, 0, 0)``,
``B = (a2, 0, 0)``) this is ``(2 a1 a2) cos q2 = x^2 + y^2 - a1^2 - a2^2`` and
``q1 = atan2(y, x) - atan2(a2 sin q2, a1 + a2 cos q2)``.

In pose mode the orientation gives the tool's turn about the axes, ``q1 + s q2``, and
``q1 = turn - phi``: the orientation exact, and ``q1`` right where the position leaves it
free (the arm folded onto axis 1) or loses its digits (a hair from folded or stretched);
with the tool point on axis 2, ``phi = turn - q1`` instead (the position leaves ``q2``
free). The target's offset along the axes is checked by the caller's FK: a target off
the plane gets no branch.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import PlannedFamily, angles, flange_point, flange_turn, register
from optik.analytic.geometry import ANGLE_TOL, LENGTH_TOL, joint_axes, revolute_chain_reason
from optik.model import Robot


class PlanarPlan(NamedTuple):
    """The plane of a two-joint arm, from its axes at ``q = 0``, in the robot's frame 0.

    Coordinates in the plane are along ``e1`` (towards axis 2) and ``e2 = z x e1``, with
    ``z`` the direction of axis 1 and the origin on axis 1; frame 0 is the world frame
    with the robot's base transform removed (where :meth:`Planar2R.candidates` gets its
    targets). Plain floats: the closed form runs on them without numpy.

    Attributes:
        reason: ``""`` when the axes are parallel and distinct, else why not (one line).
        sense: +1 or -1: axis 2's direction is ``sense * z``.
        e1: the first in-plane direction (3 floats, frame 0).
        e2: the second (3 floats).
        offset: the in-plane coordinates of axis 1 (2 floats, m).
        A: the in-plane vector from axis 1 to axis 2 (2 floats, m): ``(|A|, 0)``.
        B: the in-plane vector from axis 2 to the tool point at ``q = 0`` (2 floats, m).
        tool: the tool point in the flange frame (3 floats, m): the tool's offset.
        trig: ``(2 A.B, -2 z.(A x B), |A|^2 + |B|^2)``: the trig equation's coefficients
            and the constant of its right-hand side.
        folded: ``|X|`` (m) at or below which the arm is folded onto axis 1.
        flange_e1: the vector (flange frame) that the target's flange rotation turns
            into ``R(q1 + s q2) e1`` (3 floats): the tool's turn about the axes.
        tool_on_axis2: the tool point lies on axis 2 (``B = 0``): only the orientation
            sets joint 2.
    """

    reason: str
    sense: float = 1.0
    e1: tuple[float, float, float] = (1.0, 0.0, 0.0)
    e2: tuple[float, float, float] = (0.0, 1.0, 0.0)
    offset: tuple[float, float] = (0.0, 0.0)
    A: tuple[float, float] = (0.0, 0.0)
    B: tuple[float, float] = (0.0, 0.0)
    tool: tuple[float, float, float] = (0.0, 0.0, 0.0)
    trig: tuple[float, float, float] = (0.0, 0.0, 0.0)
    folded: float = 0.0
    flange_e1: tuple[float, float, float] = (1.0, 0.0, 0.0)
    tool_on_axis2: bool = False


def planar_plan(robot: Robot) -> PlanarPlan:
    """The plane and in-plane vectors of a two-revolute-joint arm, or why it has none."""
    reason = revolute_chain_reason(robot, 2)
    if reason is not None:
        return PlanarPlan(reason)
    axes = joint_axes(robot)
    z, z2 = axes.directions
    tilt = float(np.linalg.norm(np.cross(z, z2)))
    if tilt > ANGLE_TOL:
        degrees = math.degrees(math.asin(min(tilt, 1.0)))
        return PlanarPlan(f"axes 1 and 2 are not parallel ({degrees:.6g} deg)")
    between = axes.points[1] - axes.points[0]
    A = between - (between @ z) * z
    length = float(np.linalg.norm(A))
    if length <= LENGTH_TOL * axes.size:
        return PlanarPlan("axes 1 and 2 coincide")
    e1 = A / length
    e2 = np.cross(z, e1)
    B = axes.tool[:3, 3] - axes.points[1]
    # Into frame 0: directions turn by the base's rotation, the origin also moves.
    base = robot.T_world_base
    to_0 = base[:3, :3].T
    e1_0, e2_0 = to_0 @ e1, to_0 @ e2
    origin_0 = to_0 @ (axes.points[0] - base[:3, 3])
    tool = robot.T_flange_tool[:3, 3]
    bx, by = float(B @ e1), float(B @ e2)
    # R_f R_ft = R(q1 + s q2) R_tool(0) in frame 0, so R_f (R_ft R_tool(0)^T e1) turns e1.
    flange_e1 = robot.T_flange_tool[:3, :3] @ (to_0 @ axes.tool[:3, :3]).T @ e1_0
    return PlanarPlan(
        "",
        1.0 if float(z @ z2) > 0.0 else -1.0,
        (float(e1_0[0]), float(e1_0[1]), float(e1_0[2])),
        (float(e2_0[0]), float(e2_0[1]), float(e2_0[2])),
        (float(e1_0 @ origin_0), float(e2_0 @ origin_0)),
        (length, 0.0),
        (bx, by),
        (float(tool[0]), float(tool[1]), float(tool[2])),
        (2.0 * length * bx, -2.0 * length * by, length * length + bx * bx + by * by),
        1e-12 * max(length, math.hypot(bx, by), 1.0),
        (float(flange_e1[0]), float(flange_e1[1]), float(flange_e1[2])),
        math.hypot(bx, by) <= 1e-12 * max(length, 1.0),
    )


@register
class Planar2R(PlannedFamily):
    """Two revolute joints with parallel, distinct axes (any source: DH, modified DH, URDF)."""

    name = "planar_2r"
    modes = ("position", "pose")
    tool_point = True
    plan = staticmethod(planar_plan)

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Both elbow branches (in pose mode with the orientation's turn); checked by FK."""
        plan = robot.cached(planar_plan)
        # The tool point in frame 0 (the flange target carries the tool's offset).
        rows = T_0_target[:3].tolist()
        px, py, pz = flange_point(rows, plan.tool)
        e1, e2 = plan.e1, plan.e2
        x = e1[0] * px + e1[1] * py + e1[2] * pz - plan.offset[0]
        y = e2[0] * px + e2[1] * py + e2[2] * pz - plan.offset[1]
        ax = plan.A[0]
        bx, by = plan.B
        a, b, c0 = plan.trig
        folded = math.hypot(x, y) <= plan.folded
        s = plan.sense
        if mode == "pose":
            # The tool's turn about the axes, q1 + s q2, from the orientation: it sets the
            # joint the position leaves free or ill-conditioned (folded, or the tool on
            # axis 2) and keeps both branches' orientation exact.
            g0, g1, g2 = flange_turn(rows, plan.flange_e1)
            turn = math.atan2(
                e2[0] * g0 + e2[1] * g1 + e2[2] * g2, e1[0] * g0 + e1[1] * g1 + e1[2] * g2
            )
        out = []
        for phi in angles(a, b, x * x + y * y - c0, s * float(q_ref[1])):
            if folded:
                # Folded onto axis 1 (|A| = |B|): every angle of joint 1 works.
                q1 = float(q_ref[0])
            else:
                cos_phi, sin_phi = math.cos(phi), math.sin(phi)
                vx = ax + cos_phi * bx - sin_phi * by
                vy = sin_phi * bx + cos_phi * by
                q1 = math.atan2(vx * y - vy * x, vx * x + vy * y)
            if mode == "pose":
                if plan.tool_on_axis2:
                    phi = turn - q1
                else:
                    q1 = turn - phi
            out.append(np.array([q1, s * phi]))
        return out
