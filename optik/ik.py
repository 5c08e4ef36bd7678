"""The IK API: :func:`solve_ik`, :func:`solve_ik_batch` and :class:`IKResult`.

Warm-start policy: when the robot has a closed-form family that solves the mode, its
branches inside the limits (nearest ``q0`` first) are the starting points; with
``solver="auto"`` the nearest branch *is* the answer (it is exact, verified by FK). An
empty set of branches is a proof: the result says ``"unreachable"``, or
``"outside_limits"`` when branches exist only outside the limits. Without a family,
the solver starts from ``q0`` when given, then from the entries of a seeded table of
configurations whose poses are nearest the target (:mod:`optik.solvers._seeds`), then from
deterministic seeded draws uniform inside the limits, until ``restarts`` or
``timeout_s`` runs out.

``success`` is always computed here, from forward kinematics and the limits, never
copied from a backend.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from optik._checks import FloatArray, finite_array
from optik.analytic import analytic_ik, family_of
from optik.errors import JointLimitError, OptikError, ShapeError
from optik.limits import LIMIT_TOLERANCE
from optik.model import Robot
from optik.solvers import get_solver
from optik.solvers._base import IKQuery, IKSolver, SolverOutput, now
from optik.solvers._lm_kernel import chain_args, lm_solve_batch, lm_solve_batch_serial
from optik.solvers._seeds import nearest_seeds, seed_table
from optik.solvers.iterative import DLSSolver
from optik.spatial import as_pose, as_target, pose_error, rotation_angle

AUTO_NUMERIC_SOLVER = "dls"
"""What ``solver="auto"`` uses without a closed form: the fastest solver that meets the
tolerance in ``benchmarks/bench_ik.py`` (compiled damped least squares)."""

DEFAULT_RESTARTS = 100
"""Restarts after the first attempt when neither ``restarts`` nor ``timeout_s`` is given."""

PARALLEL_BATCH = 64
"""Batches at least this large run in parallel threads; smaller ones on one thread."""

TABLE_STARTS = 4
"""Starts taken from the seed table (nearest poses first) before uniform random draws."""

STATUSES = ("converged", "unreachable", "outside_limits", "max_iter", "timeout", "solver_failed")


@dataclass
class IKResult:
    """The outcome of one IK query, verified by optik.

    Attributes:
        q: joint vector (dof,), rad / m (the best attempt when unsuccessful).
        success: both pose errors within ``tol`` and every joint inside its limits.
        status: one of :data:`STATUSES`.
        position_error: ``||p(q) - p*||`` (m), from forward kinematics.
        orientation_error: rotation angle of ``R*^T R(q)`` (rad); 0 in position mode.
        limit_violation: largest excursion beyond a limit (rad or m); 0 inside.
        iterations: solver iterations over all attempts.
        restarts: attempts after the first.
        time_s: wall time of the call (``time.perf_counter``).
        solver: the method that produced ``q`` (``"analytic"`` for a closed-form branch).
        message: backend text or the reason for the status.
        backend_converged: the backend's own convergence claim for ``q`` (``None`` for the
            closed form).
    """

    q: FloatArray
    success: bool
    status: str
    position_error: float
    orientation_error: float
    limit_violation: float
    iterations: int = 0
    restarts: int = 0
    time_s: float = 0.0
    solver: str = ""
    message: str = ""
    backend_converged: bool | None = None


def _verify(
    robot: Robot, q: FloatArray, target: FloatArray, mode: str
) -> tuple[float, float, float]:
    q = np.ascontiguousarray(q, dtype=float)
    if not np.isfinite(q).all():
        return math.inf, math.inf, math.inf
    position, orientation = pose_error(robot._fk_unchecked(q), target)
    if mode == "position":
        orientation = 0.0
    return position, orientation, robot._violation_unchecked(q)


def _is_success(position: float, orientation: float, violation: float, tol: float) -> bool:
    return position <= tol and orientation <= tol and violation <= LIMIT_TOLERANCE


def _check_q0(robot: Robot, q0: Any) -> FloatArray:
    if q0 is None:
        return robot.mid_limits
    q = finite_array("q0", q0, (robot.dof,))
    for i, joint in enumerate(robot.joints):
        if not (joint.lower - LIMIT_TOLERANCE <= q[i] <= joint.upper + LIMIT_TOLERANCE):
            raise JointLimitError(joint.name, float(q[i]), joint.lower, joint.upper)
    return np.clip(q, robot.lower, robot.upper)


def _check_options(mode: str, tol: float, warm_start: str, timeout_s: Any, restarts: Any) -> None:
    if mode not in ("pose", "position"):
        raise OptikError(f"mode must be 'pose' or 'position', got {mode!r}")
    if not (isinstance(tol, int | float) and math.isfinite(tol) and tol > 0):
        raise OptikError(f"tol must be a positive finite number, got {tol!r}")
    if warm_start not in ("analytic", "q0"):
        raise OptikError(f"warm_start must be 'analytic' or 'q0', got {warm_start!r}")
    if timeout_s is not None and not (timeout_s > 0):
        raise OptikError(f"timeout_s must be positive, got {timeout_s!r}")
    if restarts is not None and (not isinstance(restarts, int) or restarts < 0):
        raise OptikError(f"restarts must be a non-negative integer, got {restarts!r}")


def _check_threads(threads: Any) -> int:
    """``threads`` for :func:`solve_ik_batch`: ``None`` means numba's current count."""
    if threads is None:
        return int(numba.get_num_threads())
    available = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
    if not isinstance(threads, int) or isinstance(threads, bool) or not 1 <= threads <= available:
        raise OptikError(
            f"threads must be an integer from 1 to {available} (numba's NUMBA_NUM_THREADS), "
            f"got {threads!r}"
        )
    return threads


def _random_start(robot: Robot, rng: np.random.Generator) -> FloatArray:
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    return rng.uniform(lower, upper)


def _result(
    robot: Robot,
    q: FloatArray,
    query: IKQuery,
    start_time: float,
    *,
    status_if_failed: str,
    iterations: int,
    restarts: int,
    solver: str,
    message: str,
    claim: bool | None,
) -> IKResult:
    position, orientation, violation = _verify(robot, q, query.target, query.mode)
    success = _is_success(position, orientation, violation, query.tol)
    return IKResult(
        q=q,
        success=success,
        status="converged" if success else status_if_failed,
        position_error=position,
        orientation_error=orientation,
        limit_violation=violation,
        iterations=iterations,
        restarts=restarts,
        time_s=now() - start_time,
        solver=solver,
        message=message if not success else "",
        backend_converged=claim,
    )


def solve_ik(
    robot: Robot,
    target: Any,
    *,
    mode: str = "pose",
    solver: str = "auto",
    q0: Any = None,
    warm_start: str = "analytic",
    tol: float = 1e-6,
    max_iter: int | None = None,
    timeout_s: float | None = None,
    restarts: int | None = None,
    seed: int = 0,
) -> IKResult:
    """Solve IK for one target, with hard joint limits.

    Args:
        robot: the robot.
        target: 4x4 world pose of the tool (``mode="pose"``), or a 3-vector / 4x4 whose
            translation is used (``mode="position"``); metres.
        mode: ``"pose"`` or ``"position"``.
        solver: a name from :func:`optik.available_solvers`, or ``"auto"`` (the closed
            form when the robot has one, else :data:`AUTO_NUMERIC_SOLVER`).
        q0: initial guess (dof,) inside the limits (outside raises
            :class:`~optik.errors.JointLimitError`; it is not clipped silently). Default:
            none: numeric solvers start from the seed table's nearest entry, and
            closed-form branches are ordered by their distance to mid-limits.
        warm_start: ``"analytic"`` (closed-form branches as starting points when a family
            exists) or ``"q0"`` (ignore the closed form).
        tol: position (m) and orientation (rad) tolerance of success.
        max_iter: iterations per attempt (default: the solver's own).
        timeout_s: wall-time budget for all attempts.
        restarts: attempts after the first (default: :data:`DEFAULT_RESTARTS` without a
            timeout, unlimited within a timeout).
        seed: seed of the restart sequence (results are deterministic for a seed).

    Returns:
        An :class:`IKResult`; a well-formed query that cannot be solved gives
        ``success=False`` and a status, never an exception.

    Raises:
        OptikError: malformed target, ``q0``, options, or an unknown solver name.
    """
    start_time = now()
    _check_options(mode, tol, warm_start, timeout_s, restarts)
    T_target = as_target(target, mode)
    q_start = _check_q0(robot, q0)
    numeric: IKSolver | None = None if solver == "auto" else get_solver(solver)
    query = IKQuery(robot, T_target, mode, float(tol))
    deadline = start_time + timeout_s if timeout_s is not None else math.inf

    starts: list[FloatArray] = []
    family = family_of(robot) if warm_start == "analytic" else None
    if family is not None and mode in family.modes:
        branches = analytic_ik(robot, T_target, mode, q_ref=q_start)
        if not branches:
            outside = analytic_ik(robot, T_target, mode, q_ref=q_start, within_limits=False)
            status = "outside_limits" if outside else "unreachable"
            q_report = outside[0] if outside else q_start
            reason = (
                "closed form: every branch lies outside the joint limits"
                if outside
                else "closed form: no branch reaches the target"
            )
            return _result(
                robot,
                q_report,
                query,
                start_time,
                status_if_failed=status,
                iterations=0,
                restarts=0,
                solver="analytic",
                message=reason,
                claim=None,
            )
        if numeric is None:
            return _result(
                robot,
                branches[0],
                query,
                start_time,
                status_if_failed="max_iter",
                iterations=0,
                restarts=0,
                solver="analytic",
                message="",
                claim=None,
            )
        starts = branches
    if numeric is None:
        numeric = get_solver(AUTO_NUMERIC_SOLVER)
    iterations_per_attempt = max_iter if max_iter is not None else numeric.default_max_iter
    budget = restarts if restarts is not None else (DEFAULT_RESTARTS if timeout_s is None else -1)
    rng = np.random.default_rng(seed)
    if not starts and q0 is not None:
        starts = [q_start]

    if isinstance(numeric, DLSSolver) and budget >= 0 and math.isinf(deadline):
        # The whole restart loop runs compiled, from the first start (the nearest branch,
        # exact, when there is a closed form); the answer is verified below all the same.
        output, used = numeric.solve_restarts(
            query, starts[0] if starts else None, iterations_per_attempt, budget, seed
        )
        return _result(
            robot,
            output.q,
            query,
            start_time,
            status_if_failed="max_iter",
            iterations=output.iterations,
            restarts=used,
            solver=numeric.name,
            message=output.message,
            claim=output.converged,
        )

    best: SolverOutput | None = None
    best_error = math.inf
    total_iterations = 0
    attempts = 0
    timed_out = False
    all_failed = True
    table: FloatArray | None = None
    while True:
        if budget >= 0 and attempts > budget:
            break
        if attempts < len(starts):
            start = starts[attempts]
        else:
            if table is None:  # only when the given starts are exhausted
                table = nearest_seeds(robot, T_target, mode, TABLE_STARTS)
            k = attempts - len(starts)
            start = table[k] if k < len(table) else _random_start(robot, rng)
        if attempts > 0 and now() > deadline:
            timed_out = True
            break
        try:
            output = numeric.solve(query, start, iterations_per_attempt, deadline)
        except Exception as exc:  # a backend crash becomes a status, with its text
            best = SolverOutput(start, 0, False, f"{type(exc).__name__}: {exc}", failed=True)
            attempts += 1
            break
        attempts += 1
        total_iterations += output.iterations
        all_failed = all_failed and output.failed
        if output.failed:
            if best is None:
                best = output
            continue
        position, orientation, violation = _verify(robot, output.q, T_target, mode)
        error = position + orientation + violation
        if best is None or best.failed or error < best_error:
            best, best_error = output, error
        if _is_success(position, orientation, violation, tol):
            break
        if now() > deadline:
            timed_out = True
            break
    if best is None:  # pragma: no cover - at least one attempt always runs
        raise OptikError("no IK attempt ran")
    if all_failed:
        status = "solver_failed"
    elif timed_out:
        status = "timeout"
    else:
        status = "max_iter"
    return _result(
        robot,
        best.q,
        query,
        start_time,
        status_if_failed=status,
        iterations=total_iterations,
        restarts=max(attempts - 1, 0),
        solver=numeric.name,
        message=best.message,
        claim=best.converged,
    )


@dataclass
class IKBatchResult:
    """Verified outcomes of :func:`solve_ik_batch`, one row per target.

    Attributes:
        q: (N, dof) joint vectors.
        success: (N,) verified success (FK errors within ``tol``, limits respected).
        position_error: (N,) m.
        orientation_error: (N,) rad (0 in position mode).
        iterations: (N,) iterations over all attempts.
        restarts: (N,) attempts after the first.
        time_s: wall time of the whole batch.
    """

    q: FloatArray
    success: np.ndarray
    position_error: FloatArray
    orientation_error: FloatArray
    iterations: np.ndarray
    restarts: np.ndarray
    time_s: float


def solve_ik_batch(
    robot: Robot,
    targets: Any,
    *,
    mode: str = "pose",
    q0: Any = None,
    tol: float = 1e-6,
    max_iter: int = 100,
    restarts: int = DEFAULT_RESTARTS,
    seed: int = 0,
    threads: int | None = None,
) -> IKBatchResult:
    """Solve many targets with the compiled damped least squares, in parallel threads.

    Every target starts from ``q0`` when given, then from the seed table's entries nearest
    it and seeded uniform draws (target ``k`` uses seed ``seed + k``, so results do not
    depend on the thread count).

    Args:
        robot: the robot.
        targets: (N, 4, 4) world poses (in position mode only translations count; an
            (N, 3) array of positions is accepted too).
        mode: ``"pose"`` or ``"position"``.
        q0: shared initial guess (dof,).
        tol: position (m) and orientation (rad) tolerance.
        max_iter: iterations per attempt.
        restarts: attempts after the first.
        seed: base seed of the restarts.
        threads: worker threads (default: numba's current thread count,
            ``numba.get_num_threads()``); 1 solves on the calling thread. Batches smaller
            than :data:`PARALLEL_BATCH` always do.
    """
    start_time = now()
    _check_options(mode, tol, "q0", None, restarts)
    threads = _check_threads(threads)
    array = np.asarray(targets, dtype=float)
    if mode == "position" and array.ndim == 2 and array.shape[1] == 3:
        poses = np.broadcast_to(np.eye(4), (array.shape[0], 4, 4)).copy()
        poses[:, :3, 3] = finite_array("targets", array, (3,), batch=True)
    elif array.ndim == 3 and array.shape[1:] == (4, 4):
        poses = as_pose("targets", array, batch=True)
        if mode == "position":
            poses = poses.copy()
            poses[:, :3, :3] = np.eye(3)
    else:
        raise ShapeError("targets", "(N, 4, 4) (or (N, 3) in position mode)", array.shape)
    q_start = _check_q0(robot, q0)
    table = seed_table(robot)
    parallel = threads > 1 and len(poses) >= PARALLEL_BATCH
    kernel = lm_solve_batch if parallel else lm_solve_batch_serial
    previous_threads = numba.get_num_threads()
    if parallel:
        numba.set_num_threads(threads)
    try:
        Q, iterations, used, _ = kernel(
            *chain_args(robot),
            np.ascontiguousarray(poses),
            mode == "pose",
            q_start,
            q0 is not None,
            *table,
            float(tol),
            int(max_iter),
            DLSSolver.w_bias,
            int(restarts),
            int(seed),
        )
    finally:
        numba.set_num_threads(previous_threads)
    T = robot.fk(Q)
    position = np.linalg.norm(T[:, :3, 3] - poses[:, :3, 3], axis=1)
    if mode == "pose":
        R_rel = np.swapaxes(poses[:, :3, :3], 1, 2) @ T[:, :3, :3]
        orientation = np.asarray(rotation_angle(R_rel), dtype=float).reshape(-1)
    else:
        orientation = np.zeros(len(Q))
    violation = np.asarray(robot.limit_violation(Q), dtype=float).reshape(-1)
    success = (position <= tol) & (orientation <= tol) & (violation <= LIMIT_TOLERANCE)
    return IKBatchResult(Q, success, position, orientation, iterations, used, now() - start_time)
