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
axes 4 and 6 aligned (``q_6`` then takes up the rest), the elbow with ``S`` or ``W`` on
axis 3 only when the distance already matches.

Tolerances are those of the compiled families (:data:`optik.analytic._compiled.TOL_TRIG`
...): the trig equations are normalised to coefficients of order 1, and "on its axis" is
``WRIST_SINGULAR`` relative to the point's distance from the axes' meeting point.
"""

from __future__ import annotations

import numpy as np

from optik._checks import FloatArray
from optik._math import sincos

# Steps shared by the closed forms are inlined into each: a call per shoulder branch cost
# 4-15 % of a held-joint solve.
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._compiled import MAX_BRANCHES, closed_form_tols, mul3, mul3tn
from optik.analytic._subproblems import (
    Rot9,
    Vec3,
    apply,
    apply_t,
    cross,
    distance_angles,
    meeting_point,
    norm,
    rotate,
    rotation,
    sp1_angle,
    sp2_angles,
    sub,
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


@_jit
def pair_wrist_candidates(
    z: np.ndarray,
    p: np.ndarray,
    M: np.ndarray,
    T: np.ndarray,
    ref: np.ndarray,
    tols: np.ndarray,
    cand: np.ndarray,
    lsq: np.ndarray,
) -> int:
    """Raw branches of the pair-elbow-wrist closed form into ``cand`` (>= 8, 6).

    Args:
        z: (6, 3) unit joint directions at ``q = 0`` (world frame).
        p: (6, 3) a point on each axis (m).
        M: (4, 4) world pose of the tool at ``q = 0``.
        T: (4, 4) world target of the tool.
        ref: (6,) reference angles for free joints (rad).
        tols: the tolerance block of :mod:`optik.analytic._compiled`.
        cand: output rows (joint angles, rad, not wrapped).
        lsq: (3, 6, 6) scratch of :func:`refine` (the caller allocates it once).

    Returns:
        The number of rows written (0 to 8), in the order of the module docstring.
    """
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    z1, z2, z3, z4, z5 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2), vec_at(z, 3), vec_at(z, 4)
    S = meeting_point(z1, vec_at(p, 0), z2, vec_at(p, 1))
    W = meeting_point(z4, vec_at(p, 3), z5, vec_at(p, 4))
    RG, tG = target_frame(T, M)
    GW = apply(RG, W)
    Wt = (GW[0] + tG[0], GW[1] + tG[1], GW[2] + tG[2])
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
            n = wrist_branches(z, p, M, T, RG, R123, (t1, t2, t3), across, ref, tols, cand, n, lsq)
    return n


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
    across = cross(vec_at(z, 4), vec_at(z, 5))
    na = norm(across)
    return (across[0] / na, across[1] / na, across[2] / na)


@_inline
def wrist_branches(
    z: np.ndarray,
    p: np.ndarray,
    M: np.ndarray,
    T: np.ndarray,
    RG: Rot9,
    R123: Rot9,
    arm: Vec3,
    across: Vec3,
    ref: np.ndarray,
    tols: np.ndarray,
    cand: np.ndarray,
    n: int,
    lsq: np.ndarray,
) -> int:
    """The spherical wrist's branches (axes 4-6 through one point) after the arm's angles.

    ``R_4 R_5 R_6 = R123^T R_G`` (rotation parts: ``R123`` the arm's rotation at its
    angles ``arm = (q_1, q_2, q_3)``, ``RG`` from :func:`target_frame`): ``q_4, q_5`` by
    subproblem 2 on axis 6's direction (which ``R_6`` fixes), ``q_6`` by subproblem 1 on
    ``across`` (:func:`wrist_across`) from the residual rotation, so ``q_6`` absorbs any
    rounding of ``q_4``. Writes up to two rows ``(q_1, ..., q_6)`` of ``cand`` from row
    ``n`` on (each refined by :func:`refine`); returns the new row count. The other
    arguments as :func:`pair_wrist_candidates`'.
    """
    trig_tol, _, _, axis_tol = closed_form_tols(tols)
    z4, z5, z6 = vec_at(z, 3), vec_at(z, 4), vec_at(z, 5)
    H = mul3tn(R123, RG)
    n45, ta, tb, tc, td = sp2_angles(z4, z5, z6, apply(H, z6), ref[3], ref[4], trig_tol, axis_tol)
    for i45 in range(n45):
        t4 = ta if i45 == 0 else tc
        t5 = tb if i45 == 0 else td
        R45 = mul3(rotation(z4, t4), rotation(z5, t5))
        t6 = sp1_angle(z6, across, apply_t(R45, apply(H, across)), ref[5], axis_tol)
        if n < cand.shape[0]:
            cand[n, 0] = arm[0]
            cand[n, 1] = arm[1]
            cand[n, 2] = arm[2]
            cand[n, 3] = t4
            cand[n, 4] = t5
            cand[n, 5] = t6
            refine(z, p, M, T, cand, n, lsq)
            n += 1
    return n


REFINE_DAMPING = 1e-6
"""Damping of :func:`refine`'s least-squares step (the Jacobian's scale is 1 m or 1):
directions of the Jacobian with singular values far below it (at a singularity) are not
moved, so a free angle keeps its reference."""
REFINE_MAX_STEP = 1e-4
"""Largest correction (rad) :func:`refine` applies: a larger one means an ill-posed
system, and the closed form's values are kept."""
REFINE_TRUSTED_STEP = 1e-8
"""A correction up to this (rad) is kept without recomputing the error: the damped step
never raises the linearised error, and the rest is second order (about 1e-16)."""


@_jit
def _pose_error(
    z: np.ndarray, p: np.ndarray, M: np.ndarray, T: np.ndarray, q: np.ndarray, J: np.ndarray
) -> tuple[float, float, float, float, float, float]:
    """``T``'s position and small-angle orientation error against ``fk(q)``; ``J`` (6, 6).

    The product of exponentials ``R_1(q_1) ... R_6(q_6) M``; ``J`` receives the world
    Jacobian at the tool point (rows: linear, then angular velocity). The orientation
    error is the axial vector of the skew part of ``R_T R^T`` (exact to second order).
    """
    R: Rot9 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    t = (0.0, 0.0, 0.0)
    for i in range(6):
        w = apply(R, vec_at(z, i))
        c = apply(R, vec_at(p, i))
        c = (c[0] + t[0], c[1] + t[1], c[2] + t[2])
        for a in range(3):
            J[3 + a, i] = w[a]
        J[0, i] = c[0]
        J[1, i] = c[1]
        J[2, i] = c[2]
        Ri = rotation(vec_at(z, i), q[i])
        # Moving frame: the joint turns about its line through p_i.
        pi = vec_at(p, i)
        Rp = apply(Ri, pi)
        ti = (pi[0] - Rp[0], pi[1] - Rp[1], pi[2] - Rp[2])
        Rti = apply(R, ti)
        t = (t[0] + Rti[0], t[1] + Rti[1], t[2] + Rti[2])
        R = mul3(R, Ri)
    RM = (M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2], M[2, 0], M[2, 1], M[2, 2])
    Rq = mul3(R, RM)
    tq = apply(R, (M[0, 3], M[1, 3], M[2, 3]))
    tq = (tq[0] + t[0], tq[1] + t[1], tq[2] + t[2])
    for i in range(6):
        # Linear velocity of the tool point: w x (tool - point on the turned axis).
        w = (J[3, i], J[4, i], J[5, i])
        v = cross(w, (tq[0] - J[0, i], tq[1] - J[1, i], tq[2] - J[2, i]))
        J[0, i] = v[0]
        J[1, i] = v[1]
        J[2, i] = v[2]
    RT = (T[0, 0], T[0, 1], T[0, 2], T[1, 0], T[1, 1], T[1, 2], T[2, 0], T[2, 1], T[2, 2])
    E = mul3(RT, (Rq[0], Rq[3], Rq[6], Rq[1], Rq[4], Rq[7], Rq[2], Rq[5], Rq[8]))
    return (
        T[0, 3] - tq[0],
        T[1, 3] - tq[1],
        T[2, 3] - tq[2],
        0.5 * (E[7] - E[5]),
        0.5 * (E[2] - E[6]),
        0.5 * (E[3] - E[1]),
    )


@_jit
def refine(
    z: np.ndarray,
    p: np.ndarray,
    M: np.ndarray,
    T: np.ndarray,
    cand: np.ndarray,
    r: int,
    lsq: np.ndarray,
) -> None:
    """One Newton step of ``cand[r]`` towards ``T`` on the product of exponentials.

    Axes that meet only to within the geometry's tolerances (a URDF angle written to 11
    digits) make the closed form exact to about 1e-12; near a singularity that error is
    magnified in the joints that the singularity couples. One damped least-squares step
    (:data:`REFINE_DAMPING`) restores the branch to rounding. It is kept only when it is
    small (:data:`REFINE_MAX_STEP`) and lowers the error (checked unless it is tiny,
    :data:`REFINE_TRUSTED_STEP`). ``lsq`` (3, 6, 6) is scratch:
    the Jacobian, the normal matrix, and the configuration and step in its last block.
    """
    J = lsq[0]
    A = lsq[1]
    q = lsq[2, 0]
    b = lsq[2, 1]
    for i in range(6):
        q[i] = cand[r, i]
    e = _pose_error(z, p, M, T, q, J)
    before = max(abs(e[0]), abs(e[1]), abs(e[2]), abs(e[3]), abs(e[4]), abs(e[5]))
    if before == 0.0:
        return
    # Damped normal equations (J^T J + lambda^2 I) dq = J^T e, solved by Gaussian
    # elimination (the matrix is symmetric positive definite: no pivoting needed).
    for i in range(6):
        acc = 0.0
        for m in range(6):
            acc += J[m, i] * e[m]
        b[i] = acc
        for j in range(6):
            acc = 0.0
            for m in range(6):
                acc += J[m, i] * J[m, j]
            A[i, j] = acc
        A[i, i] += REFINE_DAMPING * REFINE_DAMPING
    for col in range(6):
        for row in range(col + 1, 6):
            f = A[row, col] / A[col, col]
            for j in range(col, 6):
                A[row, j] -= f * A[col, j]
            b[row] -= f * b[col]
    for col in range(5, -1, -1):
        acc = b[col]
        for j in range(col + 1, 6):
            acc -= A[col, j] * b[j]
        b[col] = acc / A[col, col]
    step = 0.0
    for i in range(6):
        if not abs(b[i]) <= REFINE_MAX_STEP:
            return
        step = max(step, abs(b[i]))
        q[i] += b[i]
    if step > REFINE_TRUSTED_STEP:
        e = _pose_error(z, p, M, T, q, J)
        after = max(abs(e[0]), abs(e[1]), abs(e[2]), abs(e[3]), abs(e[4]), abs(e[5]))
        if not after < before:
            return
    for i in range(6):
        cand[r, i] = q[i]


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
    "axes_tuple",
    "meet_reason",
    "pair_wrist_candidates",
    "structure_reason",
    "target_frame",
    "wrist_across",
    "wrist_branches",
    "wrist_reason",
]
