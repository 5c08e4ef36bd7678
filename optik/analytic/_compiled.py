"""Compiled closed forms and the compiled IK pipeline of the six-joint families.

The one implementation of the ``spherical_wrist`` and ``ur`` closed forms (their
derivations are in :mod:`optik.analytic.spherical_wrist` and :mod:`optik.analytic.ur`),
and of the post-processing that :func:`optik.analytic.analytic_ik` applies to every family:

1. raw candidate branches from the closed form (up to :data:`MAX_BRANCHES`);
2. drop non-finite rows; shift revolute angles by multiples of 2 pi into the limits,
   nearest ``q_ref`` (the rule of :func:`optik.analytic.wrap_into_limits`);
3. drop out-of-limit rows (tolerance :data:`optik.limits.LIMIT_TOLERANCE`), unless asked;
4. verify each row by forward kinematics: the robot's own chain ``_K`` (the kinematics of
   ``Robot.fk``, not the DH rows) multiplied out with the arithmetic of
   :func:`optik._kernels.fk_into`, expression for expression (:func:`_fk_shared`; rows
   that share leading joint values share that part of the product); position error (m)
   and orientation error (rad, the robust ``atan2`` angle of
   :func:`optik.spatial.rotation_angle`) both within
   :data:`optik.analytic._base.VERIFY_TOLERANCE`;
5. drop duplicates (max-abs difference below ``DUPLICATE_TOLERANCE``);
6. with a caller's ``q_ref``, a stable sort by the Euclidean distance to it.

Every step gives what the numpy steps of :func:`optik.analytic.analytic_ik` give on the
same raw branches (a test checks it row for row). One deliberate difference: sines and
cosines come from inline fdlibm kernels (:func:`sincos`, at most 1 ulp and 2e-16 from
libm's) rather than libm calls, which cost more than the rest of the FK check; the FK
check then agrees with ``Robot.fk`` to a few 1e-16, far below the 1e-9 it enforces.

Robot data travel as one flat float64 vector, ``params`` (built once per robot by
:func:`pack_params`; layout in :data:`PARAMS_LAYOUT`), so that a call pays the numba
dispatcher's per-argument cost for few arguments. ``params`` also carries the tolerances
read from their home modules (``TRIG_TOL``, ``LIMIT_TOLERANCE``, ...): numba freezes a
global's value into its on-disk cache, which is not invalidated when another module
changes, so a tolerance defined elsewhere must be passed, never read as a global.

Hot paths index arrays rather than slicing or reshaping them per pose (a reshape is a C
call, a view a reference count): scratch arrays are made once per call or batch.
Every kernel is serial (``nogil``): callers may run them from several threads.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numba as nb
import numpy as np

from optik._checks import FloatArray
from optik._math import (
    _SINCOS_RANGE,
    _sincos_core,
    mod_two_pi,
    pose_defect,
    sincos,
    trig_roots,
    wrap_angle,
)
from optik.analytic._base import (
    DUPLICATE_TOLERANCE,
    FAMILIES,
    FREE_RHS_TOL,
    SINGULAR_EPS,
    VERIFY_TOLERANCE,
    is_right_angle,
)
from optik.limits import LIMIT_TOLERANCE
from optik.spatial import ROTATION_TOLERANCE, invert_transform
from optik.trig import TRIG_TOL

if TYPE_CHECKING:
    from optik.model import DHJoint, Robot

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")
_inline = nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")

SPHERICAL_WRIST = 1
"""Family id of :class:`optik.analytic.spherical_wrist.SphericalWrist`."""
UR = 2
"""Family id of :class:`optik.analytic.ur.URArm`."""

MAX_BRANCHES = 8
"""Most raw branches of a compiled family: two x two x two."""
_SIN = MAX_BRANCHES  # rows of the (24, 6) scratch block holding the branches' sines
_COS = 2 * MAX_BRANCHES  # ... and their cosines
DOF = 6
"""Joint count of every compiled family (chain joints = ``q`` entries, no coupling)."""

DH_COLUMNS = ("a", "alpha", "d", "theta", "is_prismatic", "cos_alpha", "sin_alpha", "right")
"""Columns of a packed DH row (:func:`pack_dh`); ``right`` is +1 / -1 for alpha = +-90 deg."""
_NCOL = len(DH_COLUMNS)

# Layout of ``params`` (flat float64): offsets of each block.
_FAMILY = 0  # (1,) the family id (SPHERICAL_WRIST, UR)
_DH = _FAMILY + 1  # (6, 8) packed DH rows, see DH_COLUMNS
_LOWER = _DH + _NCOL * DOF  # (6,) lower limits (rad or m), -inf allowed
_UPPER = _LOWER + DOF  # (6,) upper limits, +inf allowed
_BASE_INV = _UPPER + DOF  # (4, 4) inverse of T_world_base, row-major
_TOOL_INV = _BASE_INV + 16  # (4, 4) inverse of T_flange_tool, row-major
_MID = _TOOL_INV + 16  # (6,) mid-limits (the default reference)
_CHAIN = _MID + DOF  # (7, 3, 4) top rows of the robot's chain transforms _K (FK check)
_TOLS = _CHAIN + 12 * (DOF + 1)  # tolerances, in the order of _TOL_NAMES
_TOL_NAMES = (
    "TRIG_TOL",  # optik.trig: trig equation tangent / degenerate tests
    "SINGULAR_EPS",  # optik.analytic._base: a = b = 0 in angles()
    "FREE_RHS_TOL",  # optik.analytic._base: c = 0 in angles() (free joint)
    "LIMIT_TOLERANCE",  # optik.limits: slack on a bound
    "VERIFY_TOLERANCE",  # optik.analytic._base: FK check, m and rad
    "DUPLICATE_TOLERANCE",  # optik.analytic._base: two branches are one
    "ROTATION_TOLERANCE",  # optik.spatial: max |R^T R - I| of a target
    "BOTTOM_ROW_TOL",  # optik.spatial.as_pose: |last row - (0 0 0 1)|
)
_N_PARAMS = _TOLS + len(_TOL_NAMES)
PARAMS_LAYOUT: dict[str, tuple[int, tuple[int, ...]]] = {
    "family": (_FAMILY, (1,)),
    "dh": (_DH, (DOF, _NCOL)),
    "lower": (_LOWER, (DOF,)),
    "upper": (_UPPER, (DOF,)),
    "T_base_world": (_BASE_INV, (4, 4)),
    "T_tool_flange": (_TOOL_INV, (4, 4)),
    "mid_limits": (_MID, (DOF,)),
    "chain": (_CHAIN, (DOF + 1, 3, 4)),
    "tolerances": (_TOLS, (len(_TOL_NAMES),)),
}
"""Name -> (offset, shape) of each block of ``params``."""

_BOTTOM_ROW_TOL = 1e-9  # the literal of optik.spatial.as_pose
_WRIST_SINGULAR = 1e-10  # |sin q5| below which only q4 + q6 (or q6 alone) is defined
_RADICAND_TOL = 1e-12  # RRP arm: a negative radicand above -tol * max(rho^2, 1) is 0
_TWO_PI = 2.0 * math.pi


# ---------------------------------------------------------------------- packing (Python)
def pack_dh(rows: Sequence[DHJoint]) -> FloatArray:
    """Standard DH rows as a (dof, 8) array, columns :data:`DH_COLUMNS`.

    ``a, alpha, d, theta`` (m, rad; ``theta`` is the revolute offset, ``d`` the prismatic
    one), ``is_prismatic`` (0 or 1), then derived constants the kernels would otherwise
    recompute at every call: ``cos alpha``, ``sin alpha`` and ``right``
    (:func:`optik.analytic._base.is_right_angle`: +1 / -1 for alpha = +-90 deg, else 0).
    """
    return np.array(
        [
            [
                r.a,
                r.alpha,
                r.d,
                r.theta,
                1.0 if r.kind == "prismatic" else 0.0,
                math.cos(r.alpha),
                math.sin(r.alpha),
                float(is_right_angle(r.alpha)),
            ]
            for r in rows
        ],
        dtype=np.float64,
    ).reshape(-1, _NCOL)


def pack_params(robot: Robot, family: int) -> FloatArray:
    """The flat parameter vector of a six-joint robot for the compiled pipeline.

    Everything a kernel needs about the robot, in one argument (see
    :data:`PARAMS_LAYOUT`): the family id, packed DH rows, limits, base and tool
    inverses, mid-limits, the robot's own chain transforms ``_K`` (the FK check uses the
    kinematics of ``Robot.fk``, not the DH rows) and the tolerances. The caller caches it
    per robot (a :class:`~optik.Robot` does not change after construction;
    ``Robot.with_limits`` starts a fresh cache).

    The DH rows and the two transforms are the family's table of the robot
    (``AnalyticFamily.model``): the robot's own standard DH rows with its base and tool,
    or the equivalent table built from its joint axes with the world pose of its frame 0
    (stored as ``T_base_world``) and the tool in its last frame (``T_tool_flange``).

    Args:
        robot: a robot of a compiled family (six joints, no coupling) that fits it.
        family: the family id (:data:`SPHERICAL_WRIST` or :data:`UR`).
    """
    model = next(f for f in FAMILIES.values() if f.kernel == family).model(robot)
    params = np.empty(_N_PARAMS)
    params[_FAMILY] = family
    params[_DH:_LOWER] = pack_dh(model.rows).reshape(-1)
    params[_LOWER:_UPPER] = robot.lower
    params[_UPPER:_BASE_INV] = robot.upper
    params[_BASE_INV:_TOOL_INV] = invert_transform(model.T_world_0).reshape(-1)
    params[_TOOL_INV:_MID] = invert_transform(model.T_n_tool).reshape(-1)
    params[_MID:_CHAIN] = robot.mid_limits
    params[_CHAIN:_TOLS] = robot.chain.K[:, :3, :].reshape(-1)
    params[_TOLS:] = (
        TRIG_TOL,
        SINGULAR_EPS,
        FREE_RHS_TOL,
        LIMIT_TOLERANCE,
        VERIFY_TOLERANCE,
        DUPLICATE_TOLERANCE,
        ROTATION_TOLERANCE,
        _BOTTOM_ROW_TOL,
    )
    return params


def params_of(robot: Robot, family: int) -> FloatArray:
    """:func:`pack_params` of ``robot``, cached in the robot (do not modify it)."""
    kernel = _PACKERS[family]
    return robot.cached(kernel)


def _pack_spherical_wrist(robot: Robot) -> FloatArray:
    return pack_params(robot, SPHERICAL_WRIST)


def _pack_ur(robot: Robot) -> FloatArray:
    return pack_params(robot, UR)


_PACKERS = {SPHERICAL_WRIST: _pack_spherical_wrist, UR: _pack_ur}


def raw_candidates(
    kernel: Any, robot: Robot, family: int, T_0_target: FloatArray, q_ref: FloatArray
) -> list[FloatArray]:
    """The raw branches (before wrapping and verification) of a family's candidate kernel.

    Args:
        kernel: :func:`spherical_wrist_candidates` or :func:`ur_candidates`.
        robot: the robot.
        family: the family's kernel id (``AnalyticFamily.kernel``).
        T_0_target: 4x4 flange target in frame 0.
        q_ref: (dof,) reference for joints left free at singularities.
    """
    params = params_of(robot, family)
    out = np.empty((MAX_BRANCHES, DOF))
    n = kernel(
        dh_block(params),
        np.ascontiguousarray(T_0_target, dtype=np.float64),
        np.ascontiguousarray(q_ref, dtype=np.float64).reshape(1, -1),
        0,
        tolerances(params),
        out,
    )
    return list(out[:n])


def tolerances(params: FloatArray) -> FloatArray:
    """The tolerance block of ``params`` (a view), in the order of ``_TOL_NAMES``."""
    return params[_TOLS:]


def mid_limits(params: FloatArray) -> FloatArray:
    """The mid-limits block of ``params`` (a view), the default reference configuration."""
    return params[_MID:_CHAIN]


def dh_block(params: FloatArray) -> FloatArray:
    """The (6, 8) packed DH block of ``params`` (a view)."""
    return params[_DH:_LOWER].reshape(DOF, _NCOL)


def pose_tolerances() -> tuple[float, float]:
    """``(ROTATION_TOLERANCE, bottom-row tolerance)`` for :func:`first_bad_pose`."""
    return ROTATION_TOLERANCE, _BOTTOM_ROW_TOL


@_jit
def _sincos_block(flat: np.ndarray, n: int) -> None:
    """Sines and cosines of the first ``n`` values of the pipeline's scratch block.

    ``flat`` is the (24, 6) block (rows, their sines, their cosines) seen flat: value
    ``i`` gets its sine at ``48 + i`` and its cosine at ``96 + i``. One branch-free loop
    over contiguous memory when every value is in range; the offsets are compile-time
    constants, so LLVM sees that the writes never overlap the reads and vectorises it.
    """
    s0 = _SIN * DOF
    c0 = _COS * DOF
    inside = True
    for i in range(n):
        if not abs(flat[i]) < _SINCOS_RANGE:
            inside = False
    if inside:
        for i in range(n):
            flat[s0 + i], flat[c0 + i] = _sincos_core(flat[i])
    else:
        for i in range(n):
            flat[s0 + i], flat[c0 + i] = sincos(flat[i])


@_jit
def _rot(
    ct: float, st: float, ca: float, sa: float
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """Rotation block of ``Rz(theta) Rx(alpha)`` from the cosines and sines, row-major."""
    return (ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca)


@_jit
def _dh_rotation(
    theta: float, ca: float, sa: float
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """Rotation block of ``Rz(theta) Rx(alpha)``, row-major 9-tuple."""
    st, ct = sincos(theta)
    return _rot(ct, st, ca, sa)


@_jit
def _mul3(
    A: tuple[float, float, float, float, float, float, float, float, float],
    B: tuple[float, float, float, float, float, float, float, float, float],
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """``A @ B`` for row-major 3x3 9-tuples."""
    return (
        A[0] * B[0] + A[1] * B[3] + A[2] * B[6],
        A[0] * B[1] + A[1] * B[4] + A[2] * B[7],
        A[0] * B[2] + A[1] * B[5] + A[2] * B[8],
        A[3] * B[0] + A[4] * B[3] + A[5] * B[6],
        A[3] * B[1] + A[4] * B[4] + A[5] * B[7],
        A[3] * B[2] + A[4] * B[5] + A[5] * B[8],
        A[6] * B[0] + A[7] * B[3] + A[8] * B[6],
        A[6] * B[1] + A[7] * B[4] + A[8] * B[7],
        A[6] * B[2] + A[7] * B[5] + A[8] * B[8],
    )


@_jit
def _mul3tn(
    A: tuple[float, float, float, float, float, float, float, float, float],
    B: tuple[float, float, float, float, float, float, float, float, float],
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """``A^T @ B`` for row-major 3x3 9-tuples."""
    return (
        A[0] * B[0] + A[3] * B[3] + A[6] * B[6],
        A[0] * B[1] + A[3] * B[4] + A[6] * B[7],
        A[0] * B[2] + A[3] * B[5] + A[6] * B[8],
        A[1] * B[0] + A[4] * B[3] + A[7] * B[6],
        A[1] * B[1] + A[4] * B[4] + A[7] * B[7],
        A[1] * B[2] + A[4] * B[5] + A[7] * B[8],
        A[2] * B[0] + A[5] * B[3] + A[8] * B[6],
        A[2] * B[1] + A[5] * B[4] + A[8] * B[7],
        A[2] * B[2] + A[5] * B[5] + A[8] * B[8],
    )


Rows12 = tuple[float, float, float, float, float, float, float, float, float, float, float, float]
"""The top three rows of a 4x4 transform, row-major."""


@_jit
def _row_times_inverse_dh(
    t0: float,
    t1: float,
    t2: float,
    t3: float,
    R: tuple[float, float, float, float, float, float, float, float, float],
    inv_p: tuple[float, float, float],
) -> tuple[float, float, float, float]:
    """One row ``(t0, t1, t2, t3)`` of a transform times ``A^-1 = [R^T, -R^T p]``."""
    return (
        t0 * R[0] + t1 * R[1] + t2 * R[2],
        t0 * R[3] + t1 * R[4] + t2 * R[5],
        t0 * R[6] + t1 * R[7] + t2 * R[8],
        t0 * inv_p[0] + t1 * inv_p[1] + t2 * inv_p[2] + t3,
    )


@_jit
def _times_inverse_dh(
    T: Rows12,
    ct: float,
    st: float,
    ca: float,
    sa: float,
    a: float,
    d: float,
) -> Rows12:
    """``T[:3] @ A^-1`` for the top rows of ``T`` (a row-major 12-tuple).

    ``A`` is the DH matrix (theta, d, a, alpha) and ``A^-1 = [R^T, -R^T p]`` with
    ``p = (a cos theta, a sin theta, d)``; ``ct, st`` are ``cos theta, sin theta``.
    """
    R = _rot(ct, st, ca, sa)
    px = a * ct
    py = a * st
    inv_p = (
        -(R[0] * px + R[3] * py + R[6] * d),
        -(R[1] * px + R[4] * py + R[7] * d),
        -(R[2] * px + R[5] * py + R[8] * d),
    )
    r0 = _row_times_inverse_dh(T[0], T[1], T[2], T[3], R, inv_p)
    r1 = _row_times_inverse_dh(T[4], T[5], T[6], T[7], R, inv_p)
    r2 = _row_times_inverse_dh(T[8], T[9], T[10], T[11], R, inv_p)
    return (r0[0], r0[1], r0[2], r0[3], r1[0], r1[1], r1[2], r1[3], r2[0], r2[1], r2[2], r2[3])


@_jit
def _cos_sin(theta: float, t: float, x: float, y: float) -> tuple[float, float]:
    """``cos, sin`` of ``theta``, which the caller formed from ``t = atan2(y, x)``.

    When ``theta == t`` (a zero DH offset) they are ``x / r, y / r`` (``r = hypot(x, y)``
    > 0), one square root and two divisions; otherwise :func:`sincos`.
    """
    if theta == t:
        r = math.sqrt(x * x + y * y)
        if r > 0.0:
            return x / r, y / r
    st, ct = sincos(theta)
    return ct, st


@_jit
def _transform_target(params: np.ndarray, T: np.ndarray, k: int, out: np.ndarray) -> None:
    """``out <- T_base_world @ T[k] @ T_tool_flange``: the flange target in frame 0."""
    B = _BASE_INV
    E = _TOOL_INV
    for i in range(4):
        b0 = params[B + 4 * i]
        b1 = params[B + 4 * i + 1]
        b2 = params[B + 4 * i + 2]
        b3 = params[B + 4 * i + 3]
        bt0 = b0 * T[k, 0, 0] + b1 * T[k, 1, 0] + b2 * T[k, 2, 0] + b3 * T[k, 3, 0]
        bt1 = b0 * T[k, 0, 1] + b1 * T[k, 1, 1] + b2 * T[k, 2, 1] + b3 * T[k, 3, 1]
        bt2 = b0 * T[k, 0, 2] + b1 * T[k, 1, 2] + b2 * T[k, 2, 2] + b3 * T[k, 3, 2]
        bt3 = b0 * T[k, 0, 3] + b1 * T[k, 1, 3] + b2 * T[k, 2, 3] + b3 * T[k, 3, 3]
        for j in range(4):
            out[i, j] = (
                bt0 * params[E + j]
                + bt1 * params[E + 4 + j]
                + bt2 * params[E + 8 + j]
                + bt3 * params[E + 12 + j]
            )


# ---------------------------------------------------------------------- closed forms
# Packed DH columns (see DH_COLUMNS).
_A, _ALPHA, _D, _THETA, _PRISMATIC, _CA, _SA, _RIGHT = 0, 1, 2, 3, 4, 5, 6, 7


@_jit
def _sw_wrist(
    dh: np.ndarray,
    R36: tuple[float, float, float, float, float, float, float, float, float],
    ref: np.ndarray,
    kr: int,
    arm0: float,
    arm1: float,
    arm2: float,
    cand: np.ndarray,
    n: int,
) -> int:
    """Append the wrist branches (q4, q5, q6) of ``A4 A5 A6 = R36`` after the arm values.

    Writes rows ``n, n + 1`` (or only ``n`` at the wrist singularity) of ``cand``;
    returns the new row count.
    """
    th4 = dh[3, _THETA]
    th5 = dh[4, _THETA]
    th6 = dh[5, _THETA]
    ca4 = dh[3, _CA]
    sa4 = dh[3, _SA]
    ca5 = dh[4, _CA]
    sa5 = dh[4, _SA]
    ca6 = dh[5, _CA]
    sa6 = dh[5, _SA]
    s4 = dh[3, _RIGHT]
    s5 = dh[4, _RIGHT]
    # M = R36 Rx(alpha6)^T
    M = _mul3(R36, (1.0, 0.0, 0.0, 0.0, ca6, sa6, 0.0, -sa6, ca6))
    c5 = -s4 * s5 * M[8]
    s5_mag = math.sqrt(M[2] * M[2] + M[5] * M[5])
    count = 1 if s5_mag < _WRIST_SINGULAR else 2
    for b in range(count):
        if count == 1:
            t5 = math.atan2(0.0, c5)
            t4 = th4 + ref[kr, 3]
            sn4, c4 = sincos(t4)
            sn5t, c5t = sincos(t5)
        else:
            sign = 1.0 if b == 0 else -1.0
            t5 = math.atan2(sign * s5_mag, c5)
            t4 = math.atan2(s5 * sign * M[5], s5 * sign * M[2])
            c4, sn4 = _cos_sin(t4, t4, s5 * sign * M[2], s5 * sign * M[5])
            c5t, sn5t = _cos_sin(t5, t5, c5, sign * s5_mag)
        # q6 from the residual rotation N = (A4 A5)^T M given q4 and q5, not from M's row
        # alone: near the singularity q4 carries an error of eps / sin(q5), which this q6
        # absorbs exactly.
        P = _mul3(_rot(c4, sn4, ca4, sa4), _rot(c5t, sn5t, ca5, sa5))
        n00 = P[0] * M[0] + P[3] * M[3] + P[6] * M[6]
        n10 = P[1] * M[0] + P[4] * M[3] + P[7] * M[6]
        t6 = math.atan2(n10, n00)
        cand[n, 0] = arm0
        cand[n, 1] = arm1
        cand[n, 2] = arm2
        cand[n, 3] = t4 - th4
        cand[n, 4] = t5 - th5
        cand[n, 5] = t6 - th6
        n += 1
    return n


@_jit
def spherical_wrist_candidates(
    dh: np.ndarray, T: np.ndarray, ref: np.ndarray, kr: int, tols: np.ndarray, cand: np.ndarray
) -> int:
    """Raw branches of the 3+3 partition (RRR or RRP arm, spherical wrist) into ``cand``.

    Args:
        dh: (6, 8) packed DH rows (:func:`pack_dh`).
        T: (4, 4) flange target in the chain's frame 0.
        ref: (M, 6) reference configurations; row ``kr`` is used (free joints at
            singularities take it).
        kr: the row of ``ref``.
        tols: the tolerance block of ``params`` (``TRIG_TOL``, ``SINGULAR_EPS``,
            ``FREE_RHS_TOL`` first).
        cand: (>= 8, 6) output rows, joint values (rad, m) without wrapping.

    Returns:
        The number of rows written (0 to 8), in the family's order: shoulder, then
        elbow (or stroke sign), then wrist (``sin q5 >= 0`` first).
    """
    trig_tol = tols[0]
    eps = tols[1]
    free_tol = tols[2]
    a1 = dh[0, _A]
    d1 = dh[0, _D]
    th1 = dh[0, _THETA]
    a2 = dh[1, _A]
    d2 = dh[1, _D]
    th2 = dh[1, _THETA]
    a3 = dh[2, _A]
    d3 = dh[2, _D]
    th3 = dh[2, _THETA]
    d4 = dh[3, _D]
    d6 = dh[5, _D]
    ca1, sa1, ca2, sa2 = dh[0, _CA], dh[0, _SA], dh[1, _CA], dh[1, _SA]
    ca3, sa3 = dh[2, _CA], dh[2, _SA]
    s1 = dh[0, _RIGHT]
    rrp = dh[2, _PRISMATIC] != 0.0
    R = (T[0, 0], T[0, 1], T[0, 2], T[1, 0], T[1, 1], T[1, 2], T[2, 0], T[2, 1], T[2, 2])
    # 1. Wrist centre W = p - d6 R (0, sin alpha6, cos alpha6).
    sa6 = dh[5, _SA]
    ca6 = dh[5, _CA]
    wx = T[0, 3] - d6 * (R[0] * 0.0 + R[1] * sa6 + R[2] * ca6)
    wy = T[1, 3] - d6 * (R[3] * 0.0 + R[4] * sa6 + R[5] * ca6)
    wz = T[2, 3] - d6 * (R[6] * 0.0 + R[7] * sa6 + R[8] * ca6)
    # 2. Arm joints from W = A1 A2 A3 (0, 0, d4).
    b3 = -sa3 * d4
    if rrp:
        st3, ct3 = sincos(th3)
        ex = ct3 * a3 - st3 * b3
        ey = st3 * a3 + ct3 * b3
        s2 = dh[1, _RIGHT]
        h = d2 + s2 * ey
        R3 = _rot(ct3, st3, ca3, sa3)  # constant: joint 3 slides
    else:
        ex = 0.0
        s2 = 0.0
        h = d2 + d3 + ca3 * d4
        R3 = _rot(1.0, 0.0, ca3, sa3)
    n = 0
    n1, t1a, t1b = trig_roots(wy, -wx, -s1 * h, th1 + ref[kr, 0], trig_tol, eps, free_tol)
    for i1 in range(n1):
        t1 = t1a if i1 == 0 else t1b
        sn1, c1 = sincos(t1)
        vx = c1 * wx + sn1 * wy - a1
        vy = s1 * (wz - d1)
        rho2 = vx * vx + vy * vy
        phi_v = math.atan2(vy, vx)
        q1 = t1 - th1
        theta1 = th1 + q1
        # A zero offset (the usual case) reuses c1, s1.
        R1 = _rot(c1, sn1, ca1, sa1) if theta1 == t1 else _dh_rotation(theta1, ca1, sa1)
        if not rrp:
            rhs = rho2 - a2 * a2 - a3 * a3 - b3 * b3
            n3, t3a, t3b = trig_roots(
                2 * a2 * a3, -2 * a2 * b3, rhs, th3 + ref[kr, 2], trig_tol, eps, free_tol
            )
            for i3 in range(n3):
                t3 = t3a if i3 == 0 else t3b
                sn3, c3 = sincos(t3)
                ux = a2 + a3 * c3 - b3 * sn3
                uy = a3 * sn3 + b3 * c3
                t2 = phi_v - math.atan2(uy, ux)
                q2 = t2 - th2
                q3 = t3 - th3
                theta3 = th3 + q3
                R3 = _rot(c3, sn3, ca3, sa3) if theta3 == t3 else _dh_rotation(theta3, ca3, sa3)
                R03 = _mul3(_mul3(R1, _dh_rotation(th2 + q2, ca2, sa2)), R3)
                n = _sw_wrist(dh, _mul3tn(R03, R), ref, kr, q1, q2, q3, cand, n)
        else:
            base = ex + a2
            radicand = rho2 - base * base
            if radicand < -_RADICAND_TOL * max(rho2, 1.0):
                continue
            root = math.sqrt(max(radicand, 0.0))
            n_len = 1 if root == 0.0 else 2
            for iL in range(n_len):
                L = root if iL == 0 else -root
                t2 = phi_v - math.atan2(-s2 * L, base)
                q2 = t2 - th2
                q3 = L - ca3 * d4 - d3
                R03 = _mul3(_mul3(R1, _dh_rotation(th2 + q2, ca2, sa2)), R3)
                n = _sw_wrist(dh, _mul3tn(R03, R), ref, kr, q1, q2, q3, cand, n)
    return n


@_inline
def _ur_wrist_origin(
    dh: np.ndarray, T16: Rows12, c5t: float, sn5t: float, c6t: float, sn6t: float
) -> tuple[float, float, float]:
    """Frame 4 of a UR-type arm from ``T_16`` and joints 5 and 6 (cosine, sine).

    Returns its origin's (x, y) in the plane of joints 2-4 and the angle of its first
    column (theta2 + theta3 + theta4).
    """
    T15 = _times_inverse_dh(T16, c6t, sn6t, dh[5, _CA], dh[5, _SA], dh[5, _A], dh[5, _D])
    T14 = _times_inverse_dh(T15, c5t, sn5t, dh[4, _CA], dh[4, _SA], dh[4, _A], dh[4, _D])
    return T14[3], T14[7], math.atan2(T14[4], T14[0])


@_jit
def _ur_reachable_q6(dh: np.ndarray, T16: Rows12, c5t: float, sn5t: float, t6_ref: float) -> float:
    """At the wrist singularity, a theta6 (rad) whose elbow can reach, nearest ``t6_ref``.

    It puts the elbow's squared reach ``x^2 + y^2`` at the middle of its range
    ``[(a2 - a3)^2, (a2 + a3)^2]``, or as near as it gets (then on the range if any q6 is).

    With axes 4 and 6 aligned, the origin of frame 4 circles axis 6 as q6 turns, in the
    plane of the parallel joints, so ``x^2 + y^2 = A + B cos t6 + C sin t6`` exactly.
    """
    a2 = dh[1, _A]
    a3 = dh[2, _A]
    x, y, _ = _ur_wrist_origin(dh, T16, c5t, sn5t, 1.0, 0.0)
    r0 = x * x + y * y
    x, y, _ = _ur_wrist_origin(dh, T16, c5t, sn5t, 0.0, 1.0)
    r1 = x * x + y * y
    x, y, _ = _ur_wrist_origin(dh, T16, c5t, sn5t, -1.0, 0.0)
    r2 = x * x + y * y
    A = 0.5 * (r0 + r2)
    B = 0.5 * (r0 - r2)
    C = r1 - A
    R = math.sqrt(B * B + C * C)
    middle = 0.5 * ((a2 - a3) ** 2 + (a2 + a3) ** 2)
    if R < 1e-300:
        return t6_ref
    phi = math.atan2(C, B)
    off = math.acos(min(max((middle - A) / R, -1.0), 1.0))
    best = t6_ref
    gap = np.inf
    for t in (phi + off, phi - off):
        d = abs(wrap_angle(t - t6_ref))
        if d < gap:
            gap = d
            best = t6_ref + wrap_angle(t - t6_ref)
    return best


@_inline
def _ur_elbow(
    dh: np.ndarray,
    T16: Rows12,
    t1: float,
    t5: float,
    t6: float,
    c5t: float,
    sn5t: float,
    c6t: float,
    sn6t: float,
    ref: np.ndarray,
    kr: int,
    tols: np.ndarray,
    cand: np.ndarray,
    n: int,
) -> int:
    """The elbow branches (joints 2-4, a planar two-link arm) for given joints 1, 5, 6.

    Writes rows ``n`` onwards of ``cand``; returns the new row count.
    """
    th2 = dh[1, _THETA]
    th3 = dh[2, _THETA]
    a2 = dh[1, _A]
    a3 = dh[2, _A]
    x, y, t234 = _ur_wrist_origin(dh, T16, c5t, sn5t, c6t, sn6t)
    phi = math.atan2(y, x)
    n3, t3a, t3b = trig_roots(
        2 * a2 * a3,
        0.0,
        x * x + y * y - a2 * a2 - a3 * a3,
        th3 + ref[kr, 2],
        tols[0],
        tols[1],
        tols[2],
    )
    for i3 in range(n3):
        t3 = t3a if i3 == 0 else t3b
        sn3, c3 = sincos(t3)
        t2 = phi - math.atan2(a3 * sn3, a2 + a3 * c3)
        t4 = t234 - t2 - t3
        cand[n, 0] = t1 - dh[0, _THETA]
        cand[n, 1] = t2 - th2
        cand[n, 2] = t3 - th3
        cand[n, 3] = t4 - dh[3, _THETA]
        cand[n, 4] = t5 - dh[4, _THETA]
        cand[n, 5] = t6 - dh[5, _THETA]
        n += 1
    return n


@_jit
def ur_candidates(
    dh: np.ndarray, T: np.ndarray, ref: np.ndarray, kr: int, tols: np.ndarray, cand: np.ndarray
) -> int:
    """Raw branches of a UR-type arm (three parallel axes, joints 2-4) into ``cand``.

    Args:
        dh: (6, 8) packed DH rows (:func:`pack_dh`).
        T: (4, 4) flange target in the chain's frame 0.
        ref: (M, 6) reference configurations; row ``kr`` is used (free joints at
            singularities take it).
        kr: the row of ``ref``.
        tols: the tolerance block of ``params`` (``TRIG_TOL``, ``SINGULAR_EPS``,
            ``FREE_RHS_TOL`` first).
        cand: (>= 8, 6) output rows, joint angles (rad) without wrapping.

    Returns:
        The number of rows written (0 to 8), in the family's order: shoulder, then wrist
        (``sin q5 >= 0`` first), then elbow.
    """
    trig_tol = tols[0]
    eps = tols[1]
    free_tol = tols[2]
    th1 = dh[0, _THETA]
    th5 = dh[4, _THETA]
    th6 = dh[5, _THETA]
    h = dh[1, _D] + dh[2, _D] + dh[3, _D]
    d6 = dh[5, _D]
    ca1, sa1 = dh[0, _CA], dh[0, _SA]
    # 1. p5 = p - d6 z6; joint 1 from s1 p5x - c1 p5y = h.
    p5x = T[0, 3] - d6 * T[0, 2]
    p5y = T[1, 3] - d6 * T[1, 2]
    n = 0
    n1, t1a, t1b = trig_roots(-p5y, p5x, h, th1 + ref[kr, 0], trig_tol, eps, free_tol)
    for i1 in range(n1):
        t1 = t1a if i1 == 0 else t1b
        # 2. T_16 = A1^-1 T (its top rows, a row-major 12-tuple).
        theta1 = th1 + (t1 - th1)
        st1, ct1 = sincos(theta1)
        R1 = _rot(ct1, st1, ca1, sa1)
        px = dh[0, _A] * ct1
        py = dh[0, _A] * st1
        pz = dh[0, _D]
        p0 = R1[0] * px + R1[3] * py + R1[6] * pz  # R1^T p
        p1 = R1[1] * px + R1[4] * py + R1[7] * pz
        p2 = R1[2] * px + R1[5] * py + R1[8] * pz
        T16 = (
            R1[0] * T[0, 0] + R1[3] * T[1, 0] + R1[6] * T[2, 0],
            R1[0] * T[0, 1] + R1[3] * T[1, 1] + R1[6] * T[2, 1],
            R1[0] * T[0, 2] + R1[3] * T[1, 2] + R1[6] * T[2, 2],
            R1[0] * T[0, 3] + R1[3] * T[1, 3] + R1[6] * T[2, 3] - p0,
            R1[1] * T[0, 0] + R1[4] * T[1, 0] + R1[7] * T[2, 0],
            R1[1] * T[0, 1] + R1[4] * T[1, 1] + R1[7] * T[2, 1],
            R1[1] * T[0, 2] + R1[4] * T[1, 2] + R1[7] * T[2, 2],
            R1[1] * T[0, 3] + R1[4] * T[1, 3] + R1[7] * T[2, 3] - p1,
            R1[2] * T[0, 0] + R1[5] * T[1, 0] + R1[8] * T[2, 0],
            R1[2] * T[0, 1] + R1[5] * T[1, 1] + R1[8] * T[2, 1],
            R1[2] * T[0, 2] + R1[5] * T[1, 2] + R1[8] * T[2, 2],
            R1[2] * T[0, 3] + R1[5] * T[1, 3] + R1[8] * T[2, 3] - p2,
        )
        # cos q5 = T_16[2, 2] and sin q5 (c6, -s6) = T_16[2, :2]: atan2 of both keeps q5
        # accurate near 0 and pi, where the cosine alone is flat.
        s5_mag = math.sqrt(T16[8] * T16[8] + T16[9] * T16[9])
        c5 = T16[10]
        n_wrist = 1 if s5_mag < _WRIST_SINGULAR else 2
        for iw in range(n_wrist):
            sign = 1.0 if iw == 0 else -1.0
            if n_wrist == 2:
                t5 = math.atan2(sign * s5_mag, c5)
                t6 = math.atan2(-sign * T16[9], sign * T16[8])
                theta5 = th5 + (t5 - th5)
                theta6 = th6 + (t6 - th6)
                c5t, sn5t = _cos_sin(theta5, t5, c5, sign * s5_mag)
                c6t, sn6t = _cos_sin(theta6, t6, sign * T16[8], -sign * T16[9])
                n = _ur_elbow(dh, T16, t1, t5, t6, c5t, sn5t, c6t, sn6t, ref, kr, tols, cand, n)
                continue
            # Wrist singular (axes 4 and 6 aligned): q6 is free. It takes the reference,
            # unless the elbow then cannot reach; then the q6 whose elbow reach is the
            # middle of the elbow's range (nearest the reference of the two).
            t5 = math.atan2(0.0, c5)
            sn5t, c5t = sincos(t5)
            t6 = th6 + ref[kr, 5]
            sn6t, c6t = sincos(t6)
            before = n
            n = _ur_elbow(dh, T16, t1, t5, t6, c5t, sn5t, c6t, sn6t, ref, kr, tols, cand, n)
            if n == before:
                t6 = _ur_reachable_q6(dh, T16, c5t, sn5t, t6)
                sn6t, c6t = sincos(t6)
                n = _ur_elbow(dh, T16, t1, t5, t6, c5t, sn5t, c6t, sn6t, ref, kr, tols, cand, n)
    return n


@_jit
def candidates(
    family: int,
    dh: np.ndarray,
    T: np.ndarray,
    ref: np.ndarray,
    kr: int,
    tols: np.ndarray,
    cand: np.ndarray,
) -> int:
    """Raw branches of compiled family ``family`` (:data:`SPHERICAL_WRIST`, :data:`UR`)."""
    if family == SPHERICAL_WRIST:
        return spherical_wrist_candidates(dh, T, ref, kr, tols, cand)
    if family == UR:
        return ur_candidates(dh, T, ref, kr, tols, cand)
    return 0


# ---------------------------------------------------------------------- validation
# ---------------------------------------------------------------------- pipeline
@_jit
def _fk_shared(params: np.ndarray, block: np.ndarray, r: int, pre: np.ndarray, depth: int) -> int:
    """Forward kinematics of ``block[r]`` into ``pre[n]``, reusing the previous call's prefix.

    The chain product of :func:`optik._kernels.fk_into`, ``K[0] M(q1) K[1] ... M(qn) K[n]``
    (``K`` the robot's ``_K``, stored in ``params``), with its arithmetic expression for
    expression (``_apply_motion`` then ``_right_multiply``), kept in scalars. The sines
    and cosines come precomputed in ``block[8 + r]`` and ``block[16 + r]``: given libm's
    values the pose is ``fk_into``'s bit for bit (a test checks it).

    ``pre`` (n + 2, 12) holds the top three rows of each prefix product, row-major:
    ``pre[i]`` is the product up to joint ``i`` (``pre[0] = K[0]``, set by the caller);
    ``pre[n + 1, :n]`` the joint values of the previous call, whose first ``depth``
    prefixes are valid. Leading joints equal to those are not recomputed (branches share
    their shoulder and arm joints). Returns the new ``depth`` (n).
    """
    n = block.shape[1]
    last = n + 1
    j = 0
    while j < depth and block[r, j] == pre[last, j]:
        j += 1
    a00, a01, a02, a03 = pre[j, 0], pre[j, 1], pre[j, 2], pre[j, 3]
    a10, a11, a12, a13 = pre[j, 4], pre[j, 5], pre[j, 6], pre[j, 7]
    a20, a21, a22, a23 = pre[j, 8], pre[j, 9], pre[j, 10], pre[j, 11]
    for i in range(j, n):
        t = block[r, i]
        pre[last, i] = t
        # _apply_motion(T, prismatic[i], t)
        if params[_DH + _NCOL * i + _PRISMATIC] != 0.0:
            a03 += t * a02
            a13 += t * a12
            a23 += t * a22
        else:
            s = block[_SIN + r, i]
            c = block[_COS + r, i]
            a00, a01 = c * a00 + s * a01, -s * a00 + c * a01
            a10, a11 = c * a10 + s * a11, -s * a10 + c * a11
            a20, a21 = c * a20 + s * a21, -s * a20 + c * a21
        # _right_multiply(T, K[i + 1], out)
        o = _CHAIN + 12 * (i + 1)
        k00, k01, k02, k03 = params[o], params[o + 1], params[o + 2], params[o + 3]
        k10, k11, k12, k13 = params[o + 4], params[o + 5], params[o + 6], params[o + 7]
        k20, k21, k22, k23 = params[o + 8], params[o + 9], params[o + 10], params[o + 11]
        a00, a01, a02, a03 = (
            a00 * k00 + a01 * k10 + a02 * k20,
            a00 * k01 + a01 * k11 + a02 * k21,
            a00 * k02 + a01 * k12 + a02 * k22,
            a00 * k03 + a01 * k13 + a02 * k23 + a03,
        )
        a10, a11, a12, a13 = (
            a10 * k00 + a11 * k10 + a12 * k20,
            a10 * k01 + a11 * k11 + a12 * k21,
            a10 * k02 + a11 * k12 + a12 * k22,
            a10 * k03 + a11 * k13 + a12 * k23 + a13,
        )
        a20, a21, a22, a23 = (
            a20 * k00 + a21 * k10 + a22 * k20,
            a20 * k01 + a21 * k11 + a22 * k21,
            a20 * k02 + a21 * k12 + a22 * k22,
            a20 * k03 + a21 * k13 + a22 * k23 + a23,
        )
        k = i + 1
        pre[k, 0], pre[k, 1], pre[k, 2], pre[k, 3] = a00, a01, a02, a03
        pre[k, 4], pre[k, 5], pre[k, 6], pre[k, 7] = a10, a11, a12, a13
        pre[k, 8], pre[k, 9], pre[k, 10], pre[k, 11] = a20, a21, a22, a23
    return n


@_jit
def _wrap_row(params: np.ndarray, rows: np.ndarray, r: int, ref: np.ndarray, kr: int) -> None:
    """Revolute angles of ``rows[r]`` into the limits, the representative nearest ``ref[kr]``.

    The steps of :func:`optik.analytic.wrap_into_limits`, bit for bit: numpy's floor-mod,
    ``ceil`` / ``floor`` with 1e-12 slack, round half to even, clamps.
    """
    for j in range(rows.shape[1]):
        if params[_DH + _NCOL * j + _PRISMATIC] != 0.0:
            continue
        lower = params[_LOWER + j]
        upper = params[_UPPER + j]
        base = ref[kr, j] + mod_two_pi(rows[r, j] - ref[kr, j] + math.pi) - math.pi
        if abs(ref[kr, j] - base) <= math.pi and lower <= base <= upper:
            # The usual case, without divisions: |ref - base| <= pi makes k_near below
            # exactly 0 (|x / 2 pi| <= 1/2 rounds half to even to 0), and a representative
            # inside the limits gives k_min <= 0 <= k_max, so k stays 0.
            rows[r, j] = base
            continue
        k = np.rint((ref[kr, j] - base) / _TWO_PI)
        k_min = np.ceil((lower - base) / _TWO_PI - 1e-12)
        k_max = np.floor((upper - base) / _TWO_PI + 1e-12)
        if math.isfinite(k_min):
            k = max(k, k_min)
        if math.isfinite(k_max):
            k = min(k, k_max)
        if k_min > k_max or not math.isfinite(k):
            k = 0.0
        rows[r, j] = base + _TWO_PI * k


@_jit
def _postprocess(
    params: np.ndarray,
    T: np.ndarray,
    k: int,
    ref: np.ndarray,
    kr: int,
    sort: bool,
    within: bool,
    rows: np.ndarray,
    flat: np.ndarray,
    n: int,
    pre: np.ndarray,
    Q: np.ndarray,
) -> int:
    """Wrap, filter by the limits, verify by FK, dedupe and sort ``rows[:n]`` into ``Q[k]``.

    ``T[k]`` is the validated world target of the tool and ``ref[kr]`` the reference;
    ``rows`` (24, 6) holds the raw branches in its first 8 rows (wrapped and compacted
    in place), then their sines and cosines, and ``flat`` is the same memory seen flat;
    ``pre`` (8, 12) is FK scratch. Returns the number of rows written to ``Q[k]``.
    """
    limit_tol = params[_TOLS + 3]
    verify_tol = params[_TOLS + 4]
    dup_tol = params[_TOLS + 5]
    dof = rows.shape[1]
    # 1. Finite rows, wrapped, inside the limits (when asked): compacted to rows[:kept].
    kept = 0
    for r in range(n):
        finite = True
        for j in range(dof):
            if not math.isfinite(rows[r, j]):
                finite = False
        if not finite:
            continue
        _wrap_row(params, rows, r, ref, kr)
        if within:
            inside = True
            for j in range(dof):
                v = rows[r, j]
                if not (
                    v >= params[_LOWER + j] - limit_tol and v <= params[_UPPER + j] + limit_tol
                ):
                    inside = False
            if not inside:
                continue
        if kept != r:
            for j in range(dof):
                rows[kept, j] = rows[r, j]
        kept += 1
    # 2. Sines and cosines of every kept joint value at once (a vectorised loop).
    _sincos_block(flat, kept * dof)
    # 3. Verify each by the robot's own chain (fk_into's arithmetic), dedupe in order.
    for i in range(12):
        pre[0, i] = params[_CHAIN + i]
    depth = 0
    m = 0
    for r in range(kept):
        depth = _fk_shared(params, rows, r, pre, depth)
        dx = pre[dof, 3] - T[k, 0, 3]
        dy = pre[dof, 7] - T[k, 1, 3]
        dz = pre[dof, 11] - T[k, 2, 3]
        if not math.sqrt(dx * dx + dy * dy + dz * dz) <= verify_tol:
            continue
        # R_rel = R_fk^T R_target; angle = atan2(|vee(R_rel - R_rel^T)| / 2, (tr - 1) / 2).
        rr = _mul3tn(
            (
                pre[dof, 0],
                pre[dof, 1],
                pre[dof, 2],
                pre[dof, 4],
                pre[dof, 5],
                pre[dof, 6],
                pre[dof, 8],
                pre[dof, 9],
                pre[dof, 10],
            ),
            (
                T[k, 0, 0],
                T[k, 0, 1],
                T[k, 0, 2],
                T[k, 1, 0],
                T[k, 1, 1],
                T[k, 1, 2],
                T[k, 2, 0],
                T[k, 2, 1],
                T[k, 2, 2],
            ),
        )
        sx = rr[7] - rr[5]
        sy = rr[2] - rr[6]
        sz = rr[3] - rr[1]
        s = 0.5 * math.sqrt(sx * sx + sy * sy + sz * sz)
        c = 0.5 * (rr[0] + rr[4] + rr[8] - 1.0)
        # atan2(s, c) <= s / c for s >= 0 < c: a tiny ratio accepts without the libm call.
        if not (s <= 0.5 * verify_tol * c or math.atan2(s, c) <= verify_tol):
            continue
        duplicate = False
        for other in range(m):
            diff = 0.0
            for j in range(dof):
                diff = max(diff, abs(rows[r, j] - Q[k, other, j]))
            if diff < dup_tol:
                duplicate = True
                break
        if duplicate:
            continue
        for j in range(dof):
            Q[k, m, j] = rows[r, j]
        m += 1
    if sort and m > 1:
        # 4. Stable insertion sort by ||q - ref|| (Python's list.sort is stable too); the
        # distances go in the (now free) sine rows.
        for r in range(m):
            acc = 0.0
            for j in range(dof):
                acc += (Q[k, r, j] - ref[kr, j]) ** 2
            rows[_SIN, r] = math.sqrt(acc)
        for r in range(1, m):
            key = rows[_SIN, r]
            p = r - 1
            while p >= 0 and rows[_SIN, p] > key:
                p -= 1
            if p + 1 < r:
                # Rotate rows p+1..r right by one (row r moves to p + 1).
                for j in range(dof):
                    moved = Q[k, r, j]
                    for i in range(r, p + 1, -1):
                        Q[k, i, j] = Q[k, i - 1, j]
                    Q[k, p + 1, j] = moved
                for i in range(r, p + 1, -1):
                    rows[_SIN, i] = rows[_SIN, i - 1]
                rows[_SIN, p + 1] = key
    return m


SORT = 1
"""Flag of :func:`solve` / :func:`solve_batch`: sort the branches by distance to ``ref``."""
WITHIN_LIMITS = 2
"""Flag of :func:`solve` / :func:`solve_batch`: drop branches outside the joint limits."""


@_jit
def solve(params: np.ndarray, T: np.ndarray, ref: np.ndarray, flags: int, out: np.ndarray) -> int:
    """The whole pipeline for one target: validate, solve, wrap, filter, verify, sort.

    Five arguments only: the numba dispatcher's cost grows with each (about 0.15 us per
    array), and a single call is meant to take a few microseconds.

    Args:
        params: the robot's parameter vector (:func:`pack_params`), family included.
        T: (4, 4) world target of the tool.
        ref: (6,) reference configuration (rad, m).
        flags: :data:`SORT` and / or :data:`WITHIN_LIMITS`.
        out: (8, 6) output rows.

    Returns:
        The number of branches written to ``out`` (0 to 8); -1 when ``T`` is not a valid
        pose (see :func:`pose_defect`), -2 when ``ref`` is not finite. The caller raises
        the matching optik error.
    """
    T1 = T[None]
    if pose_defect(T1, 0, params[_TOLS + 6], params[_TOLS + 7]) != 0:
        return -1
    for j in range(ref.shape[0]):
        if not math.isfinite(ref[j]):
            return -2
    # Scratch (a reshape is a C call: the per-pose path indexes instead), then the steps.
    ref1 = ref[None]
    T0 = np.empty((4, 4))
    pre = np.empty((DOF + 2, 12))
    flat = np.empty(3 * MAX_BRANCHES * DOF)
    rows = flat.reshape((3 * MAX_BRANCHES, DOF))
    _transform_target(params, T1, 0, T0)
    dh = params[_DH:_LOWER].reshape((DOF, _NCOL))
    n = candidates(int(params[_FAMILY]), dh, T0, ref1, 0, params[_TOLS:], rows)
    sort = (flags & SORT) != 0
    within = (flags & WITHIN_LIMITS) != 0
    return _postprocess(params, T1, 0, ref1, 0, sort, within, rows, flat, n, pre, out[None])


@_jit
def solve_batch(
    params: np.ndarray, T: np.ndarray, ref: np.ndarray, flags: int
) -> tuple[np.ndarray, np.ndarray]:
    """The pipeline of :func:`solve` over validated targets ``T`` (N, 4, 4), serially.

    Args:
        params: the robot's parameter vector (:func:`pack_params`), family included.
        T: (N, 4, 4) world targets of the tool, already validated (:func:`first_bad_pose`).
        ref: (1, 6) one reference for every target, or (N, 6) one per target; finite.
        flags: :data:`SORT` and / or :data:`WITHIN_LIMITS`.

    Returns:
        ``Q`` (N, 8, 6): branches, rows past each count filled with NaN; ``counts`` (N,).
    """
    N = T.shape[0]
    shared = ref.shape[0] == 1
    sort = (flags & SORT) != 0
    within = (flags & WITHIN_LIMITS) != 0
    family = int(params[_FAMILY])
    dh = params[_DH:_LOWER].reshape((DOF, _NCOL))
    tols = params[_TOLS:]
    T0 = np.empty((4, 4))
    pre = np.empty((DOF + 2, 12))
    flat = np.empty(3 * MAX_BRANCHES * DOF)
    rows = flat.reshape((3 * MAX_BRANCHES, DOF))
    Q = np.empty((N, MAX_BRANCHES, DOF))
    counts = np.zeros(N, dtype=np.int64)
    for k in range(N):
        kr = 0 if shared else k
        _transform_target(params, T, k, T0)
        n = candidates(family, dh, T0, ref, kr, tols, rows)
        m = _postprocess(params, T, k, ref, kr, sort, within, rows, flat, n, pre, Q)
        counts[k] = m
        for r in range(m, MAX_BRANCHES):
            for j in range(DOF):
                Q[k, r, j] = np.nan
    return Q, counts
