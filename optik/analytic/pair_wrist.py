"""Six revolute axes: a meeting pair, an elbow, a spherical wrist (from the joint axes).

The structure (in the product-of-exponentials form of the joint axes at ``q = 0``,
:func:`optik.analytic.geometry.joint_axes`: ``fk(q) = R_1(q_1) ... R_6(q_6) M``, each
``R_i`` a rotation about axis ``i`` and ``M`` the tool's pose at ``q = 0``):

- axes 1 and 2 meet at the shoulder point ``S``;
- axes 4, 5 and 6 meet at the wrist centre ``W`` (axis 5 not parallel to 4 or 6);
- axis 3 (the elbow) passes through neither, so it alone sets ``|W - S|``.

It is what a seven-joint arm with a spherical shoulder and a spherical wrist (the KUKA
iiwa, ...) leaves when one joint of the shoulder is held (:mod:`optik.analytic.free_joint`),
and the same with the chain reversed when a joint of the wrist is held. The closed form,
with ``G = T_target M^-1`` (all in the world frame):

1. ``W_t = G W``: the wrist centre's target (the wrist rotations fix ``W``).
2. ``|R_3(q_3) W - S| = |W_t - S|`` (``R_1``, ``R_2`` fix ``S``): a trig equation in
   ``q_3`` (:func:`optik.analytic._subproblems.distance_angles`), up to two elbows.
3. ``R_1(q_1) R_2(q_2) (R_3(q_3) W - S) = W_t - S``: two rotations about axes through
   ``S`` (subproblem 2, :func:`~optik.analytic._subproblems.sp2_angles`), up to two
   shoulders.
4. ``R_4 R_5 R_6 = (R_1 R_2 R_3)^T G`` (rotation parts): ``q_4, q_5`` by subproblem 2 on
   axis 6's direction (which ``R_6`` fixes), ``q_6`` by subproblem 1 on a direction across
   axis 6 from the residual rotation, so ``q_6`` absorbs any rounding of ``q_4``.

Up to 2 x 2 x 2 = 8 branches, in this order: elbow, shoulder, wrist (each pair in the
ascending order of the angle solved first). At a singularity a free angle takes the
reference: the shoulder's ``q_1`` with ``W_t - S`` on axis 1, the wrist's ``q_4`` with
axes 4 and 6 aligned (``q_6`` then takes up the rest; a second row splits the rest
between them, the configuration nearest the reference), the elbow with ``S`` or ``W`` on
axis 3 only when the distance already matches.

Tolerances are those of the compiled families (:data:`optik.analytic._compiled.TOL_TRIG`
...): the trig equations are normalised to coefficients of order 1, and "on its axis" is
``WRIST_SINGULAR`` relative to the point's distance from the axes' meeting point.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik._math import sincos, wrap_angle

# Steps shared by the closed forms are inlined into each: a call per shoulder branch cost
# 4-15 % of a held-joint solve.
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._compiled import (
    MAX_BRANCHES,
    closed_form_tols,
    mul3,
    mul3tn,
    store_branch,
)
from optik.analytic._subproblems import (
    Rot9,
    Vec3,
    apply,
    apply_t,
    axpy,
    cross,
    distance_angles,
    dot,
    meeting_point,
    norm,
    rotate,
    rotation,
    sp1_angle,
    sp2_angles,
    sub,
    unit,
    vec_at,
)
from optik.analytic.geometry import (
    ANGLE_TOL,
    LENGTH_TOL,
    Axes,
    line_distance,
    point_line_distance,
)

REACH_TOL = 1e-9
"""A wrist centre beyond the elbow's reach by at most this (relative) takes the tangent
elbow (:func:`optik.analytic._subproblems.distance_angles`), and the shoulder's
subproblem 2 the tangent pair when its gap is below zero by at most ``REACH_TOL |p|^2``
(:func:`optik.analytic._subproblems.sp2_angles`): axes that meet only to the geometry's
tolerance (a URDF angle written to 11 digits; the Panda at q5 = +-pi/2 with q7 held) put
a double root just out of exact reach. The FK check and the polish judge the rest."""


class AxesQuery(NamedTuple):
    """One target of a six-axis arm, as every arm kernel of the axes closed forms takes it.

    Attributes:
        z: (6, 3) unit joint directions at ``q = 0`` (world frame).
        p: (6, 3) a point on each axis (m).
        M: (4, 4) world pose of the tool at ``q = 0``.
        T: (4, 4) world target of the tool.
        ref: (6,) reference angles for free joints (rad).
        tols: the tolerance block of :mod:`optik.analytic._compiled`.
    """

    z: np.ndarray
    p: np.ndarray
    M: np.ndarray
    T: np.ndarray
    ref: np.ndarray
    tols: np.ndarray


@_jit
def pair_wrist_candidates(query: AxesQuery, cand: np.ndarray) -> int:
    """Raw branches of the pair-elbow-wrist closed form of ``query`` into ``cand`` (>= 8, 6).

    Rows are joint angles (rad), not wrapped. Returns the number of rows written (0 to 8),
    in the order of the module docstring.
    """
    z, p, M, T, ref, tols = query
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    z1, z2, z3 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2)
    S = meeting_point(z1, vec_at(p, 0), z2, vec_at(p, 1))
    W, Wt, RG = wrist_target(z, p, T, M)
    q = sub(Wt, S)
    dist2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2]
    across = wrist_across(z)
    p3 = vec_at(p, 2)
    n = 0
    roots = (trig_tol, eps, free_tol, REACH_TOL)
    n3, e1, e2 = distance_angles(z3, p3, W, S, dist2, ref[2], roots)
    for i3 in range(n3):
        t3 = e1 if i3 == 0 else e2
        s3, c3 = sincos(t3)
        W3 = sub(W, p3)
        W3 = rotate(z3, s3, c3, W3)
        P = sub((W3[0] + p3[0], W3[1] + p3[1], W3[2] + p3[2]), S)
        n12, ta1, tb1, ta2, tb2 = sp2_angles(z1, z2, P, q, ref[0], ref[1], REACH_TOL, axis_tol)
        R3 = rotation(z3, t3)
        for i12 in range(n12):
            t1 = ta1 if i12 == 0 else ta2
            t2 = tb1 if i12 == 0 else tb2
            R123 = mul3(mul3(rotation(z1, t1), rotation(z2, t2)), R3)
            n = wrist_branches(z, RG, R123, (t1, t2, t3), across, ref, tols, cand, n)
    return n


@_jit
def second_pair_candidates(query: AxesQuery, cand: np.ndarray) -> int:
    """Raw branches with axes 2 and 3 meeting at ``S`` (not axes 1 and 2) into ``cand``.

    ``R_2 R_3`` fix ``S``, so ``|R_1(q_1)^-1 W_t - S| = |W - S|``: a distance condition
    on ``q_1`` alone (subproblem 3 about axis 1, up to two), then ``R_2 R_3 (W - S) =
    R_1^-1 W_t - S`` by subproblem 2 (up to two pairs), then the wrist. Up to 8 rows:
    ``q_1`` ascending, the pairs, the wrist. Arguments as :func:`pair_wrist_candidates`.
    """
    z, p, M, T, ref, tols = query
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    z1, z2, z3 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2)
    p1 = vec_at(p, 0)
    S = meeting_point(z2, vec_at(p, 1), z3, vec_at(p, 2))
    W, Wt, RG = wrist_target(z, p, T, M)
    P = sub(W, S)
    across = wrist_across(z)
    back = (-z1[0], -z1[1], -z1[2])  # R_1(q)^-1 turns by q about -z1
    roots = (trig_tol, eps, free_tol, REACH_TOL)
    n1, e1, e2 = distance_angles(back, p1, Wt, S, dot(P, P), ref[0], roots)
    n = 0
    for i1 in range(n1):
        t1 = e1 if i1 == 0 else e2
        s1, c1 = sincos(t1)
        Y = rotate(back, s1, c1, sub(Wt, p1))
        Q = sub((Y[0] + p1[0], Y[1] + p1[1], Y[2] + p1[2]), S)
        n23, ta2, tb3, tc2, td3 = sp2_angles(z2, z3, P, Q, ref[1], ref[2], REACH_TOL, axis_tol)
        R1 = rotation(z1, t1)
        for i23 in range(n23):
            t2 = ta2 if i23 == 0 else tc2
            t3 = tb3 if i23 == 0 else td3
            R123 = mul3(mul3(R1, rotation(z2, t2)), rotation(z3, t3))
            n = wrist_branches(z, RG, R123, (t1, t2, t3), across, ref, tols, cand, n)
    return n


@_inline
def wrist_target(
    z: np.ndarray, p: np.ndarray, T: np.ndarray, M: np.ndarray
) -> tuple[Vec3, Vec3, Rot9]:
    """``(W, W_t, R_G)``: the wrist centre, its target and the turn of ``G = T M^-1``.

    ``W`` is where axes 4 and 5 meet, ``W_t = G W`` (:func:`target_frame`).
    """
    W = meeting_point(vec_at(z, 3), vec_at(p, 3), vec_at(z, 4), vec_at(p, 4))
    RG, tG = target_frame(T, M)
    return W, axpy(1.0, apply(RG, W), tG), RG


@_inline
def target_frame(T: np.ndarray, M: np.ndarray) -> tuple[Rot9, Vec3]:
    """``G = T M^-1`` as (rotation, translation): the motion of the tool from ``q = 0``.

    ``T`` and ``M`` are (4, 4) world poses: the target and the tool at ``q = 0``. The
    product of exponentials is ``G``, so every point the last joints fix moves by it.
    """
    RT = (T[0, 0], T[0, 1], T[0, 2], T[1, 0], T[1, 1], T[1, 2], T[2, 0], T[2, 1], T[2, 2])
    RMt = (M[0, 0], M[1, 0], M[2, 0], M[0, 1], M[1, 1], M[2, 1], M[0, 2], M[1, 2], M[2, 2])
    RG = mul3(RT, RMt)
    GtM = apply(RG, (M[0, 3], M[1, 3], M[2, 3]))
    return RG, (T[0, 3] - GtM[0], T[1, 3] - GtM[1], T[2, 3] - GtM[2])


@_inline
def wrist_across(z: np.ndarray) -> Vec3:
    """A unit direction across axis 6 (``z5 x z6``), for :func:`wrist_branches`."""
    return unit(cross(vec_at(z, 4), vec_at(z, 5)))


@_inline
def wrist_branches(
    z: np.ndarray,
    RG: Rot9,
    R123: Rot9,
    arm: Vec3,
    across: Vec3,
    ref: np.ndarray,
    tols: np.ndarray,
    cand: np.ndarray,
    n: int,
) -> int:
    """The spherical wrist's branches (axes 4-6 through one point) after the arm's angles.

    ``R_4 R_5 R_6 = R123^T R_G`` (rotation parts: ``R123`` the arm's rotation at its
    angles ``arm = (q_1, q_2, q_3)``, ``RG`` from :func:`target_frame`): ``q_4, q_5`` by
    subproblem 2 on axis 6's direction (which ``R_6`` fixes), ``q_6`` by subproblem 1 on
    ``across`` (:func:`wrist_across`) from the residual rotation, so ``q_6`` absorbs any
    rounding of ``q_4``. Writes up to two rows ``(q_1, ..., q_6)`` of ``cand`` from row
    ``n`` on; returns the new row count. The other arguments as
    :func:`pair_wrist_candidates`'.
    """
    trig_tol, _, _, axis_tol = closed_form_tols(tols)
    z4, z5, z6 = vec_at(z, 3), vec_at(z, 4), vec_at(z, 5)
    H = mul3tn(R123, RG)
    Hz6 = apply(H, z6)
    n45, ta, tb, tc, td = sp2_angles(z4, z5, z6, Hz6, ref[3], ref[4], trig_tol, axis_tol)
    Ha = apply(H, across)
    # Axes 4 and 6 aligned (sp2_angles's test): q4 took its reference. A second row is
    # the split nearest the reference (q4 and q6 each off theirs by half q6's excess);
    # analytic_ik polishes them into narrow limits that neither row meets.
    aligned = norm(cross(z4, Hz6)) <= axis_tol
    t6 = 0.0
    for i45 in range(2 if aligned else n45):
        t4 = ta if i45 == 0 else tc
        t5 = tb if i45 == 0 else td
        if aligned and i45 == 1:
            excess = wrap_angle(t6 - ref[5])  # the first row's q6
            if abs(excess) <= axis_tol:
                break
            # Axis 6 along axis 4: q4 + q6 is fixed, so q6 turns against q4; opposite:
            # q4 - q6 is fixed.
            along = dot(z4, apply(rotation(z5, tb), z6)) > 0.0
            t4 = ta + (0.5 * excess if along else -0.5 * excess)
            t5 = tb
        t6 = _wrist_q6(z4, z5, z6, t4, t5, across, Ha, ref, axis_tol)
        if n < MAX_BRANCHES:
            n = store_branch(cand, n, (arm[0], arm[1], arm[2], t4, t5, t6))
    return n


@_inline
def _wrist_q6(
    z4: Vec3,
    z5: Vec3,
    z6: Vec3,
    t4: float,
    t5: float,
    across: Vec3,
    Ha: Vec3,
    ref: np.ndarray,
    axis_tol: float,
) -> float:
    """``q_6`` (rad) from the residual rotation given ``q_4``, ``q_5`` (subproblem 1).

    On ``across``, whose image under the wrist's target rotation is ``Ha``.
    """
    R45 = mul3(rotation(z4, t4), rotation(z5, t5))
    return sp1_angle(z6, across, apply_t(R45, Ha), ref[5], axis_tol)


# ---------------------------------------------------------------------- the structure
def axis_label(names: tuple[str, ...], i: int) -> str:
    """Axis ``i`` (0-based) as the messages name it: ``"3 (joint_name)"``."""
    return f"{i + 1} ({names[i]})"


def meet_reason(axes: Axes, names: tuple[str, ...], i: int, j: int) -> str | None:
    """Why axes ``i`` and ``j`` do not meet in one point (parallel, or apart), or ``None``."""
    z, p = axes.directions, axes.points
    a, b = axis_label(names, i), axis_label(names, j)
    if float(np.linalg.norm(np.cross(z[i], z[j]))) <= ANGLE_TOL:
        return f"axes {a} and {b} are parallel"
    dist = line_distance(z[i], p[i], z[j], p[j])
    if dist > LENGTH_TOL * axes.size:
        return f"axes {a} and {b} do not meet ({dist:.3g} m apart)"
    return None


def meeting(axes: Axes, i: int, j: int) -> FloatArray:
    """The point where axes ``i`` and ``j`` meet (the middle of their common normal)."""
    z, p = axes.directions, axes.points
    return np.array(meeting_point(*(tuple(v) for v in (z[i], p[i], z[j], p[j]))))


def wrist_reason(axes: Axes, names: tuple[str, ...]) -> str | None:
    """Why axes 4, 5 and 6 do not meet in one point (a spherical wrist), or ``None``."""
    why = meet_reason(axes, names, 3, 4) or meet_reason(axes, names, 4, 5)
    if why is not None:
        return why
    miss = point_line_distance(axes.directions[5], axes.points[5], meeting(axes, 3, 4))
    if miss > LENGTH_TOL * axes.size:
        return (
            f"axis {axis_label(names, 5)} misses the point of axes {axis_label(names, 3)}, "
            f"{axis_label(names, 4)} by {miss:.3g} m"
        )
    return None


def structure_reason(axes: Axes, names: tuple[str, ...]) -> str | None:
    """Why six axes are not a meeting pair, an elbow and a spherical wrist, or ``None``.

    Args:
        axes: the six joint axes at ``q = 0`` (:func:`optik.analytic.geometry.joint_axes`).
        names: the six joints' names, for the messages.
    """
    why = meet_reason(axes, names, 0, 1) or wrist_reason(axes, names)
    if why is not None:
        return why
    z3, p3 = axes.directions[2], axes.points[2]
    for point, what in (
        (meeting(axes, 0, 1), "the point of axes 1 and 2"),
        (meeting(axes, 3, 4), "the wrist centre"),
    ):
        if point_line_distance(z3, p3, point) <= LENGTH_TOL * axes.size:
            return (
                f"axis {axis_label(names, 2)} passes through {what}: it does not change the "
                "distance from the shoulder to the wrist"
            )
    return None


def axes_tuple(axes: Axes) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(directions, points, tool)`` as C-contiguous float64 arrays for the kernel."""
    return (
        np.ascontiguousarray(axes.directions, dtype=np.float64),
        np.ascontiguousarray(axes.points, dtype=np.float64),
        np.ascontiguousarray(axes.tool, dtype=np.float64),
    )


__all__ = [
    "MAX_BRANCHES",
    "AxesQuery",
    "axes_tuple",
    "meet_reason",
    "pair_wrist_candidates",
    "second_pair_candidates",
    "structure_reason",
    "target_frame",
    "wrist_across",
    "wrist_branches",
    "wrist_reason",
    "wrist_target",
]
