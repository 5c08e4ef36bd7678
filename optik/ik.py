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

from optik._checks import (
    FloatArray,
    as_float_array,
    check_choice,
    check_int,
    check_real,
    finite_array,
)
from optik.analytic import AnalyticFamily, analytic_ik, family_of
from optik.diffik import clip_into_limits
from optik.errors import ArgumentError, OptikError, ShapeError
from optik.model import Robot
from optik.poses import as_target_pose
from optik.solvers import get_solver
from optik.solvers._base import IKQuery, IKSolver, now
from optik.solvers._lm_kernel import lm_solve_batch, lm_solve_batch_serial
from optik.solvers._seeds import seed_table, start_sequence
from optik.solvers.iterative import DLSSolver
from optik.spatial import as_pose
from optik.verify import verify, verify_one

AUTO_NUMERIC_SOLVER = "dls"
"""What ``solver="auto"`` uses without a closed form: the fastest solver that meets the
tolerance in ``benchmarks/bench_ik.py`` (compiled damped least squares)."""

DEFAULT_RESTARTS = 100
"""Restarts after the first attempt when neither ``restarts`` nor ``timeout_s`` is given."""

PARALLEL_BATCH = 64
"""Batches at least this large run in parallel threads; smaller ones on one thread."""

UNLIMITED_RESTARTS = 2**62
"""The restart budget within a finite ``timeout_s`` when ``restarts`` is not given."""

BATCH_SLICE = 4096
"""Targets per compiled call of :func:`solve_ik_batch`: between calls Python lets a
``KeyboardInterrupt`` through."""

MAX_SEED = 2**63 - 1
"""Largest ``seed`` (the streams are 64-bit)."""

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


def _check_q0(robot: Robot, q0: Any) -> FloatArray:
    """``q0`` as a (dof,) array inside the limits; see :func:`optik.diffik.clip_into_limits`."""
    if q0 is None:
        return robot.mid_limits
    return clip_into_limits(robot, "q0", q0)


def _check_options(
    mode: Any,
    tol: Any,
    warm_start: Any,
    timeout_s: Any,
    restarts: Any,
    max_iter: Any = None,
    seed: Any = 0,
) -> None:
    """Validate the keywords shared by :func:`solve_ik` and :func:`solve_ik_batch`."""
    check_choice("mode", mode, ("pose", "position"))
    check_real("tol", tol, positive=True)
    check_choice("warm_start", warm_start, ("analytic", "q0"))
    if timeout_s is not None:
        check_real("timeout_s", timeout_s, positive=True, allow_inf=True)
    if restarts is not None:
        check_int("restarts", restarts, minimum=0, maximum=UNLIMITED_RESTARTS)
    if max_iter is not None:
        check_int("max_iter", max_iter, minimum=1, maximum=10**9)
    check_int("seed", seed, minimum=0, maximum=MAX_SEED)


def _check_threads(threads: Any) -> int:
    """``threads`` for :func:`solve_ik_batch`: ``None`` means numba's current count."""
    if threads is None:
        return int(numba.get_num_threads())
    available = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
    if isinstance(threads, float):  # an integral float is not a thread count
        raise ArgumentError("threads", threads, f"an integer from 1 to {available}")
    # NUMBA_NUM_THREADS is numba's ceiling: set_num_threads refuses more.
    return check_int("threads", threads, minimum=1, maximum=available)


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
    position, orientation, violation, success = verify_one(
        robot, q, query.target, query.mode, query.tol
    )
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


CROSS_CHECK_RESTARTS = 20
"""Restarts of the numeric attempt that checks a closed form's "no branch" before it is
reported as a proof: at singular poses (a wrist or elbow aligned, a joint free) a closed
form can miss the one-parameter family of solutions that passes through them."""


def _family_solves(robot: Robot, family: AnalyticFamily, mode: str) -> bool:
    """Whether the closed form applies (position-only closed forms place the flange).

    The mode must be one the family solves, and for position-only IK the tool must have
    no offset.
    """
    if mode not in family.modes:
        return False
    return mode != "position" or not np.any(np.abs(robot.T_flange_tool[:3, 3]) > 0.0)


def _closed_form_proof(
    robot: Robot, query: IKQuery, q_start: FloatArray, start_time: float, seed: int
) -> IKResult:
    """The result when the closed form finds no branch inside the limits, cross-checked.

    Before ``unreachable`` or ``outside_limits`` is reported, a short ``dls`` run
    (:data:`CROSS_CHECK_RESTARTS`, from the out-of-limit branches clipped into the limits,
    then the seed table) looks for an answer the closed form missed at a degenerate pose;
    if it finds a verified one, that answer is returned.
    """
    outside = analytic_ik(robot, query.target, query.mode, q_ref=q_start, within_limits=False)
    given = [np.clip(q, robot.lower, robot.upper) for q in outside] or [q_start]
    numeric = get_solver(AUTO_NUMERIC_SOLVER)
    sequence = start_sequence(robot, query.target, query.mode, given, seed)
    run = numeric.run(query, sequence, numeric.default_max_iter, CROSS_CHECK_RESTARTS, math.inf)
    found = verify_one(robot, run.q, query.target, query.mode, query.tol)[3]
    if found:
        return _result(
            robot,
            run.q,
            query,
            start_time,
            status_if_failed="max_iter",
            iterations=run.iterations,
            restarts=run.restarts,
            solver=numeric.name,
            message="",
            claim=run.converged,
        )
    status = "outside_limits" if outside else "unreachable"
    reason = (
        "closed form: every branch lies outside the joint limits"
        if outside
        else "closed form: no branch reaches the target"
    )
    return _result(
        robot,
        outside[0] if outside else q_start,
        query,
        start_time,
        status_if_failed=status,
        iterations=run.iterations,
        restarts=run.restarts,
        solver="analytic",
        message=reason + f" (a {numeric.name} cross-check found no answer either)",
        claim=None,
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
        target: world pose of the tool (``mode="pose"``): a 4x4, a ``(p, R)`` pair or a
            mapping of :func:`optik.pose`'s keywords (e.g. ``{"position": p,
            "quat_wxyz": q}``); in position mode also a 3-vector (metres). See
            :func:`optik.as_target_pose`.
        mode: ``"pose"`` or ``"position"``.
        solver: a name from :func:`optik.available_solvers`, or ``"auto"`` (the closed
            form when the robot has one, else :data:`AUTO_NUMERIC_SOLVER`).
        q0: initial guess (dof,) inside the limits; within
            :data:`~optik.limits.Q_CLIP_TOLERANCE` outside them it is clipped onto them,
            beyond it raises :class:`~optik.errors.JointLimitError`. Default:
            none: numeric solvers start from the seed table's nearest entry, and
            closed-form branches are ordered by their distance to mid-limits.
        warm_start: ``"analytic"`` (closed-form branches as starting points when a family
            exists) or ``"q0"`` (ignore the closed form).
        tol: position (m) and orientation (rad) tolerance of success.
        max_iter: iterations per attempt (default: the solver's own).
        timeout_s: wall-time budget (s) for all attempts; ``inf`` means no time limit
            (the restart budget then stays :data:`DEFAULT_RESTARTS`). Compilation on a
            first call in a fresh environment is counted too.
        restarts: attempts after the first (default: :data:`DEFAULT_RESTARTS` without a
            finite timeout, unlimited within one).
        seed: seed of the restart sequence, 0 to 2**63 - 1 (results are deterministic
            for a seed, and the same with and without ``timeout_s`` until it cuts the run
            short: :mod:`optik.solvers._starts`).

    Returns:
        An :class:`IKResult`; a well-formed query that cannot be solved gives
        ``success=False`` and a status, never an exception.

    Raises:
        OptikError: malformed target, ``q0``, options, or an unknown solver name.
    """
    start_time = now()
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    _check_options(mode, tol, warm_start, timeout_s, restarts, max_iter, seed)
    if not isinstance(solver, str):
        raise OptikError(f"solver must be a solver name (str), got {solver!r}")
    T_target = as_target_pose(target, mode)
    q_start = _check_q0(robot, q0)
    numeric: IKSolver | None = None if solver == "auto" else get_solver(solver)
    query = IKQuery(robot, T_target, mode, float(tol))
    # timeout_s=inf is "no time limit": the restart budget then stays finite.
    deadline = start_time + float(timeout_s) if timeout_s is not None else math.inf

    starts: list[FloatArray] = []
    family = family_of(robot) if warm_start == "analytic" else None
    if family is not None and _family_solves(robot, family, mode):
        branches = analytic_ik(robot, T_target, mode, q_ref=q_start)
        if not branches:
            return _closed_form_proof(robot, query, q_start, start_time, int(seed))
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
    # No closed form: the reach sphere still proves a target unreachable.
    centre, radius = robot.reach_sphere
    if float(np.linalg.norm(T_target[:3, 3] - centre)) > radius + tol:
        return _result(
            robot,
            q_start,
            query,
            start_time,
            status_if_failed="unreachable",
            iterations=0,
            restarts=0,
            solver="reach",
            message=(
                f"the target lies {float(np.linalg.norm(T_target[:3, 3] - centre)):.6g} m from "
                f"the reach sphere's centre, beyond its radius {radius:.6g} m"
            ),
            claim=None,
        )

    if numeric is None:
        numeric = get_solver(AUTO_NUMERIC_SOLVER)
    iterations_per_attempt = max_iter if max_iter is not None else numeric.default_max_iter
    if restarts is not None:
        last = int(restarts)
    else:
        last = UNLIMITED_RESTARTS if math.isfinite(deadline) else DEFAULT_RESTARTS
    if not starts and q0 is not None:
        starts = [q_start]
    sequence = start_sequence(robot, T_target, mode, starts, int(seed))
    run = numeric.run(query, sequence, int(iterations_per_attempt), last, deadline)
    return _result(
        robot,
        run.q,
        query,
        start_time,
        status_if_failed=run.status_if_failed,
        iterations=run.iterations,
        restarts=run.restarts,
        solver=numeric.name,
        message=run.message,
        claim=run.converged,
    )


BATCH_STATUSES = ("converged", "unreachable", "max_iter")
"""Per-target statuses of :func:`solve_ik_batch`: ``unreachable`` is proved (the target
lies outside the robot's reach sphere, :attr:`optik.Robot.reach_sphere`)."""


@dataclass
class IKBatchResult:
    """Verified outcomes of :func:`solve_ik_batch`, one row per target.

    Attributes:
        q: (N, dof) joint vectors (the best attempt where unsuccessful; NaN where the
            target was proved unreachable and not solved).
        success: (N,) verified success (FK errors within ``tol``, limits respected).
        status: (N,) strings from :data:`BATCH_STATUSES`.
        position_error: (N,) m (inf where not solved).
        orientation_error: (N,) rad (0 in position mode).
        limit_violation: (N,) largest excursion beyond a limit (rad or m).
        iterations: (N,) iterations over all attempts.
        restarts: (N,) attempts after the first.
        time_s: wall time of the whole batch.
    """

    q: FloatArray
    success: np.ndarray
    status: np.ndarray
    position_error: FloatArray
    orientation_error: FloatArray
    limit_violation: FloatArray
    iterations: np.ndarray
    restarts: np.ndarray
    time_s: float


def _batch_poses(targets: Any, mode: str) -> FloatArray:
    """(N, 4, 4) validated target poses (identity rotations in position mode)."""
    array = as_float_array("targets", targets)  # rejects ragged, complex, bool, strings
    if array.ndim >= 1 and array.shape[0] == 0:
        expected = (3,) if (mode == "position" and array.ndim == 2) else (4, 4)
        return np.empty((0, 4, 4)) if array.shape[1:] in ((4, 4), expected) else _bad(array)
    if mode == "position" and array.ndim == 2 and array.shape[1:] == (3,):
        poses = np.broadcast_to(np.eye(4), (array.shape[0], 4, 4)).copy()
        poses[:, :3, 3] = finite_array("targets", array, (3,), batch=True)
        return poses
    if array.ndim == 3 and array.shape[1:] == (4, 4):
        poses = as_pose("targets", array, batch=True)
        if mode == "position":
            poses = poses.copy()
            poses[:, :3, :3] = np.eye(3)
        return np.ascontiguousarray(poses, dtype=np.float64)
    return _bad(array)


def _bad(array: np.ndarray) -> FloatArray:
    raise ShapeError("targets", "(N, 4, 4) (or (N, 3) in position mode)", array.shape)


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
    it and seeded uniform draws (:mod:`optik.solvers._starts`; target ``k`` uses the stream
    ``seed + k``, so results do not depend on the thread count or the slicing). Targets
    outside the robot's reach sphere are not solved: their status is ``"unreachable"``.

    Args:
        robot: the robot.
        targets: (N, 4, 4) world poses (in position mode only translations count; an
            (N, 3) array of positions is accepted too); N may be 0.
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
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    _check_options(mode, tol, "q0", None, restarts, max_iter, seed)
    if seed > MAX_SEED - 2**40:  # target k uses seed + k
        raise OptikError(f"seed must be at most 2**63 - 2**40 in a batch, got {seed!r}")
    threads = _check_threads(threads)
    poses = _batch_poses(targets, mode)
    q_start = _check_q0(robot, q0)
    N = poses.shape[0]
    Q = np.full((N, robot.dof), math.nan)
    iterations = np.zeros(N, dtype=np.int64)
    used = np.zeros(N, dtype=np.int64)
    centre, radius = robot.reach_sphere
    with np.errstate(over="ignore"):  # a target 1e154 m away is simply unreachable
        distance = np.linalg.norm(poses[:, :3, 3] - centre, axis=1)
    reachable = distance <= radius * (1 + 1e-9) + 1e-12
    rows = np.flatnonzero(reachable)
    table = seed_table(robot)
    given = q_start.reshape(1, -1) if q0 is not None else np.empty((0, robot.dof))
    K, prismatic, C, identity, lower, upper = robot.chain.kernel_args()
    previous_threads = numba.get_num_threads()
    try:
        for lo in range(0, len(rows), BATCH_SLICE):
            part = rows[lo : lo + BATCH_SLICE]
            parallel = threads > 1 and len(part) >= PARALLEL_BATCH
            kernel = lm_solve_batch if parallel else lm_solve_batch_serial
            if parallel:
                numba.set_num_threads(threads)
            # Target k keeps the stream seed + k whatever slice it falls in.
            Qp, it, u, _ = kernel(
                K, prismatic, C, identity, lower, upper, np.ascontiguousarray(poses[part]),
                mode == "pose", given, *table, float(tol), int(max_iter), DLSSolver.w_bias,
                int(restarts), part.astype(np.int64) + int(seed),
            )  # fmt: skip
            Q[part], iterations[part], used[part] = Qp, it, u
    finally:
        numba.set_num_threads(previous_threads)
    verdict = verify(robot, Q, poses, mode, float(tol))
    status = np.where(verdict.success, "converged", np.where(reachable, "max_iter", "unreachable"))
    return IKBatchResult(
        Q,
        verdict.success,
        status.astype(object),
        verdict.position_error,
        verdict.orientation_error,
        verdict.limit_violation,
        iterations,
        used,
        now() - start_time,
    )
