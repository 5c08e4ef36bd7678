"""Six-joint arms with a spherical wrist: the 3+3 partition of seed 000, section IV.

Requirements (standard DH): joints 4-6 revolute with ``a4 = a5 = d5 = a6 = 0`` and
``alpha4, alpha5 = +-90 deg``, so axes 4, 5, 6 meet at the wrist centre ``W = o4``; and an
arm whose first twist is ``+-90 deg`` and that is either articulated (RRR with joints 2
and 3 parallel, e.g. the Puma 560) or spherical (RRP with ``alpha2 = +-90 deg``, e.g. the
Stanford arm and the jumbo drill).

1. ``W = p - d6 R (0, sin alpha6, cos alpha6)``: the wrist centre from the target.
2. Arm joints from ``W = A1 A2 A3 (0, 0, d4)``: one trig equation for ``q1``
   (``-s1 Wx + c1 Wy = -sin(alpha1) h``, where ``h`` is the arm's constant offset along
   joint 2's axis), then the planar distance gives ``q3`` (RRR, a trig equation) or the
   stroke (RRP, a square root), then ``q2`` by one atan2 difference.
3. Wrist joints from ``R_36 = R_03^T R``: ``cos q5`` from one entry, ``q4`` by atan2 of a
   column, ``q6`` by atan2 of the residual rotation ``(A4 A5)^T R_36``; at ``sin q5 = 0``
   only ``q4 + q6`` is defined and ``q4`` takes its reference value.

Up to 2 x 2 x 2 = 8 branches.
"""

from __future__ import annotations

import math

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import (
    AnalyticFamily,
    angles,
    dh_matrix,
    dh_rows,
    is_right_angle,
    register,
)
from optik.model import DHJoint, Robot
from optik.spatial import rot_x, rot_z

_EPS = 1e-12
_WRIST_SINGULAR = 1e-10


def _zero(*values: float) -> bool:
    return all(abs(v) < _EPS for v in values)


def _arm_kind(rows: tuple[DHJoint, ...]) -> str | None:
    r1, r2, r3 = rows[:3]
    if r1.kind != "revolute" or r2.kind != "revolute" or not is_right_angle(r1.alpha):
        return None
    if r3.kind == "revolute" and _zero(r2.alpha):
        return "rrr"
    if r3.kind == "prismatic" and is_right_angle(r2.alpha):
        return "rrp"
    return None


def _arm_solutions(rows: tuple[DHJoint, ...], W: FloatArray, q_ref: FloatArray) -> list[FloatArray]:
    """Joint values (q1, q2, q3) placing ``A1 A2 A3 (0, 0, d4)`` at ``W``."""
    r1, r2, r3, r4 = rows[:4]
    kind = _arm_kind(rows)
    sa1 = is_right_angle(r1.alpha)
    d4 = r4.d
    ca3, sa3 = math.cos(r3.alpha), math.sin(r3.alpha)
    wx, wy, wz = (float(v) for v in W)
    if kind == "rrr":
        a3, b3 = r3.a, -sa3 * d4
        h = r2.d + r3.d + ca3 * d4
    else:
        ct, st = math.cos(r3.theta), math.sin(r3.theta)
        ex, ey = ct * r3.a - st * (-sa3 * d4), st * r3.a + ct * (-sa3 * d4)
        sa2 = is_right_angle(r2.alpha)
        h = r2.d + sa2 * ey
    out = []
    for t1 in angles(wy, -wx, -sa1 * h, r1.theta + float(q_ref[0])):
        c1, s1 = math.cos(t1), math.sin(t1)
        vx = c1 * wx + s1 * wy - r1.a
        vy = sa1 * (wz - r1.d)
        rho2 = vx * vx + vy * vy
        if kind == "rrr":
            a2 = r2.a
            rhs = rho2 - a2 * a2 - a3 * a3 - b3 * b3
            for t3 in angles(2 * a2 * a3, -2 * a2 * b3, rhs, r3.theta + float(q_ref[2])):
                c3, s3 = math.cos(t3), math.sin(t3)
                ux, uy = a2 + a3 * c3 - b3 * s3, a3 * s3 + b3 * c3
                t2 = math.atan2(vy, vx) - math.atan2(uy, ux)
                out.append(np.array([t1 - r1.theta, t2 - r2.theta, t3 - r3.theta]))
        else:
            base = ex + r2.a
            radicand = rho2 - base * base
            if radicand < -1e-12 * max(rho2, 1.0):
                continue
            root = math.sqrt(max(radicand, 0.0))
            for L in {root, -root}:
                t2 = math.atan2(vy, vx) - math.atan2(-sa2 * L, base)
                d3 = L - ca3 * d4
                out.append(np.array([t1 - r1.theta, t2 - r2.theta, d3 - r3.d]))
    return out


def wrist_solutions(
    rows: tuple[DHJoint, ...], R_36: FloatArray, q_ref: FloatArray
) -> list[FloatArray]:
    """(q4, q5, q6) with ``A4 A5 A6`` rotating by ``R_36``."""
    r4, r5, r6 = rows[3:6]
    sa4, sa5 = is_right_angle(r4.alpha), is_right_angle(r5.alpha)
    M = R_36 @ rot_x(r6.alpha).T
    c5 = -sa4 * sa5 * float(M[2, 2])
    s5_mag = math.hypot(float(M[0, 2]), float(M[1, 2]))
    out = []
    if s5_mag < _WRIST_SINGULAR:
        t5 = math.atan2(0.0, c5)
        t4 = r4.theta + float(q_ref[3])
        N = (rot_z(t4) @ rot_x(r4.alpha) @ rot_z(t5) @ rot_x(r5.alpha)).T @ M
        t6 = math.atan2(float(N[1, 0]), float(N[0, 0]))
        out.append(np.array([t4 - r4.theta, t5 - r5.theta, t6 - r6.theta]))
        return out
    for sign in (1.0, -1.0):
        t5 = math.atan2(sign * s5_mag, c5)
        t4 = math.atan2(sa5 * sign * float(M[1, 2]), sa5 * sign * float(M[0, 2]))
        # q6 from the residual rotation given q4 and q5, not from M's row alone: near the
        # singularity q4 carries an error of eps / sin(q5), and this q6 absorbs it exactly.
        N = (rot_z(t4) @ rot_x(r4.alpha) @ rot_z(t5) @ rot_x(r5.alpha)).T @ M
        t6 = math.atan2(float(N[1, 0]), float(N[0, 0]))
        out.append(np.array([t4 - r4.theta, t5 - r5.theta, t6 - r6.theta]))
    return out


@register
class SphericalWrist(AnalyticFamily):
    """6-dof arms (RRR or RRP arm) with a spherical wrist, by the 3+3 partition."""

    name = "spherical_wrist"
    modes = ("pose",)

    def fits(self, robot: Robot) -> bool:
        """See the module docstring for the structure required."""
        rows = dh_rows(robot)
        if robot.convention != "dh" or robot.dof != 6 or len(rows) != 6:
            return False
        if any(r.mimic is not None for r in rows):
            return False
        r4, r5, r6 = rows[3:]
        return (
            all(r.kind == "revolute" for r in rows[3:])
            and _zero(r4.a, r5.a, r5.d, r6.a)
            and bool(is_right_angle(r4.alpha))
            and bool(is_right_angle(r5.alpha))
            and _arm_kind(rows) is not None
        )

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to eight branches: two shoulders x two elbows x two wrists."""
        rows = dh_rows(robot)
        R = T_0_target[:3, :3]
        a6 = rows[5].alpha
        W = T_0_target[:3, 3] - rows[5].d * (R @ np.array([0.0, math.sin(a6), math.cos(a6)]))
        out = []
        for arm in _arm_solutions(rows, W, q_ref):
            T_03 = (
                dh_matrix(rows[0], arm[0]) @ dh_matrix(rows[1], arm[1]) @ dh_matrix(rows[2], arm[2])
            )
            for wrist in wrist_solutions(rows, T_03[:3, :3].T @ R, q_ref):
                out.append(np.concatenate([arm, wrist]))
        return out
