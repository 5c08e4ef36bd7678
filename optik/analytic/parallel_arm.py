"""Six revolute axes: a spherical wrist after an arm with two parallel axes (from the axes).

The structure (in the product of exponentials of the joint axes at ``q = 0``,
:func:`optik.analytic.geometry.joint_axes`: ``fk(q) = R_1(q_1) ... R_6(q_6) M``):
axes 4, 5 and 6 meet at the wrist centre ``W``, and of the arm's axes either

- axes 1 and 2 are parallel (direction ``h``), distinct, and axis 3 is not parallel to
  them and misses ``W`` (:data:`PARALLEL_12`), or
- axes 2 and 3 are parallel (direction ``h``), distinct, and axis 1 is not parallel to
  them (:data:`PARALLEL_23`).

A rotation about a line of direction ``h`` keeps every point's height along ``h``, which
leaves one joint alone to set a height (Paden–Kahan subproblem 4); with ``G = T M^-1``
and the wrist centre's target ``W_t = G W``:

- :data:`PARALLEL_12`: ``h . R_3(q_3) W = h . W_t`` gives up to two ``q_3``
  (:func:`optik.analytic._subproblems.plane_angles`); then ``X = R_3 W`` must turn about
  axis 2 to the distance of ``W_t`` from axis 1 (subproblem 3, up to two ``q_2``), and
  ``q_1`` turns ``R_2 X`` onto ``W_t`` (subproblem 1);
- :data:`PARALLEL_23`: ``h . R_1(q_1)^-1 W_t = h . W`` gives up to two ``q_1``; then
  ``R_3(q_3) W`` must lie at the distance of ``X = R_1^-1 W_t`` from axis 2 (subproblem 3,
  up to two ``q_3``), and ``q_2`` turns ``R_3 W`` onto ``X`` (subproblem 1).

The wrist follows as in :func:`optik.analytic.pair_wrist.wrist_branches`. Up to
2 x 2 x 2 = 8 branches (each refined by one Newton step on the robot's chain in the
post-processing, :mod:`optik.analytic._newton`). At a singularity a free angle takes the
reference: ``q_1`` with ``W_t`` on axis 1 (:data:`PARALLEL_23`), the distance angle with
its point on its axis, the wrist's ``q_4`` with axes 4 and 6 aligned.
"""

from __future__ import annotations

import numpy as np

from optik._numba import jit as _jit
from optik.analytic._compiled import closed_form_tols, mul3
from optik.analytic._subproblems import (
    dot,
    plane_angles,
    reach_angles,
    rotation,
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

PARALLEL_12 = 1
"""Arm kind: axes 1 and 2 parallel."""
PARALLEL_23 = 2
"""Arm kind: axes 2 and 3 parallel."""


@_jit
def parallel_arm_candidates(query: AxesQuery, kind: int, cand: np.ndarray) -> int:
    """Raw branches of the parallel-arm, spherical-wrist closed form into ``cand`` (>= 8, 6).

    Arguments as :func:`optik.analytic.pair_wrist.pair_wrist_candidates`, and ``kind``:
    :data:`PARALLEL_12` or :data:`PARALLEL_23`. Returns the number of rows written (0 to
    8): the first arm angle solved, then the second (each pair ascending), then the wrist.
    """
    z, p, M, T, ref, tols = query
    trig_tol, eps, free_tol, axis_tol = closed_form_tols(tols)
    roots = (trig_tol, eps, free_tol, REACH_TOL)
    z1, z2, z3 = vec_at(z, 0), vec_at(z, 1), vec_at(z, 2)
    p1, p2, p3 = vec_at(p, 0), vec_at(p, 1), vec_at(p, 2)
    W, Wt, RG = wrist_target(z, p, T, M)
    across = wrist_across(z)
    n = 0
    if kind == PARALLEL_12:
        na, a1, a2 = plane_angles(z3, p3, W, z1, dot(z1, Wt), ref[2], roots)
        d = sub(Wt, p1)
        for ia in range(na):
            t3 = a1 if ia == 0 else a2
            X = turn_point(z3, p3, t3, W)
            nb_, u1, v1, u2, v2 = reach_angles(
                z1, p1, z2, p2, X, d, ref[0], ref[1], roots, axis_tol
            )
            for ib in range(nb_):
                t1, t2 = (u1, v1) if ib == 0 else (u2, v2)
                R123 = mul3(mul3(rotation(z1, t1), rotation(z2, t2)), rotation(z3, t3))
                n = wrist_branches(z, RG, R123, (t1, t2, t3), across, ref, tols, cand, n)
        return n
    back = (-z1[0], -z1[1], -z1[2])  # R_1(q)^-1 turns by q about -z1
    na, a1, a2 = plane_angles(back, p1, Wt, z2, dot(z2, W), ref[0], roots)
    for ia in range(na):
        t1 = a1 if ia == 0 else a2
        d = sub(turn_point(back, p1, t1, Wt), p2)
        nb_, u1, v1, u2, v2 = reach_angles(z2, p2, z3, p3, W, d, ref[1], ref[2], roots, axis_tol)
        for ib in range(nb_):
            t2, t3 = (u1, v1) if ib == 0 else (u2, v2)
            R123 = mul3(mul3(rotation(z1, t1), rotation(z2, t2)), rotation(z3, t3))
            n = wrist_branches(z, RG, R123, (t1, t2, t3), across, ref, tols, cand, n)
    return n


__all__ = ["PARALLEL_12", "PARALLEL_23", "parallel_arm_candidates"]
