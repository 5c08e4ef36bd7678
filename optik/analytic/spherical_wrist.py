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

Up to 2 x 2 x 2 = 8 branches, in this order: shoulder (the two roots of the ``q1``
equation, ascending), elbow (``q3`` roots ascending; for RRP the stroke root ``+L`` then
``-L``), wrist (``sin q5 >= 0`` first).

Robots built otherwise (URDF, modified DH) or whose table differs fit when their joint
axes do (revolute joints only): axes 4, 5 and 6 meet in one point with axis 5
perpendicular to axes 4 and 6, axis 2 perpendicular to axis 1, and axes 2 and 3 parallel
with the same direction. The equivalent table of :mod:`optik.analytic.geometry` then
carries the closed form.

The closed form is compiled: :func:`spherical_wrist_candidates` is its one
implementation, and :func:`optik.analytic.analytic_ik` runs it together with the wrapping,
limit filter and FK check in one compiled call (:mod:`optik.analytic._pipeline`).
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import atan2, sincos, trig_roots, wrap_angle
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic import _compiled
from optik.analytic._base import ELBOW_REACH_TOL, deg, is_right_angle, opposite, register
from optik.analytic._compiled import (
    CompiledFamily,
    closed_form_tols,
    cos_sin,
    dh_rot,
    dh_rotation,
    dh_row,
    mul3,
    mul3tn,
    store_branch,
)
from optik.analytic._subproblems import elbow_roots
from optik.model import DHJoint

_EPS = 1e-12
_RADICAND_TOL = 1e-12  # RRP arm: a negative radicand above -tol * max(rho^2, 1) is 0


def _zero(*values: float) -> bool:
    return all(abs(v) < _EPS for v in values)


def _arm_reason(rows: tuple[DHJoint, ...]) -> str | None:
    """Why the first three rows are neither an RRR (articulated) nor an RRP arm."""
    r1, r2, r3 = rows[:3]
    if r1.kind != "revolute" or r2.kind != "revolute":
        return "joints 1 and 2 must be revolute"
    if not is_right_angle(r1.alpha):
        return f"alpha1 = {deg(r1.alpha)}, needs +-90 deg (axes 1 and 2 perpendicular)"
    if r3.kind == "revolute" and not _zero(r2.alpha):
        return (
            f"alpha2 = {deg(r2.alpha)}, needs 0 (axes 2 and 3 parallel, same direction)"
            f"{opposite(r2.alpha)}"
        )
    if r3.kind == "prismatic" and not is_right_angle(r2.alpha):
        return f"alpha2 = {deg(r2.alpha)}, needs +-90 deg (joint 3 sliding across axis 2)"
    return None


def rows_reason(rows: tuple[DHJoint, ...]) -> str | None:
    """Why a DH table has no spherical wrist of this family, or ``None`` when it has."""
    if len(rows) != 6:
        return f"{len(rows)} DH rows (the family takes 6)"
    if any(r.mimic is not None for r in rows):
        return "coupled (mimic) joints"
    r4, r5, r6 = rows[3:]
    if not all(r.kind == "revolute" for r in rows[3:]):
        return "joints 4 to 6 must be revolute"
    if not _zero(r4.a):
        return f"a4 = {r4.a:.6g} m: axes 4 and 5 do not intersect"
    if not _zero(r5.a, r5.d):
        return f"a5 = {r5.a:.6g} m, d5 = {r5.d:.6g} m: axis 6 misses the point of axes 4, 5"
    if not _zero(r6.a):
        return f"a6 = {r6.a:.6g} m, needs 0"
    if not is_right_angle(r4.alpha):
        return f"alpha4 = {deg(r4.alpha)}, needs +-90 deg (axes 4 and 5 perpendicular)"
    if not is_right_angle(r5.alpha):
        return f"alpha5 = {deg(r5.alpha)}, needs +-90 deg (axes 5 and 6 perpendicular)"
    return _arm_reason(rows)


# ---------------------------------------------------------------------- the compiled closed form
@_jit
def _sw_wrist(
    dh: np.ndarray,
    R36: tuple[float, float, float, float, float, float, float, float, float],
    ref: np.ndarray,
    kr: int,
    arm0: float,
    arm1: float,
    arm2: float,
    wrist_tol: float,
    cand: np.ndarray,
    n: int,
) -> int:
    """Append the wrist branches (q4, q5, q6) of ``A4 A5 A6 = R36`` after the arm values.

    Writes rows ``n, n + 1`` of ``cand`` and returns the new row count. At the wrist
    singularity (``|sin q5| < wrist_tol``) only ``q4 +- q6`` is defined: the first row
    keeps ``q4`` at its reference, the second is the split nearest the reference
    (``q4`` and ``q6`` each off theirs by half the excess; the same row when the
    reference fits both). When neither row is inside narrow limits that the singular
    set still enters, ``analytic_ik`` polishes them into the limits
    (``optik.analytic._degenerate``).
    """
    _, _, _, th4, _, ca4, sa4, s4 = dh_row(dh, 3)
    _, _, _, th5, _, ca5, sa5, s5 = dh_row(dh, 4)
    _, _, _, th6, _, ca6, sa6, _ = dh_row(dh, 5)
    # M = R36 Rx(alpha6)^T
    M = mul3(R36, (1.0, 0.0, 0.0, 0.0, ca6, sa6, 0.0, -sa6, ca6))
    c5 = -s4 * s5 * M[8]
    s5_mag = math.sqrt(M[2] * M[2] + M[5] * M[5])
    singular = s5_mag < wrist_tol
    t6 = 0.0
    for b in range(2):
        if singular:
            t5 = atan2(0.0, c5)
            sn5t, c5t = sincos(t5)
            t4 = th4 + ref[kr, 3]
            if b == 1:
                # q6 (the first row's t6) moves against (or with) q4 along the singular
                # set, measured by one turn of q4; both take half its excess over its
                # reference.
                excess = wrap_angle(t6 - th6 - ref[kr, 5])
                if abs(excess) < wrist_tol:
                    break  # the reference fits both: one row
                sb, cb = sincos(t4 + 1.0)
                turned = _sw_q6(M, cb, sb, c5t, sn5t, ca4, sa4, ca5, sa5)
                against = -1.0 if wrap_angle(turned - t6) < 0.0 else 1.0
                t4 = t4 - against * 0.5 * excess
            sn4, c4 = sincos(t4)
        else:
            sign = 1.0 if b == 0 else -1.0
            t5 = atan2(sign * s5_mag, c5)
            t4 = atan2(s5 * sign * M[5], s5 * sign * M[2])
            c4, sn4 = cos_sin(t4, t4, s5 * sign * M[2], s5 * sign * M[5])
            c5t, sn5t = cos_sin(t5, t5, c5, sign * s5_mag)
        t6 = _sw_q6(M, c4, sn4, c5t, sn5t, ca4, sa4, ca5, sa5)
        n = store_branch(cand, n, (arm0, arm1, arm2, t4 - th4, t5 - th5, t6 - th6))
    return n


@_inline
def _sw_q6(
    M: tuple[float, float, float, float, float, float, float, float, float],
    c4: float,
    sn4: float,
    c5t: float,
    sn5t: float,
    ca4: float,
    sa4: float,
    ca5: float,
    sa5: float,
) -> float:
    """``theta6`` (rad) from the residual rotation ``N = (A4 A5)^T M`` given q4 and q5.

    Not from ``M``'s row alone: near the singularity q4 carries an error of
    ``eps / sin(q5)``, which this q6 absorbs exactly.
    """
    P = mul3(dh_rot(c4, sn4, ca4, sa4), dh_rot(c5t, sn5t, ca5, sa5))
    n00 = P[0] * M[0] + P[3] * M[3] + P[6] * M[6]
    n10 = P[1] * M[0] + P[4] * M[3] + P[7] * M[6]
    return atan2(n10, n00)


@_jit
def spherical_wrist_candidates(
    dh: np.ndarray, T: np.ndarray, ref: np.ndarray, kr: int, tols: np.ndarray, cand: np.ndarray
) -> int:
    """Raw branches of the 3+3 partition (RRR or RRP arm, spherical wrist) into ``cand``.

    A family kernel (:data:`optik.analytic._compiled.CandidateKernel`): up to 8 rows, in
    the family's order: shoulder, then elbow (or stroke sign), then wrist (``sin q5 >= 0``
    first). Joint values in rad, and m for a prismatic joint 3.
    """
    trig_tol, eps, free_tol, wrist_tol = closed_form_tols(tols)
    a1, _, d1, th1, _, ca1, sa1, s1 = dh_row(dh, 0)
    a2, _, d2, th2, _, ca2, sa2, right2 = dh_row(dh, 1)
    a3, _, d3, th3, prismatic3, ca3, sa3, _ = dh_row(dh, 2)
    d4 = dh_row(dh, 3)[2]
    _, _, d6, _, _, ca6, sa6, _ = dh_row(dh, 5)
    rrp = prismatic3 != 0.0
    R = (T[0, 0], T[0, 1], T[0, 2], T[1, 0], T[1, 1], T[1, 2], T[2, 0], T[2, 1], T[2, 2])
    # 1. Wrist centre W = p - d6 R (0, sin alpha6, cos alpha6).
    wx = T[0, 3] - d6 * (R[0] * 0.0 + R[1] * sa6 + R[2] * ca6)
    wy = T[1, 3] - d6 * (R[3] * 0.0 + R[4] * sa6 + R[5] * ca6)
    wz = T[2, 3] - d6 * (R[6] * 0.0 + R[7] * sa6 + R[8] * ca6)
    # 2. Arm joints from W = A1 A2 A3 (0, 0, d4).
    b3 = -sa3 * d4
    if rrp:
        st3, ct3 = sincos(th3)
        ex = ct3 * a3 - st3 * b3
        ey = st3 * a3 + ct3 * b3
        s2 = right2
        h = d2 + s2 * ey
        R3 = dh_rot(ct3, st3, ca3, sa3)  # constant: joint 3 slides
    else:
        ex = 0.0
        s2 = 0.0
        h = d2 + d3 + ca3 * d4
        R3 = dh_rot(1.0, 0.0, ca3, sa3)
    n = np.int64(0)  # not the literal 0: one signature of _sw_wrist for every call
    n1, t1a, t1b = trig_roots(wy, -wx, -s1 * h, th1 + ref[kr, 0], trig_tol, eps, free_tol)
    for i1 in range(n1):
        t1 = t1a if i1 == 0 else t1b
        sn1, c1 = sincos(t1)
        vx = c1 * wx + sn1 * wy - a1
        vy = s1 * (wz - d1)
        rho2 = vx * vx + vy * vy
        phi_v = atan2(vy, vx)
        q1 = t1 - th1
        theta1 = th1 + q1
        # A zero offset (the usual case) reuses c1, s1.
        R1 = dh_rot(c1, sn1, ca1, sa1) if theta1 == t1 else dh_rotation(theta1, ca1, sa1)
        if not rrp:
            rhs = rho2 - a2 * a2 - a3 * a3 - b3 * b3
            n3, t3a, t3b = elbow_roots(
                2 * a2 * a3,
                -2 * a2 * b3,
                rhs,
                th3 + ref[kr, 2],
                (trig_tol, eps, free_tol, ELBOW_REACH_TOL),
            )
            for i3 in range(n3):
                t3 = t3a if i3 == 0 else t3b
                sn3, c3 = sincos(t3)
                ux = a2 + a3 * c3 - b3 * sn3
                uy = a3 * sn3 + b3 * c3
                t2 = phi_v - atan2(uy, ux)
                q2 = t2 - th2
                q3 = t3 - th3
                theta3 = th3 + q3
                R3 = dh_rot(c3, sn3, ca3, sa3) if theta3 == t3 else dh_rotation(theta3, ca3, sa3)
                R03 = mul3(mul3(R1, dh_rotation(th2 + q2, ca2, sa2)), R3)
                n = _sw_wrist(dh, mul3tn(R03, R), ref, kr, q1, q2, q3, wrist_tol, cand, n)
        else:
            base = ex + a2
            radicand = rho2 - base * base
            if radicand < -_RADICAND_TOL * max(rho2, 1.0):
                continue
            root = math.sqrt(max(radicand, 0.0))
            n_len = 1 if root == 0.0 else 2
            for iL in range(n_len):
                L = root if iL == 0 else -root
                t2 = phi_v - atan2(-s2 * L, base)
                q2 = t2 - th2
                q3 = L - ca3 * d4 - d3
                R03 = mul3(mul3(R1, dh_rotation(th2 + q2, ca2, sa2)), R3)
                n = _sw_wrist(dh, mul3tn(R03, R), ref, kr, q1, q2, q3, wrist_tol, cand, n)
    return n


@register
class SphericalWrist(CompiledFamily):
    """6-dof arms (RRR or RRP arm) with a spherical wrist, by the 3+3 partition."""

    name = "spherical_wrist"
    kernel = _compiled.SPHERICAL_WRIST
    closed_form = spherical_wrist_candidates
    mismatch = "robot {name!r}: no spherical wrist family"
    rows_test = staticmethod(rows_reason)
