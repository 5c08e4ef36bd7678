"""One differential-IK step program in preallocated arrays, filled by compiled code.

The same programs as :mod:`optik.programs.diff_qp` (unit weights ``W = I``, ``Wt = I``),
without building a ``qpsolvers.Problem`` per step: :class:`StepArrays` holds every array
of one robot and task shape (task rows, objective, the joints that move), and
:func:`fill_step` fills them in one compiled call from ``q`` and the twist. It validates
``q`` and the twist on the way (finite, within the limits up to a tolerance, lengths
bounded) and returns a code; callers that get a nonzero code run the Python validators,
which raise the error that names the argument. :func:`check_step` is the cheap
verification of a backend's point: finite, inside the bounds, ``J dq = v`` (least norm)
and KKT stationarity with multipliers fitted here on the joints off their bounds (least
squares on ``J_F^T y = -g_F``, then the bound multipliers from the residual, with their
signs enforced). A point it accepts satisfies the KKT conditions of the convex program,
so it is the minimizer; a point it rejects goes to the full proof
(:meth:`DiffIKProgram.kkt`, sign-constrained multipliers fitted by BVLS over every
unknown).

Arrays (``n`` joints, ``nv`` of them the program's variables, ``m`` task rows), written
by :func:`fill_step`:

* ``q`` (n,): the configuration, clipped onto the bounds; ``T`` (4, 4), ``J`` (m, nv),
  ``v`` (m,) = ``twist[rows] * dt``;
* ``lb``, ``ub`` (nv,): the step bounds (``-inf``/``inf`` where unbounded);
* ``P`` (nv, nv), ``c`` (nv,): the cost (least norm: ``I`` and 0; least squares:
  ``J^T J + lambda^2 I`` and ``-J^T v``);
* the equilibrated copies for the backend (:meth:`DiffIKProgram.equilibrated`): ``Ps =
  P / p``, ``cs = c s / p``, ``bs = v s``, ``lbs = lb s``, ``ubs = ub s`` with ``p = max
  |P|`` and ``s = 1 / ||v||_inf`` (``scale = [p, s]``, capped at ``2**1000``:
  :func:`~optik.programs.diff_qp.equilibration_scale`); the step is ``x / s``.

By default (what :func:`optik.diff_ik` uses) every joint is a variable, the bounds are the
joint limits and the rows are the world-frame Jacobian's. An IK task
(:meth:`StepArrays.set_task`) replaces the bounds by the query's box and the rows by the
task's (:func:`optik.task.task_rows`: weighted, in the target frame); the twist is then
the task residual of :func:`optik.task.task_error`. Joints that the box freezes (lower ==
upper) are left out of the variables (``moving``), so a backend never sees a zero-width box.
"""

from __future__ import annotations

import functools
import math
import threading
from typing import Any, Final, NamedTuple

import numpy as np
import qpsolvers

from optik import _kernels
from optik._checks import MAX_LENGTH_M, FloatArray
from optik._math import householder_lstsq
from optik._numba import inline, jit
from optik.errors import OptikError
from optik.limits import Q_CLIP_TOLERANCE
from optik.model import Robot
from optik.programs.diff_qp import (
    MAX_SCALE_EXPONENT,
    TASK_ROUNDING,
    DiffIKProgram,
    Objective,
)
from optik.task import make_task, task_error, task_rows

__all__ = [
    "FILL_BAD_Q",
    "FILL_BAD_TWIST",
    "FILL_INCONSISTENT",
    "FILL_OK",
    "FILL_Q_OUTSIDE",
    "FILL_STEP_TOO_LONG",
    "ScaledProgram",
    "StepArrays",
    "StepBuffers",
    "check_step",
    "fill_step",
    "step_arrays",
    "take_step",
]

#: :func:`fill_step` codes.
FILL_OK: Final[int] = 0
FILL_BAD_Q: Final[int] = 1
FILL_Q_OUTSIDE: Final[int] = 2
FILL_BAD_TWIST: Final[int] = 3
FILL_STEP_TOO_LONG: Final[int] = 4
FILL_INCONSISTENT: Final[int] = 5

#: :func:`check_step` codes: accepted; not finite; bounds; ``J dq = v``; KKT.
CHECK_OK: Final[int] = 0
CHECK_NOT_FINITE: Final[int] = 1
CHECK_BOUNDS: Final[int] = 2
CHECK_TASK: Final[int] = 3
CHECK_KKT: Final[int] = 4

# Every array of a StepArrays lives in one float64 buffer, at the offsets of a layout
# array indexed by these slots: a compiled call then takes two arrays instead of twenty
# (numba's dispatcher spends time on each array, loose or in a tuple: measured with numba
# 0.68, a call of one array 0.24 µs, of six 0.47 µs, of a tuple of six 0.59 µs; a
# prebuilt tuple costs what its entries splatted into the call do).
# The scaled bounds and task right-hand side are stacked, lower bounds then ``bs`` and
# upper bounds then ``bs`` again, so that a backend taking ``[bounds; rows]`` (DAQP) gets
# them as two views without a copy.
# The last slots hold what an IK task sets (StepArrays.set_task): the box q stays in, the
# target pose, the packed task and the task error's scratch.
_Q, _THETA, _T, _J6, _WORK, _J, _V, _LB, _UB, _P, _C = range(11)
_PS, _CS, _LBS, _BS, _UBS, _BS2, _SCALE, _DQ, _G, _R, _MA, _MB, _Y = range(11, 24)
_LO, _HI, _TARGET, _TASK, _SCRATCH = range(24, 29)
_SLOTS = 29
# Constants, in a second float buffer: the chain transforms K and the coupling C; and in
# an int buffer: the joint kinds (1 = prismatic), the task rows, the moving joints.
_K, _CC = range(2)
# Entry of Task.packed saying 2.0 for a position task with unit weights (optik.task).
_TASK_FAST = 10
# Entry of Task.packed holding a length-balanced search's arm size L (m), else 0
# (optik.task.balanced_search): a slide's damping is then over L^2, its travel measured
# in the arm's size, as in the compiled dls.
_TASK_LENGTH = 12


StepBuffers = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]
"""The arrays of a :class:`StepArrays` as compiled code takes them (:attr:`StepArrays.buffers`):
``(const, const_layout, ints, buf, layout, identity)``: the constants (float and their
layout; int: joint kinds, task rows, moving joints), the buffer of every array and its
layout, and whether the chain's coupling is the identity."""


class ScaledProgram(NamedTuple):
    """An equilibrated step program as a backend takes it (:attr:`StepArrays.scaled`).

    ``min 1/2 x^T P x + c^T x  s.t.  A x = b,  lb <= x <= ub`` (``A``/``b`` with ``m`` rows,
    ``m = 0`` for least squares; ``-inf``/``inf`` where unbounded). ``lower_stack`` and
    ``upper_stack`` are ``[lb; b]`` and ``[ub; b]`` when the caller keeps them so, else
    ``None``.
    """

    P: FloatArray
    c: FloatArray
    A: FloatArray
    b: FloatArray
    lb: FloatArray
    ub: FloatArray
    lower_stack: FloatArray | None
    upper_stack: FloatArray | None


@functools.cache
def _plain_pose() -> FloatArray:
    """The packed task of a full pose with unit weights: rows and residual in the world frame.

    Built on first use, not at import: :func:`make_task` calls a kernel, and an import
    should neither compile nor load one.
    """
    return make_task("pose").packed


@inline
def _vec(buf: np.ndarray, layout: np.ndarray, slot: int) -> np.ndarray:
    return buf[layout[slot] : layout[slot + 1]]


@inline
def _mat(buf: np.ndarray, layout: np.ndarray, slot: int, rows: int) -> np.ndarray:
    flat = buf[layout[slot] : layout[slot + 1]]
    return flat.reshape((rows, flat.shape[0] // rows))


@inline
def _chain(
    const: np.ndarray, const_layout: np.ndarray, ints: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The chain of ``n`` joints: transforms ``K``, coupling ``C``, prismatic flags."""
    nc = (const_layout[_CC + 1] - const_layout[_CC]) // n
    K = _vec(const, const_layout, _K).reshape((nc + 1, 4, 4))
    return K, _mat(const, const_layout, _CC, nc), ints[:nc]


@inline
def _rows_and_moving(ints: np.ndarray, nc: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The task rows (m,) and the moving joints (the program's variables) of ``ints``."""
    return ints[nc : nc + m], ints[nc + m :]


@inline
def _chain_angles(C: np.ndarray, q: np.ndarray, theta: np.ndarray, identity: bool) -> None:
    """``theta = C q``: the chain's joint values (``q`` itself when ``C`` is the identity)."""
    if identity:
        for j in range(theta.shape[0]):
            theta[j] = q[j]
    else:
        for j in range(theta.shape[0]):
            acc = 0.0
            for i in range(q.shape[0]):
                acc += C[j, i] * q[i]
            theta[j] = acc


@jit
def fill_step(
    const: np.ndarray,
    const_layout: np.ndarray,
    ints: np.ndarray,
    q_in: np.ndarray,
    twist: np.ndarray,
    vmax: np.ndarray,
    buf: np.ndarray,
    layout: np.ndarray,
    dt: float,
    limits: bool | np.bool_,
    clip_tol: float,
    max_length: float,
    gain: float,
    use_vmax: bool | np.bool_,
    least_squares: bool | np.bool_,
    lam: float,
    identity: bool,
) -> int:
    """Fill the program arrays of a :class:`StepArrays` (see the module); return a code.

    Codes: :data:`FILL_OK`; :data:`FILL_BAD_Q` (``q`` not finite or beyond
    ``max_length``); :data:`FILL_Q_OUTSIDE` (with ``limits``, a joint beyond its limits
    by more than ``clip_tol``); :data:`FILL_BAD_TWIST` (not finite);
    :data:`FILL_STEP_TOO_LONG` (an entry of ``twist * dt`` beyond ``max_length``);
    :data:`FILL_INCONSISTENT` (a lower step bound above the upper one; every array is
    filled). ``limits`` and ``clip_tol`` are on the box of the ``_LO``/``_HI`` slots (the
    joint limits unless :meth:`StepArrays.set_task` set another), ``vmax`` (n,) per joint.
    """
    n = q_in.shape[0]
    K, C, prismatic = _chain(const, const_layout, ints, n)
    nc = prismatic.shape[0]
    lower = _vec(buf, layout, _LO)
    upper = _vec(buf, layout, _HI)
    q = _vec(buf, layout, _Q)
    theta = _vec(buf, layout, _THETA)
    T = _mat(buf, layout, _T, 4)
    J6 = _mat(buf, layout, _J6, 6)
    work = _mat(buf, layout, _WORK, nc)
    v = _vec(buf, layout, _V)
    m = v.shape[0]
    rows, moving = _rows_and_moving(ints, nc, m)
    nv = moving.shape[0]
    J = _mat(buf, layout, _J, m) if m > 0 else _mat(buf, layout, _J, 1)
    lb = _vec(buf, layout, _LB)
    ub = _vec(buf, layout, _UB)
    P = _mat(buf, layout, _P, nv)
    c = _vec(buf, layout, _C)
    Ps = _mat(buf, layout, _PS, nv)
    cs = _vec(buf, layout, _CS)
    bs = _vec(buf, layout, _BS)
    bs2 = _vec(buf, layout, _BS2)
    lbs = _vec(buf, layout, _LBS)
    ubs = _vec(buf, layout, _UBS)
    scale = _vec(buf, layout, _SCALE)
    for i in range(n):
        x = q_in[i]
        if not math.isfinite(x) or abs(x) > max_length:
            return FILL_BAD_Q
        if limits:
            lo = lower[i]
            hi = upper[i]
            if not (lo <= x <= hi):
                if not (lo - clip_tol <= x <= hi + clip_tol):
                    return FILL_Q_OUTSIDE
                x = min(max(x, lo), hi)
        q[i] = x
    for k in range(6):
        if not math.isfinite(twist[k]):
            return FILL_BAD_TWIST
        if not abs(twist[k] * dt) <= max_length:
            return FILL_STEP_TOO_LONG
    _chain_angles(C, q, theta, identity)
    _kernels.fk_jacobian_work(K, prismatic, theta, T, J6, work)
    # The task's rows (weighted, in the target frame); a plain pose keeps the world rows.
    task = _vec(buf, layout, _TASK)
    if task[_TASK_FAST] != 1.0:
        task_rows(J6, _mat(buf, layout, _TARGET, 4), task)
    vabs = 0.0
    for r in range(m):
        row = rows[r]
        v[r] = twist[row] * dt
        vabs = max(vabs, abs(v[r]))
        if identity:
            for k in range(nv):
                J[r, k] = J6[row, moving[k]]
        else:
            for k in range(nv):
                acc = 0.0
                for j in range(nc):
                    acc += J6[row, j] * C[j, moving[k]]
                J[r, k] = acc
    consistent = True
    for k in range(nv):
        i = moving[k]
        lo = -np.inf
        hi = np.inf
        if limits:
            if math.isfinite(lower[i]):
                lo = gain * (lower[i] - q[i])
            if math.isfinite(upper[i]):
                hi = gain * (upper[i] - q[i])
        if use_vmax:
            reach = vmax[i] * dt
            lo = max(lo, -reach)
            hi = min(hi, reach)
        lb[k] = lo
        ub[k] = hi
        if not lo <= hi:
            consistent = False
    pmax = 0.0
    length = task[_TASK_LENGTH]
    for i in range(nv):
        if least_squares:
            acc = 0.0
            for r in range(m):
                acc -= J[r, i] * v[r]
            c[i] = acc
            damping = lam * lam
            if length > 0.0 and _kernels.drives_slide(prismatic, C, identity, moving[i]):
                damping /= length * length
            for j in range(i, nv):
                acc = 0.0
                for r in range(m):
                    acc += J[r, i] * J[r, j]
                if i == j:
                    acc += damping
                P[i, j] = acc
                P[j, i] = acc
                pmax = max(pmax, abs(acc))
        else:
            c[i] = 0.0
            for j in range(nv):
                P[i, j] = 1.0 if i == j else 0.0
            pmax = 1.0
    p = pmax if pmax > 0.0 else 1.0
    # 1 / vabs, capped so a subnormal task cannot overflow it (equilibration_scale).
    s = 1.0
    if vabs > 0.0:
        s = (
            1.0 / vabs
            if vabs >= math.ldexp(1.0, -MAX_SCALE_EXPONENT)
            else math.ldexp(1.0, MAX_SCALE_EXPONENT)
        )
    scale[0] = p
    scale[1] = s
    for i in range(nv):
        for j in range(nv):
            Ps[i, j] = P[i, j] / p
        cs[i] = c[i] * (s / p)
        lbs[i] = lb[i] * s
        ubs[i] = ub[i] * s
    for r in range(m):
        bs[r] = v[r] * s
        bs2[r] = bs[r]
    return FILL_OK if consistent else FILL_INCONSISTENT


@jit
def check_step(
    x: np.ndarray,
    buf: np.ndarray,
    layout: np.ndarray,
    m: int,
    least_squares: bool,
    feas_rtol: float,
    feas_atol: float,
    kkt_rtol: float,
) -> tuple[int, float, int]:
    """Cheap verification of a backend's point ``x`` (equilibrated: ``dq = x / s``).

    Fills ``dq`` with the point clipped onto the bounds and returns ``(code, value,
    active)``, ``active`` the number of joints within the bounds' tolerance of a bound
    (0 until the bounds are checked): :data:`CHECK_OK` (accepted, value = stationarity
    residual), :data:`CHECK_NOT_FINITE`,
    :data:`CHECK_BOUNDS` (value = violation), :data:`CHECK_TASK` (value = ``|J dq -
    v|_inf``), :data:`CHECK_KKT` (value = the residual with the multipliers fitted here:
    not a proof of non-optimality, the full proof decides). Tolerances as in
    :func:`optik.diffik.verify_step`.
    """
    dq = _vec(buf, layout, _DQ)
    n = dq.shape[0]
    J = _mat(buf, layout, _J, m) if m > 0 else _mat(buf, layout, _J, 1)
    v = _vec(buf, layout, _V)
    lb = _vec(buf, layout, _LB)
    ub = _vec(buf, layout, _UB)
    P = _mat(buf, layout, _P, n)
    c = _vec(buf, layout, _C)
    g = _vec(buf, layout, _G)
    r_vec = _vec(buf, layout, _R)
    s = _vec(buf, layout, _SCALE)[1]
    active = 0  # a variable, not a literal: numba unifies the returned tuples
    if x.shape[0] != n:
        return CHECK_NOT_FINITE, np.nan, active
    vabs = 0.0
    for r in range(m):
        vabs = max(vabs, abs(v[r]))
    tol = feas_rtol * vabs + feas_atol
    violation = 0.0
    for i in range(n):
        xi = x[i] / s
        if not math.isfinite(xi):
            return CHECK_NOT_FINITE, np.nan, active
        violation = max(violation, lb[i] - xi, xi - ub[i])
        dq[i] = min(max(xi, lb[i]), ub[i])
    if violation > tol:
        return CHECK_BOUNDS, violation, active
    jmax = 0.0
    if not least_squares:
        residual = 0.0
        size = 0.0
        for r in range(m):
            acc = -v[r]
            row = 0.0
            for i in range(n):
                acc += J[r, i] * dq[i]
                row += abs(J[r, i] * dq[i])
                jmax = max(jmax, abs(J[r, i]))
            residual = max(residual, abs(acc))
            size = max(size, row)
        # Relative to the task and the rounding of J dq (DiffIKProgram.task_tolerance).
        if residual > feas_rtol * vabs + TASK_ROUNDING * size:
            return CHECK_TASK, residual, active
    pmax = 0.0
    cmax = 0.0
    dmax = 0.0
    free = 0
    for i in range(n):
        acc = c[i]
        for j in range(n):
            acc += P[i, j] * dq[j]
            pmax = max(pmax, abs(P[i, j]))
        g[i] = acc
        r_vec[i] = acc
        cmax = max(cmax, abs(c[i]))
        dmax = max(dmax, abs(dq[i]))
        if not _active(lb[i], ub[i], dq[i], tol) > 0:
            free += 1
    active = n - free
    if not least_squares and m > 0:
        if free < m:
            # The multipliers are not fitted here: the full proof decides.
            return CHECK_KKT, np.nan, active
        # y minimizing ||g_F + J_F^T y||: the multipliers of J dq = v on the free joints.
        A = _vec(buf, layout, _MA)[: free * m].reshape((free, m))
        b = _vec(buf, layout, _MB)[:free]
        y = _vec(buf, layout, _Y)
        k = 0
        for i in range(n):
            if _active(lb[i], ub[i], dq[i], tol) == 0:
                for r in range(m):
                    A[k, r] = J[r, i]
                b[k] = -g[i]
                k += 1
        if not householder_lstsq(A, b, y):
            return CHECK_KKT, np.nan, active
        for i in range(n):
            acc = g[i]
            for r in range(m):
                acc += J[r, i] * y[r]
            r_vec[i] = acc
    stationarity = 0.0
    for i in range(n):
        ri = r_vec[i]
        # g + J^T y - z_lower + z_upper = 0 with z >= 0 on the active bounds only.
        side = _active(lb[i], ub[i], dq[i], tol)
        if side == 3:
            res = 0.0
        elif side == 1:
            res = max(-ri, 0.0)
        elif side == 2:
            res = max(ri, 0.0)
        else:
            res = abs(ri)
        stationarity = max(stationarity, res)
    scale = pmax * dmax + cmax + (jmax * vabs if not least_squares else 0.0)
    if stationarity > kkt_rtol * scale + feas_atol:
        return CHECK_KKT, stationarity, active
    return CHECK_OK, stationarity, active


@jit
def take_step(
    buffers: StepBuffers, x: np.ndarray, q_new: np.ndarray, e_new: np.ndarray
) -> tuple[float, float, float]:
    """Apply a backend's point to the filled program and measure the task there.

    ``buffers`` is :attr:`StepArrays.buffers`.
    ``dq = clip(x / s, lb, ub)`` (nv,) on the moving joints, ``q_new = clip(q + dq, lower,
    upper)`` (n,) (the other joints keep their value); ``e_new`` (6,) the task residual at
    ``q_new`` (:func:`optik.task.task_error` with the target and task of
    :meth:`StepArrays.set_task`). Returns ``(||e_new||^2, position error, orientation
    error)``; ``||e_new||^2`` is NaN when ``x`` is not finite. The norm is over
    ``e_new[:3]`` for a position task with unit weights, else over all six entries.
    """
    const, const_layout, ints, buf, layout, identity = buffers
    q = _vec(buf, layout, _Q)
    n = q.shape[0]
    K, C, prismatic = _chain(const, const_layout, ints, n)
    m = layout[_V + 1] - layout[_V]
    _, moving = _rows_and_moving(ints, prismatic.shape[0], m)
    lb = _vec(buf, layout, _LB)
    ub = _vec(buf, layout, _UB)
    s = _vec(buf, layout, _SCALE)[1]
    lower = _vec(buf, layout, _LO)
    upper = _vec(buf, layout, _HI)
    target = _mat(buf, layout, _TARGET, 4)
    task = _vec(buf, layout, _TASK)
    theta = _vec(buf, layout, _THETA)
    T = _mat(buf, layout, _T, 4)
    if x.shape[0] != moving.shape[0]:
        return np.nan, np.nan, np.nan
    for i in range(n):
        q_new[i] = q[i]
    for k in range(moving.shape[0]):
        dq = x[k] / s
        if not math.isfinite(dq):
            return np.nan, np.nan, np.nan
        i = moving[k]
        dq = min(max(dq, lb[k]), ub[k])
        q_new[i] = min(max(q[i] + dq, lower[i]), upper[i])
    _chain_angles(C, q_new, theta, identity)
    _kernels.fk_into(K, prismatic, theta, T)
    position, orientation = task_error(T, target, task, e_new, _mat(buf, layout, _SCRATCH, 3))
    size = 3 if task[_TASK_FAST] == 2.0 else 6
    err2 = 0.0
    for k in range(size):
        err2 += e_new[k] * e_new[k]
    return err2, position, orientation


@inline
def _active(lo: float, hi: float, x: float, tol: float) -> int:
    """0 free, 1 at the lower bound, 2 at the upper one, 3 at both (within ``tol``)."""
    side = 0
    if math.isfinite(lo) and x - lo <= tol:
        side = 1
    if math.isfinite(hi) and hi - x <= tol:
        side += 2
    return side


class StepArrays:
    """The preallocated arrays of the step programs of one robot and task shape.

    Built once per robot, task rows, objective and moving joints (and reused, one per
    thread, by :func:`optik.diff_ik` and the ``qp:<backend>`` IK loop); :meth:`fill`
    writes a new program into them. The attributes are views of one buffer (see the
    module docstring for their meaning); they are overwritten by the next :meth:`fill`.

    Args:
        robot: the robot.
        rows: the task rows (indices into the six rows of the task) the program keeps.
        objective: ``"least_norm"`` or ``"least_squares"``.
        moving: the joints that are the program's variables, ascending (default: all);
            the others keep their value in :func:`take_step`.
    """

    def __init__(
        self,
        robot: Robot,
        rows: tuple[int, ...],
        objective: Objective,
        moving: tuple[int, ...] | None = None,
    ) -> None:
        chain = robot.chain
        n = robot.dof
        nc = chain.n
        m = len(rows)
        moving = tuple(range(n)) if moving is None else moving
        nv = len(moving)
        self.robot = robot
        self.objective: Objective = objective
        self.least_squares = objective == "least_squares"
        self.rows = rows
        self.moving = moving
        self.dof = n
        #: The number of the program's variables (the moving joints).
        self.nv = nv
        self.task_dim = m
        self._identity = bool(chain.identity)
        sizes = [0] * _SLOTS
        shapes: dict[int, tuple[int, ...]] = {
            _Q: (n,), _THETA: (nc,), _T: (4, 4), _J6: (6, nc), _WORK: (nc, 3), _J: (m, nv),
            _V: (m,), _LB: (nv,), _UB: (nv,), _P: (nv, nv), _C: (nv,), _PS: (nv, nv),
            _CS: (nv,), _LBS: (nv,), _BS: (m,), _UBS: (nv,), _BS2: (m,), _SCALE: (2,),
            _DQ: (nv,), _G: (nv,), _R: (nv,), _MA: (nv * m,), _MB: (nv,), _Y: (m,),
            _LO: (n,), _HI: (n,), _TARGET: (4, 4), _TASK: (_plain_pose().size,),
            _SCRATCH: (3, 4),
        }  # fmt: skip
        for slot, shape in shapes.items():
            sizes[slot] = int(np.prod(shape))
        self._layout = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self._buf = np.zeros(int(self._layout[-1]))
        views = {
            slot: self._buf[self._layout[slot] : self._layout[slot + 1]].reshape(shape)
            for slot, shape in shapes.items()
        }
        self.q, self.T, self.J, self.v = views[_Q], views[_T], views[_J], views[_V]
        self.lb, self.ub, self.P, self.c = views[_LB], views[_UB], views[_P], views[_C]
        self.Ps, self.cs, self.bs = views[_PS], views[_CS], views[_BS]
        self.lbs, self.ubs, self.scale, self.dq = (
            views[_LBS],
            views[_UBS],
            views[_SCALE],
            views[_DQ],
        )
        self._task_views = views[_LO], views[_HI], views[_TARGET], views[_TASK]
        self.scale[:] = 1.0
        #: ``[lbs; bs]`` and ``[ubs; bs]`` (nv + m,): the bounds then the task rows.
        self.lower_stack = self._buf[self._layout[_LBS] : self._layout[_BS + 1]]
        self.upper_stack = self._buf[self._layout[_UBS] : self._layout[_BS2 + 1]]
        # The plain program: the joint limits, the world-frame rows.
        self.set_task(np.eye(4), _plain_pose(), chain.lower, chain.upper)
        const = [
            np.ascontiguousarray(chain.K, dtype=np.float64).ravel(),
            np.ascontiguousarray(chain.C, dtype=np.float64).ravel(),
        ]
        self._const = np.concatenate(const)
        self._const_layout = np.concatenate([[0], np.cumsum([a.size for a in const])]).astype(
            np.int64
        )
        self._ints = np.concatenate(
            [
                np.asarray(chain.prismatic, dtype=np.int64),
                np.array(rows, dtype=np.int64),
                np.array(moving, dtype=np.int64),
            ]
        )
        self._no_vmax = np.zeros(n)
        #: A step of zeros (nv,): :meth:`take` of it measures the task at :attr:`q`.
        self.zero_step = np.zeros(nv)
        self.damping = 0.0
        #: The first argument of :func:`take_step` (and of the compiled IK loop's calls):
        #: a :data:`StepBuffers`.
        self.buffers: StepBuffers = (
            self._const,
            self._const_layout,
            self._ints,
            self._buf,
            self._layout,
            self._identity,
        )
        #: The backend's equality rows and right-hand side: ``J`` and ``bs`` for least
        #: norm, empty for least squares.
        self.A_eq = np.zeros((0, nv)) if self.least_squares else self.J
        self.b_eq = np.zeros(0) if self.least_squares else self.bs
        #: The equilibrated program for a backend (views of the arrays above, filled by
        #: each :meth:`fill`): ``Ps``, ``cs``, the equality rows, ``lbs``, ``ubs`` and the
        #: stacks of the bounds and the rows.
        rows_eq = 0 if self.least_squares else m
        self.scaled = ScaledProgram(
            self.Ps,
            self.cs,
            self.A_eq,
            self.b_eq,
            self.lbs,
            self.ubs,
            self.lower_stack[: nv + rows_eq],
            self.upper_stack[: nv + rows_eq],
        )

    def set_task(
        self, target: FloatArray, task: FloatArray, lower: FloatArray, upper: FloatArray
    ) -> None:
        """Make the next programs those of an IK task (read by :meth:`fill` and :meth:`take`).

        Args:
            target: 4x4 target pose (world frame).
            task: the packed task (:attr:`optik.task.Task.packed`); its residual
                (:func:`optik.task.task_error`) is the twist :meth:`fill` then takes
                (with ``dt = 1``), its rows (:func:`optik.task.task_rows`) the program's.
            lower: (dof,) lower bound of ``q`` (the query's box), rad or m.
            upper: (dof,) upper bound of ``q``.
        """
        lo, hi, target_view, task_view = self._task_views
        lo[:] = lower
        hi[:] = upper
        target_view[:] = target
        task_view[:] = task

    def fill(
        self,
        q: FloatArray,
        twist: FloatArray,
        dt: float,
        *,
        limits: bool = True,
        limit_gain: float = 1.0,
        velocity_limits: FloatArray | None = None,
        damping: float = 0.0,
    ) -> int:
        """Fill the program at ``q`` (dof,) for ``twist`` (6,) over ``dt``; a ``FILL_*`` code.

        Arguments are not validated here beyond what :func:`fill_step` checks: ``q`` and
        ``twist`` float64 arrays of the right shapes, ``dt > 0``, ``limit_gain`` in
        (0, 1], ``velocity_limits`` (dof,) ``>= 0`` or ``None``, ``damping >= 0``.
        """
        self.damping = damping if self.least_squares else 0.0
        vmax = self._no_vmax if velocity_limits is None else velocity_limits
        return int(
            fill_step(
                self._const,
                self._const_layout,
                self._ints,
                q,
                twist,
                vmax,
                self._buf,
                self._layout,
                dt,
                limits,
                Q_CLIP_TOLERANCE,
                MAX_LENGTH_M,
                limit_gain,
                velocity_limits is not None,
                self.least_squares,
                self.damping,
                self._identity,
            )
        )

    def check(
        self, x: FloatArray, feas_rtol: float, feas_atol: float, kkt_rtol: float
    ) -> tuple[int, float, int]:
        """:func:`check_step` of the backend's equilibrated point ``x``; fills :attr:`dq`.

        Returns ``(code, value, active)``: the check's code and value, and the number of
        joints it found on a bound.
        """
        return check_step(
            x,
            self._buf,
            self._layout,
            self.task_dim,
            self.least_squares,
            feas_rtol,
            feas_atol,
            kkt_rtol,
        )

    def take(
        self, x: FloatArray, q_new: FloatArray, e_new: FloatArray
    ) -> tuple[float, float, float]:
        """:func:`take_step`: the point ``x`` applied at :attr:`q`, the task measured."""
        return take_step(self.buffers, x, q_new, e_new)

    def program(self) -> DiffIKProgram:
        """The filled program as a :class:`DiffIKProgram` (copies of the arrays).

        Raises:
            OptikError: some joints are not moving (the program is not of every joint).
        """
        n = self.dof
        if self.nv != n:
            raise OptikError(f"program() needs every joint moving, not only joints {self.moving}")
        bounded = bool(np.any(np.isfinite(self.lb)) or np.any(np.isfinite(self.ub)))
        lb = self.lb.copy() if bounded else None
        ub = self.ub.copy() if bounded else None
        if self.least_squares:
            qp = qpsolvers.Problem(self.P.copy(), self.c.copy(), lb=lb, ub=ub)
        else:
            qp = qpsolvers.Problem(
                self.P.copy(), self.c.copy(), A=self.J.copy(), b=self.v.copy(), lb=lb, ub=ub
            )
        return DiffIKProgram(
            qp=qp,
            objective=self.objective,
            q=self.q.copy(),
            J=self.J.copy(),
            v=self.v.copy(),
            rows=self.rows,
            lower=self.lb.copy(),
            upper=self.ub.copy(),
            W=np.eye(n),
            Wt=np.eye(self.task_dim),
            damping=self.damping,
        )


def _per_robot(robot: Robot) -> dict[tuple[Any, ...], StepArrays]:
    return {}


def step_arrays(
    robot: Robot,
    rows: tuple[int, ...],
    objective: Objective,
    moving: tuple[int, ...] | None = None,
) -> StepArrays:
    """The calling thread's :class:`StepArrays` of this robot and task shape (cached).

    ``moving=None`` gives the plain programs of :func:`optik.diff_ik` (every joint, the joint
    limits, the world frame: never :meth:`StepArrays.set_task`); a tuple of joints gives
    arrays of their own, for the IK loop that sets its task on them.
    """
    per_robot = robot.cached(_per_robot)
    key = (threading.get_ident(), rows, objective, moving)
    arrays = per_robot.get(key)
    if arrays is None:
        arrays = per_robot[key] = StepArrays(robot, rows, objective, moving)
    return arrays
