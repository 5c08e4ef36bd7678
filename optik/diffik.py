"""Differential IK: the joint step for one time step of a commanded tool twist.

:func:`diff_ik` builds the step program of :mod:`optik.programs.diff_qp`, hands it to a
``qpsolvers`` backend or a CasADi conic plugin, and checks the answer itself before
returning it: finite, inside the bounds, ``J dq = v`` for least norm, and the KKT
conditions with multipliers fitted by optik. When the least-norm equality cannot hold, an
LP (``scipy.optimize.linprog``, independent of the backend) proves it before
:class:`~optik.errors.NoSolutionError` is raised; a backend that fails on a feasible
program raises :class:`~optik.errors.SolverError` instead.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

from optik._checks import (
    MAX_LENGTH_M,
    FloatArray,
    check_bool,
    check_real,
    finite_array,
    finite_length_array,
)
from optik._interrupts import surfaces_interrupts
from optik.errors import (
    ArgumentError,
    JointLimitError,
    NonFiniteError,
    NoSolutionError,
    OptikError,
    SolverError,
    UnknownSolverError,
)
from optik.limits import Q_CLIP_TOLERANCE
from optik.model import Robot
from optik.posture import check_joint_weights
from optik.programs.diff_lsq import polish_least_squares, resolve_least_squares
from optik.programs.diff_qp import (
    ALL_ROWS,
    DEFAULT_DAMPING,
    MAX_DAMPING,
    OBJECTIVES,
    DiffIKProgram,
    KKTReport,
    Objective,
    QPSolution,
    _check_positive,
    _check_rows,
    build_program,
    check_velocity_limits,
    equilibration_scale,
)
from optik.programs.step_arrays import CHECK_OK, FILL_INCONSISTENT, FILL_OK, step_arrays
from optik.solvers import StepBackend, available_solvers, get_solver, registered_solvers

__all__ = [
    "DEFAULT_POSTURE_GAIN",
    "FEASIBILITY_ATOL",
    "FEASIBILITY_RTOL",
    "KKT_RTOL",
    "clip_into_limits",
    "diff_ik",
    "diff_ik_solvers",
    "polish_least_norm",
    "polish_least_squares",
    "verify_step",
]

#: Relative tolerance (times ``||v||_inf``, or the posture offset's size when larger) on
#: ``J dq = v`` and on the bounds.
FEASIBILITY_RTOL: Final[float] = 1e-7
#: Absolute floor of that tolerance (m, rad).
FEASIBILITY_ATOL: Final[float] = 1e-12
#: Default fraction of ``posture - q`` one :func:`diff_ik` step pulls towards: the gap to
#: the posture shrinks by about 10 % per step along the task's null space (a time constant
#: of about 10 steps), gentle enough not to fight the task's own motion.
DEFAULT_POSTURE_GAIN: Final[float] = 0.1
#: Relative tolerance on KKT stationarity (times the program's scale, see ``KKTReport``).
KKT_RTOL: Final[float] = 1e-6
#: A least-squares point within this (relative to the KKT scale) of stationary, but not
#: within :data:`KKT_RTOL`, is solved again from its active set (:func:`verify_step`).
RESOLVE_KKT_RTOL: Final[float] = 1e-2


def clip_into_limits(robot: Robot, name: str, q: Any) -> FloatArray:
    """A given configuration (dof,) clipped onto the limits within a tolerance.

    A measured configuration may lie a hair outside a limit: within
    :data:`~optik.limits.Q_CLIP_TOLERANCE` (rad or m) of the limits it is clipped onto
    them; beyond it the configuration is rejected.

    Args:
        robot: the robot whose limits apply.
        name: argument name for messages (``"q0"``, ``"q"``).
        q: configuration (dof,), rad or m.

    Returns:
        A new (dof,) float64 array inside ``[robot.lower, robot.upper]``.

    Raises:
        ShapeError, ArgumentError, NonFiniteError: not a finite real (dof,) array.
        JointLimitError: a joint beyond its limits by more than the tolerance (the first
            such joint is named).
    """
    array = finite_array(name, q, (robot.dof,))
    lower, upper = robot.lower, robot.upper
    # A loop over Python floats beats numpy's per-call overhead for a few joints.
    # ``lower - tol <= q <= upper + tol`` as written (not ``|clip(q) - q| <= tol``, whose
    # subtraction rounds): a value exactly at the tolerance is accepted.
    inside = True
    values = zip(array.tolist(), lower.tolist(), upper.tolist(), strict=True)
    for i, (x, lo, hi) in enumerate(values):
        if not lo <= x <= hi:
            if not lo - Q_CLIP_TOLERANCE <= x <= hi + Q_CLIP_TOLERANCE:
                unit = "m" if robot.joints[i].kind == "prismatic" else "rad"
                raise JointLimitError(robot.joints[i].name, x, lo, hi, unit, argument=name)
            inside = False
    return array.copy() if inside else np.clip(array, lower, upper)


def diff_ik_solvers() -> list[str]:
    """Solver names :func:`diff_ik` accepts here: ``available_solvers(kind="step")``."""
    return available_solvers(kind="step")


def _resolve(solver: Any) -> StepBackend:
    """The step backend registered as ``solver`` (a bare ``qpsolvers`` name is deprecated)."""
    if (
        isinstance(solver, str)
        and ":" not in solver
        and f"qp:{solver}" in registered_solvers(kind="step")
    ):
        warnings.warn(
            f"diff_ik(solver={solver!r}) is deprecated: write solver='qp:{solver}'",
            DeprecationWarning,
            stacklevel=3,
        )
        solver = f"qp:{solver}"
    if not isinstance(solver, str):
        raise UnknownSolverError(repr(solver), diff_ik_solvers())
    backend: StepBackend = get_solver(solver, kind="step")
    return backend


def _tolerance(program: DiffIKProgram) -> float:
    return FEASIBILITY_RTOL * program.magnitude + FEASIBILITY_ATOL


def verify_step(program: DiffIKProgram, solution: QPSolution) -> tuple[FloatArray | None, str]:
    """Check a backend's answer independently; return ``(dq, "")`` or ``(None, reason)``.

    The point must be finite; within :data:`FEASIBILITY_RTOL` times the program's
    :attr:`~optik.programs.diff_qp.DiffIKProgram.magnitude` (``||v||_inf``, or the
    posture offset's size when larger), plus :data:`FEASIBILITY_ATOL`, of the bounds,
    after which it is clipped onto them; satisfy ``J dq = v`` to
    :meth:`~optik.programs.diff_qp.DiffIKProgram.task_tolerance` (least norm: relative to
    ``||v||_inf`` alone, a point that misses it being projected back first,
    :func:`polish_least_norm`); and satisfy KKT stationarity with sign-constrained
    multipliers fitted by optik to :data:`KKT_RTOL` times the program's scale, the
    gradient taken from the stated objective (weights, damping and the posture offset,
    ``c = -W d``: :meth:`~optik.programs.diff_qp.DiffIKProgram.gradient`). The backend's
    own claim (``solution.found``) is not needed: a point that passes every check is
    accepted. A least-squares point is solved again in square-root form on its active
    set (:func:`~optik.programs.diff_lsq.resolve_least_squares`); a point that misses
    stationarity by less than :data:`RESOLVE_KKT_RTOL` of the scale is replaced by that
    solve when the solve passes the KKT test itself (the program is convex: a KKT point is
    a minimiser).
    """
    x = solution.x
    if x is None:
        return None, f"no point returned ({solution.status})"
    if x.shape != (program.dof,) or not np.all(np.isfinite(x)):
        return None, f"non-finite point returned ({solution.status})"
    tol = _tolerance(program)
    violation = program.bound_violation(x)
    if violation > tol:
        return None, f"bounds violated by {violation:.3g} ({solution.status})"
    dq = program.clip(x)
    if program.objective == "least_squares":
        kkt = program.kkt(dq, active_tol=tol)
        resolved = resolve_least_squares(program, dq, tol, KKT_RTOL, FEASIBILITY_ATOL)
        if _stationary(kkt):
            return resolved, ""
        # A point a little off (Clarabel's, 4e-6 to 2e-3 of the scale from stationary on
        # Panda and Dobot steps): the square-root solve on its active set, or scipy's
        # BVLS, finds the minimiser, taken only when it passes the KKT test. A point
        # further off is the backend's failure, reported as such.
        near = kkt.stationarity <= RESOLVE_KKT_RTOL * kkt.scale + FEASIBILITY_ATOL
        if near and resolved is not dq and _stationary(program.kkt(resolved, active_tol=tol)):
            return resolved, ""
        return None, _not_optimal(kkt, solution.status)
    residual = float(np.max(np.abs(program.task_residual(dq)), initial=0.0))
    limit = program.task_tolerance(dq, FEASIBILITY_RTOL)
    if residual <= limit:
        kkt = program.kkt(dq, active_tol=tol)
        if _stationary(kkt):
            return dq, ""
    # The backend's tolerances act on the equilibrated program, relative to the posture
    # offset when that is larger than the task: its point may miss J dq = v, and is
    # projected back onto it. A subnormal task reached the backend scaled by at most
    # 2**MAX_SCALE_EXPONENT, far below unit size, so only its active set is taken.
    tiny = 0.0 < program.magnitude < 1.0 / equilibration_scale(program.magnitude)
    polished = polish_least_norm(program, dq, tol, resolve=tiny)
    if polished is None:
        if residual > limit:
            return None, f"|J dq - v| = {residual:.3g} > {limit:.3g} ({solution.status})"
        return None, _not_optimal(program.kkt(dq, active_tol=tol), solution.status)
    kkt = program.kkt(polished, active_tol=tol)
    if not _stationary(kkt):
        return None, _not_optimal(kkt, solution.status)
    return polished, ""


def _stationary(kkt: KKTReport) -> bool:
    """KKT stationarity within :data:`KKT_RTOL` of the program's scale."""
    return bool(kkt.stationarity <= KKT_RTOL * kkt.scale + FEASIBILITY_ATOL)


def _not_optimal(kkt: KKTReport, status: str) -> str:
    return (
        f"not optimal: KKT stationarity residual {kkt.stationarity:.3g} "
        f"(scale {kkt.scale:.3g}) ({status})"
    )


def polish_least_norm(
    program: DiffIKProgram, dq: FloatArray, active_tol: float, resolve: bool = False
) -> FloatArray | None:
    """``dq`` moved back onto ``J dq = v``, its active bounds kept.

    The joints within ``active_tol`` (rad or m) of a bound are held exactly on it; the
    free ones move by the smallest correction in the ``W`` norm that meets the task, the
    ``W``-orthogonal projection onto ``J dq = v`` (``lstsq`` of ``J_F L^-T``,
    ``W_FF = L L^T``, refined once). The correction lies in the row space of ``J_F``
    scaled by ``W_FF^-1``, so it changes only the equality multipliers: a point whose
    KKT conditions held before holds them after. With ``resolve`` the free joints start
    from their unconstrained minimiser instead of ``dq``, which gives the minimiser on
    the active set of ``dq`` (only that active set is taken from ``dq``). The data are
    scaled by the exact power of two that brings the program's magnitude to unit size,
    so a subnormal task (``dt = 1e-309``) or a far posture loses no digits to the scale.

    Returns:
        The step (dof,), or ``None`` when no joint is free, the result is not finite, it
        leaves the bounds by more than ``active_tol`` or misses ``J dq = v`` by more than
        :meth:`~optik.programs.diff_qp.DiffIKProgram.task_tolerance` (the KKT signs are
        checked by the caller).
    """
    lower, upper = program.lower, program.upper
    at_lower = np.isfinite(lower) & (dq - lower <= active_tol)
    at_upper = np.isfinite(upper) & (upper - dq <= active_tol) & ~at_lower
    active = at_lower | at_upper
    free = ~active
    if not np.any(free):
        return None
    size = program.magnitude
    k = -math.frexp(size)[1] if size > 0.0 and math.isfinite(size) else 0
    held = np.ldexp(np.where(at_lower, lower, np.where(at_upper, upper, 0.0)), k)
    d = np.zeros(program.dof) if program.offset is None else np.ldexp(program.offset, k)
    v = np.ldexp(program.v, k)
    W, J = program.W, program.J
    W_ff = W[np.ix_(free, free)]
    x = held.copy()
    if resolve:
        x[free] = d[free]
        if np.any(active):
            pull = W[np.ix_(free, active)] @ (held[active] - d[active])
            x[free] -= np.linalg.solve(W_ff, pull)
    else:
        x[free] = np.ldexp(dq[free], k)
    w = np.diagonal(W_ff)
    diagonal = np.array_equal(W_ff, np.diag(w))
    root = np.sqrt(w) if diagonal else np.linalg.cholesky(W_ff)
    B = J[:, free] / root if diagonal else np.linalg.solve(root, J[:, free].T).T
    for _ in range(2):  # the projection, then one refinement of its rounding
        z, *_ = np.linalg.lstsq(B, v - J @ x, rcond=None)
        x[free] += z / root if diagonal else np.linalg.solve(root.T, z)
    out = np.ldexp(x, -k)
    if not np.all(np.isfinite(out)) or program.bound_violation(out) > active_tol:
        return None
    out = program.clip(out)
    residual = float(np.max(np.abs(program.task_residual(out)), initial=0.0))
    return out if residual <= program.task_tolerance(out, FEASIBILITY_RTOL) else None


def _inconsistent(program: DiffIKProgram) -> NoSolutionError:
    return NoSolutionError(
        "no step exists: the bounds on dq are inconsistent (q lies outside its limits by "
        "more than the velocity limits allow in one step)",
        program,
    )


def _no_solution(program: DiffIKProgram, backend: str) -> NoSolutionError | None:
    """A :class:`NoSolutionError` when the least-norm equality provably cannot hold."""
    if not program.bounds_consistent:
        return _inconsistent(program)
    if program.objective != "least_norm":
        return None
    gap = program.min_task_violation()
    tol = _tolerance(program)
    if gap <= tol:
        return None
    free, *_ = np.linalg.lstsq(program.J, program.v, rcond=None)
    unbounded_gap = float(np.max(np.abs(program.J @ free - program.v)))
    if unbounded_gap > tol:
        why = (
            "the twist is outside the range of J at q even without limits "
            f"(best |J dq - v|_inf = {unbounded_gap:.3g}: a singularity or too few joints)"
        )
    else:
        why = (
            "the joint (or velocity) limits block it: the best |J dq - v|_inf inside the "
            f"bounds is {gap:.3g}"
        )
    return NoSolutionError(
        f"least-norm step infeasible ({backend}): J dq = twist*dt cannot hold; {why}. "
        "Use objective='least_squares' for the closest bounded step.",
        program,
    )


@surfaces_interrupts
def diff_ik(
    robot: Robot,
    q: Any,
    twist: Any,
    *,
    dt: float,
    objective: Objective = "least_norm",
    solver: str = "qp:proxqp",
    limits: bool = True,
    velocity_limits: Any = None,
    damping: float | None = None,
    limit_gain: float = 1.0,
    rows: Sequence[int] | None = None,
    kkt_proof: bool = False,
    weights: Any = None,
    joint_weights: Any = None,
    posture: Any = None,
    posture_gain: float = DEFAULT_POSTURE_GAIN,
) -> FloatArray:
    """Joint step ``dq`` (rad, m) that moves the tool by ``twist * dt``, inside the limits.

    With ``v = twist * dt`` and ``J`` the geometric Jacobian at ``q`` (world frame, tool
    point; its ``rows`` when given), ``W = diag(joint_weights)`` (default ``I``),
    ``Wt = diag(weights)`` over the task rows (default ``I``) and the posture pull
    ``d = posture_gain (posture - q)`` (default 0), the step solves

    * ``objective="least_norm"``: ``min 1/2 ||dq - d||^2_W  s.t.  J dq = v,
      lb <= dq <= ub``; without active bounds the answer is
      ``d + W^-1 J^T (J W^-1 J^T)^-1 (v - J d)`` (``W^-1 J^T (J W^-1 J^T)^-1 v`` without a
      posture, ``J^T (J J^T)^-1 v`` with unit weights too);
    * ``objective="least_squares"``: ``min 1/2 ||J dq - v||^2_Wt + 1/2 lambda^2
      ||dq - d||^2_W  s.t.  lb <= dq <= ub`` (``lambda`` = ``damping``, default
      :data:`~optik.programs.diff_qp.DEFAULT_DAMPING` = 1e-3); without active bounds the
      answer is ``(J^T Wt J + lambda^2 W)^-1 (J^T Wt v + lambda^2 W d)``
      (``(J^T J + lambda^2 I)^-1 J^T v`` with the defaults);

    with ``lb = max(limit_gain (lower - q), -velocity_limits dt)`` and
    ``ub = min(limit_gain (upper - q), velocity_limits dt)``, so ``q + dq`` stays inside
    the limits.

    In the least-norm step the task rows hold exactly whatever the weights: a positive
    task weight does not change the answer (the equality leaves nothing to trade off), and
    a zero weight frees that row (it is dropped, as if left out of ``rows``). The posture
    moves the least-norm step only in the null space of ``J`` (``J dq = v`` still holds)
    and, without active bounds, brings ``q + dq`` nearer ``posture`` in the ``W`` norm
    whenever ``posture - q`` has a component in that null space. Without ``weights``,
    ``joint_weights`` and ``posture`` the step takes the compiled fast path; with any of
    them it builds the general program (:func:`~optik.programs.diff_qp.build_program`)
    and verifies it the same way.

    Args:
        robot: the robot.
        q: configuration (dof,), rad or m; with ``limits``, within
            :data:`~optik.limits.Q_CLIP_TOLERANCE` of the limits (a measured
            configuration a hair outside is clipped onto them).
        twist: tool twist (6,) in the world frame: linear velocity (m/s) then angular
            velocity (rad/s).
        dt: time step (s), > 0.
        objective: ``"least_norm"`` or ``"least_squares"``.
        solver: a step backend of the registry, ``available_solvers(kind="step")``: a
            ``qpsolvers`` backend ``"qp:<name>"`` or a CasADi conic plugin
            ``"casadi:<plugin>"``. A bare ``"<name>"`` still means ``"qp:<name>"`` but is
            deprecated (``DeprecationWarning``).
        limits: bound ``q + dq`` by the joint limits.
        velocity_limits: joint speed limits (dof,), rad/s or m/s, ``inf`` for none.
        damping: ``lambda >= 0`` for least squares (``None``: the default); must be
            ``None`` for least norm.
        limit_gain: fraction in (0, 1] of the distance to a limit one step may cover.
        rows: Jacobian rows (0..5) the task constrains (default all six), e.g.
            ``(0, 1, 2)`` for the tool's linear velocity only.
        kkt_proof: also run the full KKT proof of :func:`verify_step` (multipliers fitted
            with their signs by BVLS) on an answer the cheap check already accepted. By
            default it runs only when the cheap check (multipliers fitted on the free
            joints, :func:`optik.programs.step_arrays.check_step`) rejects the answer.
        weights: (6,) >= 0 on the twist's rows ``[vx, vy, vz, wx, wy, wz]`` (world frame,
            no unit). Least squares: ``Wt = diag`` of the task rows' weights. Least norm: a
            zero weight drops that row; positive weights leave the answer unchanged. With
            ``rows``, a positive weight on a row that ``rows`` leaves out is a conflict
            (``OptikError``); zero weights on rows of ``rows`` free them.
        joint_weights: (dof,) in [1e-100, 1e100], the joint weights
            ``W = diag(joint_weights)`` (no unit): a heavier joint moves less.
        posture: a reference configuration ``q_ref`` (dof,), rad or m, the step also pulls
            towards (see above).
        posture_gain: fraction in (0, 1] of ``posture - q`` one step pulls towards
            (default :data:`DEFAULT_POSTURE_GAIN` = 0.1); used only with ``posture``.

    Returns:
        ``dq`` of shape (dof,), verified by optik: finite, inside the bounds, ``J dq = v``
        for least norm, and the KKT conditions (see :func:`verify_step`).

    Raises:
        NoSolutionError: least norm and ``J dq = twist*dt`` cannot hold inside the bounds
            (proved by an LP), or the bounds are inconsistent; ``exc.program`` is the
            :class:`~optik.programs.diff_qp.DiffIKProgram`.
        SolverError: the backend failed (raised, returned nothing, or a point that fails
            optik's checks) on a program that has a solution.
        UnknownSolverError: unknown or uninstalled solver; the message lists the installed.
        JointLimitError: with ``limits``, a joint of ``q`` beyond its limits by more
            than :data:`~optik.limits.Q_CLIP_TOLERANCE`.
        ShapeError, NonFiniteError: bad ``q``, ``twist`` or ``velocity_limits``.
        ArgumentError: an entry of ``twist * dt`` beyond
            :data:`~optik._checks.MAX_LENGTH_M` (1e9, m or rad).
        OptikError: a non-``Robot``; ``dt`` not a number > 0, ``limits`` not a bool,
            ``limit_gain`` outside (0, 1], a bad ``damping``, ``objective`` or ``rows``;
            ``weights`` not (6,) finite and >= 0, conflicting with ``rows``, or freeing
            every least-norm row; ``joint_weights`` not (dof,) finite and > 0;
            ``posture`` not (dof,) finite or an entry beyond ``MAX_LENGTH_M``;
            ``posture_gain`` outside (0, 1].
    """
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    backend = _resolve(solver)
    step = dt if type(dt) is float and 0.0 < dt < math.inf else _check_dt(dt)
    if limits is not True and limits is not False:
        check_bool("limits", limits)
    check_bool("kkt_proof", kkt_proof)
    picked, lam, gain = _options(objective, damping, limit_gain, rows)
    vmax = None
    if velocity_limits is not None:
        vmax = check_velocity_limits(velocity_limits, robot.dof)
    q_arr = q if _is_vector(q, robot.dof) else finite_array("q", q, (robot.dof,))
    twist_arr = twist if _is_vector(twist, 6) else finite_array("twist", twist, (6,))
    if weights is not None or joint_weights is not None or posture is not None:
        tasks = _task_options(robot, objective, picked, weights, joint_weights, posture)
        gain_p = (
            posture_gain
            if type(posture_gain) is float and 0.0 < posture_gain <= 1.0
            else _check_gain("posture_gain", posture_gain)
        )
        return _general_step(
            robot, backend, q_arr, twist_arr, step, objective, limits, vmax, lam, gain,
            tasks, gain_p,
        )  # fmt: skip
    if not (type(posture_gain) is float and 0.0 < posture_gain <= 1.0):
        _check_gain("posture_gain", posture_gain)
    arrays = step_arrays(robot, picked, objective)
    code = arrays.fill(
        q_arr,
        twist_arr,
        step,
        limits=limits,
        limit_gain=gain,
        velocity_limits=vmax,
        damping=lam,
    )
    if code == FILL_INCONSISTENT:
        raise _inconsistent(arrays.program())
    if code != FILL_OK:
        _raise_input_error(robot, q_arr, twist_arr, step, limits)
    label = backend.name
    direct = getattr(backend, "direct", None)
    if direct is not None:
        # The backend's own API on the arrays, and the cheap check (see step_arrays).
        m = 0 if arrays.least_squares else arrays.task_dim
        x, found, status, iterations = direct(arrays.dof, m).solve_scaled(arrays.scaled)
        if x is not None:
            check, _, active = arrays.check(x, FEASIBILITY_RTOL, FEASIBILITY_ATOL, KKT_RTOL)
            if check == CHECK_OK and not kkt_proof:
                if active == 0 or not arrays.least_squares:
                    return arrays.dq.copy()
                # A bound is active: the backend solved P = J^T J + lambda^2 I, whose
                # condition number is the square of the rows' (1e-6 off on a UR5 at its
                # limits); solve again in square-root form, as verify_step does.
                program = arrays.program()
                dq = arrays.dq.copy()
                tol = _tolerance(program)
                return resolve_least_squares(program, dq, tol, KKT_RTOL, FEASIBILITY_ATOL)
            x = x / arrays.scale[1]
        program = arrays.program()
        solution = QPSolution(x, found, status, label, iterations)
    else:
        program = arrays.program()
        solution = backend.solve(program)
    dq, reason = verify_step(program, solution)
    if dq is not None:
        return dq
    error = _no_solution(program, label)
    if error is not None:
        raise error
    raise SolverError(label, f"{reason}; the program has a solution")


@dataclass(frozen=True)
class _Tasks:
    """The validated task keywords of :func:`diff_ik`'s general path."""

    rows: tuple[int, ...]  # the rows the program keeps
    Wt: FloatArray | None  # (len(rows),) task weights, least squares only
    W: FloatArray | None  # (dof,) joint weights
    posture: FloatArray | None  # (dof,) q_ref


def _task_options(
    robot: Robot,
    objective: str,
    picked: tuple[int, ...],
    weights: Any,
    joint_weights: Any,
    posture: Any,
) -> _Tasks:
    """Validate ``weights``, ``joint_weights`` and ``posture``; the rows they leave."""
    rows = picked
    Wt = None
    if weights is not None:
        w = finite_array("weights", weights, (6,))
        if np.any(w < 0.0):
            raise OptikError(f"weights must be >= 0, got {w.tolist()}")
        dropped = [i for i in range(6) if i not in picked and w[i] > 0.0]
        if dropped:
            raise OptikError(
                f"weights conflict with rows {picked}: rows {dropped} have positive weights "
                "but rows leaves them out (give them weight 0, or add them to rows)"
            )
        if objective == "least_norm":
            # The equality holds exactly: a positive weight changes nothing, zero frees.
            rows = tuple(i for i in picked if w[i] > 0.0)
            if not rows:
                raise OptikError(
                    "weights free every task row: a least-norm step needs at least one "
                    "row with a positive weight"
                )
        else:
            Wt = w[list(picked)].copy()
    W = None if joint_weights is None else check_joint_weights(joint_weights, robot.dof)
    q_ref = (
        None
        if posture is None
        else finite_length_array("posture", posture, (robot.dof,), unit="rad or m").copy()
    )
    return _Tasks(rows, Wt, W, q_ref)


def _general_step(
    robot: Robot,
    backend: StepBackend,
    q: FloatArray,
    twist: FloatArray,
    step: float,
    objective: Objective,
    limits: bool,
    vmax: FloatArray | None,
    lam: float,
    gain: float,
    tasks: _Tasks,
    posture_gain: float,
) -> FloatArray:
    """The step with weights or a posture: the general program, the backend, the proof."""
    # The compiled fill validates q and the twist as on the fast path and clips q.
    arrays = step_arrays(robot, tasks.rows, objective)
    code = arrays.fill(
        q, twist, step, limits=limits, limit_gain=gain, velocity_limits=vmax, damping=lam
    )
    if code == FILL_INCONSISTENT:
        raise _inconsistent(arrays.program())
    if code != FILL_OK:
        _raise_input_error(robot, q, twist, step, limits)
    q_start = arrays.q.copy()
    offset = None if tasks.posture is None else posture_gain * (tasks.posture - q_start)
    program = build_program(
        robot,
        q_start,
        twist * step,
        objective=objective,
        dt=step,
        W=tasks.W,
        Wt=tasks.Wt,
        damping=None if objective == "least_norm" else lam,
        limits=limits,
        limit_gain=gain,
        velocity_limits=vmax,
        rows=tasks.rows,
        offset=offset,
    )
    solution = backend.solve(program)
    dq, reason = verify_step(program, solution)
    if dq is not None:
        return dq
    error = _no_solution(program, backend.name)
    if error is not None:
        raise error
    raise SolverError(backend.name, f"{reason}; the program has a solution")


def _check_dt(dt: Any) -> float:
    """``dt`` as a float > 0 (the slow path of :func:`diff_ik`'s check)."""
    step = check_real("dt", dt, allow_nan=True, allow_inf=True)
    if not math.isfinite(step):
        raise NonFiniteError("dt")
    check_real("dt", step, positive=True)
    return step


def _is_vector(value: Any, size: int) -> bool:
    """Already a writable, contiguous float64 array of shape (size,): passed on as is.

    Anything else is converted by the validators first (the compiled checks are compiled
    for this one array type).
    """
    if type(value) is not np.ndarray or value.dtype is not _FLOAT64 or value.shape != (size,):
        return False
    flags = value.flags
    return bool(flags.c_contiguous and flags.writeable)


_FLOAT64: Final = np.dtype(np.float64)


_ZERO_TWIST: Final = np.zeros(6)


def _options(
    objective: Any, damping: Any, limit_gain: Any, rows: Any
) -> tuple[tuple[int, ...], float, float]:
    """The task rows, the damping and the limit gain, validated (the defaults at once)."""
    if objective not in OBJECTIVES:
        raise OptikError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    if objective == "least_norm":
        if damping is not None:
            raise OptikError("damping applies to the least_squares objective only")
        lam = 0.0
    elif damping is None:
        lam = DEFAULT_DAMPING
    else:
        lam = _check_positive("damping", damping, True, maximum=MAX_DAMPING)
    gain = (
        1.0
        if type(limit_gain) is float and limit_gain == 1.0
        else _check_gain("limit_gain", limit_gain)
    )
    if rows is None:
        return ALL_ROWS, lam, gain
    picked = _ROWS.get(rows) if type(rows) is tuple else None
    if picked is None:
        picked, _ = _check_rows(rows, _ZERO_TWIST)
        if type(rows) is tuple and len(_ROWS) < 64:
            _ROWS[rows] = picked
    return picked, lam, gain


_ROWS: dict[tuple[Any, ...], tuple[int, ...]] = {}


def _check_gain(name: str, value: Any) -> float:
    """A gain (``limit_gain``, ``posture_gain``): a finite real number in (0, 1]."""
    gain = _check_positive(name, value)
    if gain > 1.0:
        raise OptikError(f"{name} must lie in (0, 1], got {gain}")
    return gain


def _raise_input_error(
    robot: Robot, q: FloatArray, twist: FloatArray, step: float, limits: bool
) -> None:
    """Raise the error that names the bad argument (the compiled fill found one)."""
    q_arr = clip_into_limits(robot, "q", q) if limits else finite_array("q", q, (robot.dof,))
    robot.check_q(q_arr)
    finite_array("twist", twist, (6,))
    with np.errstate(over="ignore"):  # an overflow to inf is rejected just below
        v = twist * step
    if not np.all(np.abs(v) <= MAX_LENGTH_M):
        # One step of 1e9 m is no servo command, and the program's products would overflow.
        i = int(np.argmax(~(np.abs(v) <= MAX_LENGTH_M)))
        raise ArgumentError(
            f"twist[{i}] * dt", float(v[i]), f"a step of magnitude <= {MAX_LENGTH_M:g}"
        )
    raise OptikError("diff_ik: q or twist rejected by the compiled checks")  # pragma: no cover
