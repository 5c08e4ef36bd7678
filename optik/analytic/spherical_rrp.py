"""Revolute, revolute, prismatic arms (seed 000's jumbo boom), from the joint axes.

Found from the joint axes at ``q = 0`` (:func:`optik.analytic.geometry.joint_axes`), so
an arm loaded from URDF, modified DH or standard DH fits alike: three joints without
coupling, revolute, revolute, prismatic, with axis 2 not parallel to axis 1 and the
prismatic direction ``u`` perpendicular to axis 2 (both within
:data:`~optik.analytic.geometry.ANGLE_TOL`). Axes 1 and 2 may meet or be skew, at any
angle; the tool point may sit anywhere.

Turning about axis 2 and sliding along ``u`` keep the tool point's height along axis 2,
``h2 = z2 . (P0 - p1)`` (``P0`` the tool point at ``q = 0``, ``p1`` a point on axis 1), so
the first joint must bring axis 2 to the height of the target ``x``:
``(R1(q1) z2) . (x - p1) = h2``, a trig equation ``a cos q1 + b sin q1 = c`` (two
branches; ``q1`` free, at its reference, for a target on axis 1). With ``x`` turned back,
``y = R1(q1)^-1 (x - p1) + p1``, the rest is planar, in the plane of axis 2's normal
through ``y``: in coordinates along ``u`` and ``n = z2 x u`` about axis 2's point ``p2``,
the tool's line is ``(s0 + q3, h)`` (``s0, h`` those of ``P0 - p2``), and it must turn onto
``Y`` (those of ``y - p2``): ``s = +-sqrt(|Y|^2 - h^2)`` (two branches), ``q3 = s - s0`` and
``q2`` the angle from ``(s, h)`` to ``Y``: up to four branches, two of them usually with the
boom retracted through its pivot, outside the limits.

Seed 000's arm (``0A1 = DH(q1, 0, a1, +90)``, ``1A2 = DH(q2, 0, 0, -90)``,
``2A3 = DH(0, d3, 0, +90)``, see docs/errata.md) has axis 1 vertical, axis 2 horizontal
at the distance ``a1`` and the boom through axis 2 (``h = 0``): its position branches
are the seed's eq. 27, 33 and 34, ``s1 px - c1 py = 0``,
``s2 pz + (c1 px + s1 py - a1) c2 = 0``, ``d3 = (a1 - c1 px - s1 py) s2 + pz c2``; in pose
mode the caller's FK keeps the one of the target's orientation (the corrected eq. 35-42).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import PlannedFamily, angles, flange_point, flange_turn, register
from optik.analytic.geometry import ANGLE_TOL, Axes, joint_axes, joint_kinds_reason
from optik.model import Robot

Vector = tuple[float, float, float]


class RRPPlan(NamedTuple):
    """An RRP arm's axes at ``q = 0`` in a frame on axis 1 (``z`` along it, origin on it).

    ``to_axis`` maps a point of the robot's frame 0 (the world frame with the base
    transform removed, where :meth:`SphericalRRP.candidates` gets its targets) into that
    frame. Plain floats: the closed form runs on them without numpy.

    Attributes:
        reason: ``""`` when the joints have the structure, else why not (one line).
        to_axis: rows of the rotation, then the offset (12 floats): ``x' = R x + t``.
        z2: axis 2's direction (3 floats, axis-1 frame).
        height: ``z2 . (P0 - p1)``, the height (m) the first joint must match (``P0``:
            the placed point at ``q = 0``, the tool point or a wrist centre, :func:`arm_plan`).
        p2: a point on axis 2 (3 floats, m).
        u: the prismatic direction (3 floats).
        n: ``z2 x u`` (3 floats).
        s0: the placed point's coordinate along ``u`` from ``p2`` at ``q = 0`` (m).
        h: its coordinate along ``n`` (m).
        tool: the placed point in the flange frame (3 floats, m).
        flange_z2: the vector (flange frame) that the tool's orientation turns into
            ``R1(q1) z2`` (3 floats): ``z2`` seen from the tool at ``q = 0``.
        flange_u: the same for ``u``, which it turns into ``R1(q1) R2(q2) u``.
    """

    reason: str
    to_axis: tuple[float, ...] = ()
    z2: Vector = (0.0, 0.0, 1.0)
    height: float = 0.0
    p2: Vector = (0.0, 0.0, 0.0)
    u: Vector = (1.0, 0.0, 0.0)
    n: Vector = (0.0, 1.0, 0.0)
    s0: float = 0.0
    h: float = 0.0
    tool: Vector = (0.0, 0.0, 0.0)
    flange_z2: Vector = (0.0, 0.0, 1.0)
    flange_u: Vector = (1.0, 0.0, 0.0)


def _floats(v: FloatArray) -> Vector:
    return float(v[0]), float(v[1]), float(v[2])


def rrp_plan(robot: Robot) -> RRPPlan:
    """The axes of an RRP arm in a frame on axis 1, or why it does not fit the family."""
    reason = joint_kinds_reason(robot, "RRP")
    if reason is not None:
        return RRPPlan(reason)
    axes = joint_axes(robot)
    return arm_plan(robot, axes, axes.tool[:3, 3])


def arm_plan(robot: Robot, axes: Axes, point: FloatArray) -> RRPPlan:
    """The plan that places ``point`` (world, at ``q = 0``) with joints 1 to 3 (R, R, P).

    ``point`` moves with joints 1 to 3 only: the tool point of a three-joint arm, or the
    centre of a spherical wrist (:mod:`optik.analytic.rrp_wrist`). Its place in the
    flange frame goes into ``tool``, so the target's flange pose places it.
    """
    z1, z2, u = axes.directions[:3]
    p1, p2 = axes.points[0], axes.points[1]
    if float(np.linalg.norm(np.cross(z1, z2))) <= ANGLE_TOL:
        return RRPPlan("axes 1 and 2 are parallel: the first joint cannot set the height")
    off = float(u @ z2)
    if abs(off) > ANGLE_TOL:
        degrees = math.degrees(math.asin(min(abs(off), 1.0)))
        return RRPPlan(f"the prismatic direction is {degrees:.6g} deg off the normal of axis 2")
    # A frame with z on axis 1 and its origin at p1, expressed from frame 0.
    x_axis = np.cross(z1, z2)
    x_axis /= np.linalg.norm(x_axis)
    R_world = np.stack([x_axis, np.cross(z1, x_axis), z1])  # rows: world -> axis frame
    base = robot.T_world_base
    R = R_world @ base[:3, :3]  # frame 0 -> axis frame
    t = R_world @ (base[:3, 3] - p1)

    def into(v: FloatArray) -> FloatArray:
        return np.asarray(R_world @ v, dtype=np.float64)

    z2_a, u_a, p2_a = into(z2), into(u), into(p2 - p1)
    n_a = np.cross(z2_a, u_a)
    w = into(point - p2)
    # R(q) = R1 R2 R(0) (world) for the three joints, so R(q) R(0)^T z2 = R1 z2 and
    # R(q) R(0)^T u = R1 R2 u; the flange's rotation is R(q) times the tool's inverse.
    to_flange = robot.T_flange_tool[:3, :3] @ axes.tool[:3, :3].T
    in_flange = robot.T_flange_tool @ np.linalg.inv(axes.tool) @ np.append(point, 1.0)
    return RRPPlan(
        "",
        tuple(float(v) for v in [*R.ravel(), *t]),
        _floats(z2_a),
        float(z2 @ (point - p1)),
        _floats(p2_a),
        _floats(u_a),
        _floats(n_a),
        float(w @ u_a),
        float(w @ n_a),
        _floats(in_flange),
        _floats(to_flange @ z2),
        _floats(to_flange @ u),
    )


def placed_point(plan: RRPPlan, rows: list[list[float]]) -> tuple[float, float, float]:
    """The point the plan places, in the axis-1 frame, for a flange target's ``rows``.

    ``rows``: the first three rows of the flange target in frame 0 (``T[:3].tolist()``).
    """
    px, py, pz = flange_point(rows, plan.tool)
    r = plan.to_axis
    return (
        r[0] * px + r[1] * py + r[2] * pz + r[9],
        r[3] * px + r[4] * py + r[5] * pz + r[10],
        r[6] * px + r[7] * py + r[8] * pz + r[11],
    )


def arm_branches(
    plan: RRPPlan, x: float, y: float, z: float, q_ref: FloatArray
) -> list[tuple[float, float, float]]:
    """Up to four ``(q1, q2, q3)`` placing the plan's point at ``(x, y, z)`` (axis-1 frame).

    ``q_ref`` (at least 2 entries) gives the free joints' values at singularities.
    """
    zx, zy, zz = plan.z2
    p2x, p2y, p2z = plan.p2
    ux, uy, uz = plan.u
    nx, ny, nz = plan.n
    h = plan.h
    out = []
    # (R1 z2) . x = c (zx x + zy y) + s (zx y - zy x) + zz z = height
    for q1 in angles(zx * x + zy * y, zx * y - zy * x, plan.height - zz * z, float(q_ref[0])):
        c1, s1 = math.cos(q1), math.sin(q1)
        # The target turned back by q1 about axis 1, from axis 2's point.
        dx = c1 * x + s1 * y - p2x
        dy = -s1 * x + c1 * y - p2y
        dz = z - p2z
        yu = ux * dx + uy * dy + uz * dz
        yn = nx * dx + ny * dy + nz * dz
        # s^2 = |Y|^2 - h^2, formed as a product so that a tangent keeps its digits.
        r = math.hypot(yu, yn)
        disc = (r - abs(h)) * (r + abs(h))
        if disc < -1e-12 * max(r * r, 1.0):
            continue
        root = math.sqrt(max(disc, 0.0))
        for s in (root, -root) if root > 0.0 else (0.0,):
            if abs(s) + abs(h) <= 1e-12 * max(r, 1.0):
                # The line passes through axis 2 at the target: q2 is free.
                q2 = float(q_ref[1])
            else:
                q2 = math.atan2(s * yn - h * yu, s * yu + h * yn)
            out.append((q1, q2, s - plan.s0))
    return out


def _flange_vector(plan: RRPPlan, rows: list[list[float]], m: Vector) -> Vector:
    """``m`` (flange frame) turned by the flange target's rotation, in the axis-1 frame.

    ``rows``: the flange target's first three rows (frame 0).
    """
    a0, a1, a2 = flange_turn(rows, m)
    r = plan.to_axis
    return (
        r[0] * a0 + r[1] * a1 + r[2] * a2,
        r[3] * a0 + r[4] * a1 + r[5] * a2,
        r[6] * a0 + r[7] * a1 + r[8] * a2,
    )


@register
class SphericalRRP(PlannedFamily):
    """Revolute, revolute, prismatic (seed 000's boom), from the axes (any source).

    Axes 1 and 2 not parallel, the slide normal to axis 2 (module docstring).
    """

    name = "spherical_rrp"
    modes = ("position", "pose")
    tool_point = True
    plan = staticmethod(rrp_plan)

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to four position branches; the orientation is checked by the caller's FK."""
        plan = robot.cached(rrp_plan)
        rows = T_0_target[:3].tolist()
        x, y, z = placed_point(plan, rows)
        if mode == "pose":
            return [self._pose_branch(plan, rows, x, y, z)]
        return [np.array(q) for q in arm_branches(plan, x, y, z, q_ref)]

    @staticmethod
    def _pose_branch(
        plan: RRPPlan, rows: list[list[float]], x: float, y: float, z: float
    ) -> FloatArray:
        """The one branch of a pose (seed 000's eq. 35-42, from the axes).

        ``q1`` from where the orientation takes axis 2, ``q2`` from where it takes ``u``,
        ``q3`` from the position (``x, y, z``: the tool point in the axis-1 frame);
        ``rows``: the flange target's first three rows (frame 0).
        """
        gx, gy, _ = _flange_vector(plan, rows, plan.flange_z2)
        wx, wy, wz = _flange_vector(plan, rows, plan.flange_u)
        zx, zy, _ = plan.z2
        q1 = math.atan2(zx * gy - zy * gx, zx * gx + zy * gy)
        c1, s1 = math.cos(q1), math.sin(q1)
        vx, vy = c1 * wx + s1 * wy, -s1 * wx + c1 * wy
        ux, uy, uz = plan.u
        nx, ny, nz = plan.n
        q2 = math.atan2(nx * vx + ny * vy + nz * wz, ux * vx + uy * vy + uz * wz)
        p2x, p2y, p2z = plan.p2
        dx = c1 * x + s1 * y - p2x
        dy = -s1 * x + c1 * y - p2y
        dz = z - p2z
        yu = ux * dx + uy * dy + uz * dz
        yn = nx * dx + ny * dy + nz * dz
        s = math.cos(q2) * yu + math.sin(q2) * yn
        return np.array([q1, q2, s - plan.s0])
