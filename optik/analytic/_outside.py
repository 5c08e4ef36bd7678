"""A quick proof that a pose's closed-form branches all lie outside the joint limits.

When a compiled pipeline finds no branch inside the limits, :func:`optik.analytic.
_degenerate` polishes the raw branches and the reference by Gauss-Newton before it
accepts "none" (a pose where rounding lost a branch, or a singular one whose continuum of
answers may enter the limits elsewhere): some 1 ms a pose, two hundred times the closed
form. Most such poses are plain ones of an arm with narrow limits (a Kinova Jaco 2 with
its shoulder and elbow limited: a quarter of the poses of its whole joint space), and
for them the answer is already proven by the closed form itself:

- the pipeline without the limit filter returns :data:`MAX_BRANCHES` distinct branches,
  each verified by forward kinematics: the most isolated answers the compiled families
  have (four arm solutions, two wrists), so there is no other exact answer to find;
- an answer within the FK check's tolerance ``tol`` (position and rotation together) of
  the target lies within about ``tol / sigma_min(J)`` of an exact branch, when
  ``sigma_min(J)`` is large beside the curvature of the kinematics (``sigma_min^2 >=``
  :data:`TOLERANCE_FACTOR` ``tol dof max(1, r)``, ``r`` the reach sphere's radius);
- each branch lies outside the limits by at least :data:`PROOF_MARGIN` and by
  :data:`TOLERANCE_FACTOR` times that ``tol / sigma_min(J)``, over every 2 pi shift of
  its revolute joints: no configuration in the limits passes the FK check.

Poses that miss any of these (a wrist nearly aligned, a millimetre arm, a branch just
beyond a limit) take the polish as before.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from optik._checks import FloatArray
from optik._kernels import fk_jacobian_work
from optik._math import cholesky_factor
from optik._numba import inline, jit
from optik.analytic._base import VERIFY_TOLERANCE, CompiledPipeline, verify_position_tolerance
from optik.analytic._compiled import MAX_BRANCHES
from optik.analytic._steps import _wrap_bounds
from optik.model import Robot

PROOF_MARGIN = 1e-6
"""Least distance (rad or m) outside the limits of the branches of a quick proof."""

TOLERANCE_FACTOR = 10.0
"""Safety factor on the first-order reach ``tol / sigma_min(J)`` of the FK check's
tolerance around an exact branch."""


def proven_outside(
    robot: Robot,
    pipeline: CompiledPipeline,
    T: FloatArray,
    ref: FloatArray,
    flags: int,
    singular_gate: float,
) -> NDArray[np.bool_]:
    """Which targets are proven to have every branch outside the limits, without a polish.

    Args:
        robot: the robot the pipeline solves.
        pipeline: its compiled pose pipeline.
        T: (N, 4, 4) valid world targets for which the pipeline found no branch inside the
            limits.
        ref: (1, 6) or (N, 6) references, as the pipeline took them.
        flags: the pipeline's flags without the limit filter.
        singular_gate: smallest singular value (m or rad per rad) below which a branch
            is singular.

    Returns:
        (N,) bool: ``True`` where the closed form proves there is no branch in the limits.
    """
    Q, counts = pipeline.solve_batch(pipeline.params, T, ref, flags)
    proven = counts == MAX_BRANCHES
    if proven.any():
        chain = robot.chain
        lower, upper, circular, anywhere = robot.cached(_distance_bounds)
        floor, reach = robot.cached(_tolerance_reach)
        proven[proven] = isolated_outside(
            chain.K, chain.prismatic, chain.C, chain.identity, Q[proven],
            lower, upper, circular, anywhere, max(singular_gate, floor), reach, PROOF_MARGIN,
        )  # fmt: skip
    return proven


@jit
def isolated_outside(
    K: np.ndarray,
    prismatic: np.ndarray,
    C: np.ndarray,
    identity: bool,
    Q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    circular: np.ndarray,
    anywhere: np.ndarray,
    floor: float,
    reach: float,
    margin: float,
) -> np.ndarray:
    """Whether every branch of each target in ``Q`` (N, B, dof) is isolated and outside.

    Each branch must lie outside the limits by ``d >= margin`` (:func:`_distance_beyond`)
    and have ``sigma_min(J) > max(floor, reach / d)``, so that it is ``reach /
    sigma_min(J)`` within ``d``: ``J^T J - s I`` has a Cholesky factor with ``s`` that
    bound squared plus ``4 dof eps ||J||_F^2`` (the allowance covers the rounding of ``J^T
    J``, so a branch at the bound up to rounding fails). Returns (N,) bool.
    """
    N, B, dof = Q.shape
    n = prismatic.shape[0]
    theta = np.empty(n)
    T = np.empty((4, 4))
    Jt = np.empty((6, n))
    work = np.empty((n, 3))
    J = np.empty((6, dof))
    G = np.empty((dof, dof))
    L = np.empty((dof, dof + 1))
    eps = np.finfo(np.float64).eps
    out = np.zeros(N, dtype=np.bool_)
    for k in range(N):
        ok = True
        for b in range(B):
            q = Q[k, b]
            beyond = _distance_beyond(q, lower, upper, circular, anywhere)
            if beyond < margin:
                ok = False
                break
            if identity:
                theta[:] = q
            else:
                theta[:] = C @ q
            fk_jacobian_work(K, prismatic, theta, T, Jt, work)
            if identity:
                J[:] = Jt
            else:
                J[:] = Jt @ C
            frobenius = 0.0
            for i in range(6):
                for j in range(dof):
                    frobenius += J[i, j] * J[i, j]
            needed = max(floor, reach / beyond)
            shift = needed * needed + 4.0 * dof * eps * frobenius
            for i in range(dof):
                for j in range(i + 1):
                    s = 0.0
                    for r in range(6):
                        s += J[r, i] * J[r, j]
                    G[i, j] = s - shift if i == j else s
            if not cholesky_factor(G, L):
                ok = False
                break
        out[k] = ok
    return out


@inline
def _distance_beyond(
    q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    circular: np.ndarray,
    anywhere: np.ndarray,
) -> float:
    """How far the branch ``q`` (dof,) is outside its limits: the largest joint's distance.

    A revolute joint whose range is finite and shorter than 2 pi is judged by its nearest
    representative modulo 2 pi; one with a longer range has a representative inside; any
    other joint by its value. 0 when every joint is inside.
    """
    two_pi = 2.0 * math.pi
    largest = 0.0
    for j in range(q.shape[0]):
        if anywhere[j]:
            continue
        if circular[j]:
            shifted = lower[j] + np.remainder(q[j] - lower[j], two_pi)
            d = min(shifted - upper[j], lower[j] + two_pi - shifted)
        else:
            d = max(lower[j] - q[j], q[j] - upper[j])
        largest = max(largest, d)
    return largest


def _distance_bounds(
    robot: Robot,
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.bool_]]:
    """What :func:`_distance_beyond` reads of the robot, kept per robot.

    ``(lower, upper, circular, anywhere)`` (dof,) each: the limits (a limit that is not
    finite read as none), the revolute joints with a finite range shorter than 2 pi, and
    those with a longer one (a representative of every angle lies inside).
    """
    revolute, lower, upper = robot.cached(_wrap_bounds)
    span = upper - lower
    circular = revolute & np.isfinite(span) & (span < 2.0 * math.pi)
    anywhere = revolute & ~circular
    for array in (circular, anywhere):
        array.flags.writeable = False
    return lower, upper, circular, anywhere


def _tolerance_reach(robot: Robot) -> tuple[float, float]:
    """``(floor, reach)`` of :func:`isolated_outside` for ``robot``, kept per robot.

    ``reach`` is :data:`TOLERANCE_FACTOR` times the FK check's tolerance (position and
    rotation together); ``floor`` the least ``sigma_min(J)`` for which that tolerance's
    neighbourhood of a branch is first order: ``sqrt(reach dof max(1, r))``, the
    curvature of the kinematics bounded by the number of joints times the reach radius.
    """
    reach = TOLERANCE_FACTOR * math.hypot(verify_position_tolerance(robot), VERIFY_TOLERANCE)
    return math.sqrt(reach * robot.dof * max(1.0, robot.reach_sphere[1])), reach
