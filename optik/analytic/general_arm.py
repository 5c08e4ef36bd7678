"""Six revolute axes: a spherical wrist after a general arm, by one quartic (from the axes).

The structure (in the product of exponentials of the joint axes at ``q = 0``,
:func:`optik.analytic.geometry.joint_axes`: ``fk(q) = R_1(q_1) ... R_6(q_6) M``): axes
4, 5 and 6 meet at the wrist centre ``W``, and the arm's axes have none of the relations
the other arm kinds use — axes 1 and 2 neither meet nor are parallel, nor do axes 2 and 3
— and axis 3 misses ``W`` (EAIK's "spherical, no parallel, no intersecting"; axes 2 and
3 meeting take :func:`optik.analytic.pair_wrist.second_pair_candidates`).
Pieper's problem: with ``G = T M^-1`` and the wrist centre's target ``W_t = G W``,

``R_2(q_2) X(q_3) = Y(q_1)``, ``X(q_3) = R_3(q_3) W``, ``Y(q_1) = R_1(-q_1) W_t``:

both points run on circles (``X = x_0 + x_c cos q_3 + x_s sin q_3``, ``Y`` alike), and
``R_2`` turns one onto the other exactly when they have the same height along axis 2 and
the same distance from its point ``p_2``. Both conditions are linear in ``u_1 = (cos
q_1, sin q_1)`` and in ``u_3 = (cos q_3, sin q_3)``: ``A u_1 = b_0 + B u_3`` with 2x2
matrices ``A`` (of the target) and ``B`` (of the arm): the pair step of
:mod:`optik.analytic._angle_pairs`. Eliminating ``q_1`` without dividing, ``|adj(A) (b_0
+ B u_3)|^2 = det(A)^2``, leaves a trig polynomial of degree 2 in ``q_3``, that is a
quartic: its real roots by certified subdivision and Newton's method, or, where a root may
hide (a near-double one), the eigenvalues of the companion matrix of ``z^2 f`` in ``z =
e^{i q_3}`` that lie on the unit circle (:mod:`optik.analytic._quartic`); then ``q_1`` is
the angle of ``adj(A) (b_0 + B u_3)`` times the sign of ``det A``. Near axis 1 ``A``
shrinks and that quartic's roots pair up (their gap is ``det A``, squared), so there
``q_3`` is eliminated instead (``B`` stays regular when axes 2 and 3 are skew): whichever
keeps the roots further apart (:func:`optik.analytic._angle_pairs.root_separation`). Then
``q_2`` turns ``X`` onto ``Y`` (subproblem 1), and the wrist follows as in
:func:`optik.analytic.pair_wrist.wrist_branches`.

Up to 4 x 2 = 8 branches, the quartic's angle ascending, then the wrist; each is
refined by one Newton step on the robot's chain and checked by FK in the
post-processing. At a singularity a free angle takes the reference: ``q_1`` with ``W_t`` on
axis 1 (then ``q_3`` puts ``X`` at ``W_t``'s height along axis 2; ``det A`` vanishes
there and only there), the wrist's ``q_4`` with axes 4 and 6 aligned.
"""

from __future__ import annotations

import math

import numpy as np

from optik._numba import jit as _jit
from optik.analytic._angle_pairs import angle_pairs
from optik.analytic._compiled import closed_form_tols, mul3
from optik.analytic._subproblems import (
    Rot9,
    Vec3,
    circle,
    dot,
    plane_angles,
    rotation,
    sp1_angle,
    sub,
    turn_point,
    vec_at,
)
from optik.analytic.pair_wrist import (
    REACH_TOL,
    AxesQuery,
    wrist_across,
    wrist_branches,
    wrist_target,
)


@_jit
def general_arm_candidates(query: AxesQuery, cand: np.ndarray) -> int:
    """Raw branches of the general arm and spherical wrist into ``cand`` (>= 8, 6).

    Arguments as :func:`optik.analytic.pair_wrist.pair_wrist_candidates`. Returns the
    number of rows written (0 to 8), in the order of the module docstring.
    """
    z, p, M, T, ref, tols = query
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    z1, z2, z3 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2)
    p1, p2, p3 = vec_at(p, 0), vec_at(p, 1), vec_at(p, 2)
    W, Wt, RG = wrist_target(z, p, T, M)
    across = wrist_across(z)
    back = (-z1[0], -z1[1], -z1[2])  # R_1(q)^-1 turns by q about -z1
    x0, xc, xs = circle(z3, p3, W)
    y0, yc, ys = circle(back, p1, Wt)
    dx, dy = sub(x0, p2), sub(y0, p2)
    size = max(math.sqrt(dot(dx, dx) + dot(xc, xc)), math.sqrt(dot(dy, dy) + dot(yc, yc)))
    n = 0
    roots = (trig_tol, eps, free_tol, REACH_TOL)
    if not math.sqrt(dot(yc, yc)) > axis_tol * size:
        # W_t on axis 1: q_1 free; X must reach W_t's height along axis 2.
        count, e1, e2 = plane_angles(z3, p3, W, z2, dot(z2, Wt), ref[2], roots)
        for i3 in range(count):
            t3 = e1 if i3 == 0 else e2
            n = _branch(z, p, RG, W, Wt, ref[0], t3, across, ref, tols, cand, n)
        return n
    # The height (row 1, / size) and squared distance (row 2, / size^2) conditions:
    # A (cos q_1, sin q_1) = b0 + B (cos q_3, sin q_3), B's columns b1, b2.
    inv, inv2 = 1.0 / size, 1.0 / (size * size)
    A = (dot(z2, yc) * inv, dot(z2, ys) * inv, 2.0 * dot(dy, yc) * inv2, 2.0 * dot(dy, ys) * inv2)
    spread = dot(dx, dx) + dot(xc, xc) - dot(dy, dy) - dot(yc, yc)
    b0 = (dot(z2, sub(x0, y0)) * inv, spread * inv2)
    B = (dot(z2, xc) * inv, dot(z2, xs) * inv, 2.0 * dot(dx, xc) * inv2, 2.0 * dot(dx, xs) * inv2)
    angles = np.empty((2, 4))
    # The quartic eliminates the angle whose matrix keeps its roots apart: near axis 1 (A
    # small) q_3's quartic has near-double roots, q_1's (B constant, regular when axes 2
    # and 3 are skew) does not.
    count = angle_pairs(A, b0, B, ref[0], ref[2], roots, angles)
    for i in range(count):
        n = _branch(z, p, RG, W, Wt, angles[0, i], angles[1, i], across, ref, tols, cand, n)
    return n


@_jit
def _branch(
    z: np.ndarray,
    p: np.ndarray,
    RG: Rot9,
    W: Vec3,
    Wt: Vec3,
    t1: float,
    t3: float,
    across: Vec3,
    ref: np.ndarray,
    tols: np.ndarray,
    cand: np.ndarray,
    n: int,
) -> int:
    """``q_2`` turning ``X(q_3)`` onto ``Y(q_1)`` about axis 2, then the wrist's rows.

    ``W`` is the wrist centre, ``W_t`` its target (:func:`optik.analytic.pair_wrist.wrist_target`).
    """
    axis_tol = closed_form_tols(tols)[3]
    z1, z2, z3 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2)
    p1, p2, p3 = vec_at(p, 0), vec_at(p, 1), vec_at(p, 2)
    X = turn_point(z3, p3, t3, W)
    Y = turn_point(z1, p1, -t1, Wt)
    t2 = sp1_angle(z2, sub(X, p2), sub(Y, p2), ref[1], axis_tol)
    R123 = mul3(mul3(rotation(z1, t1), rotation(z2, t2)), rotation(z3, t3))
    return wrist_branches(z, RG, R123, (t1, t2, t3), across, ref, tols, cand, n)


__all__ = ["general_arm_candidates"]
