"""Many IK targets at once: :func:`solve_ik_batch` and :class:`IKBatchResult`.

Where the robot has a closed form with a compiled pipeline, each target's branch nearest
its ``q0`` is its answer, as in :func:`optik.solve_ik`; the other targets run the compiled
damped least squares (:mod:`optik.solvers._lm_kernel`) in worker threads
(:mod:`optik.solvers._batch_threads`), each with its own random stream, and a closed form
run in Python (or, for a tool-axis task, a compiled one over a grid of rolls) answers the
targets that search missed. The batch is verified in one compiled call
(:func:`optik.verify.verify`). Importable from :mod:`optik.ik` and :mod:`optik` too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, cast

import numba
import numpy as np

from optik._checks import FloatArray, as_float_array, check_bool, check_int, finite_array
from optik._ik_options import (
    CROSS_CHECK_RESTARTS,
    DEFAULT_RESTARTS,
    MAX_SEED,
    check_options,
    check_q0,
    query_bounds,
)
from optik._interrupts import surfaces_interrupts
from optik.analytic import (
    AnalyticFamily,
    checked_batch,
    compiled_batch,
    family_of,
    family_solves,
    wrap_into_limits,
)
from optik.analytic.roll import ROLL_GRID, roll_grid, rolled_poses, solves_axis_task
from optik.diffik import clip_into_limits
from optik.errors import ArgumentError, OptikError, ShapeError
from optik.limits import LIMIT_TOLERANCE, into_box, limit_violation
from optik.model import Robot
from optik.solvers._base import (
    IKQuery,
    compromise,
    now,
    search_length,
    within_reach_of_tolerance,
)
from optik.solvers._batch_threads import solve_batch
from optik.solvers._seeds import seed_table
from optik.solvers.iterative import DLSSolver
from optik.spatial import as_pose
from optik.task import Task, balanced_search, make_task
from optik.verify import Verdict, beyond_reach_task, verify

PARALLEL_BATCH = 64
"""Batches at least this large run in parallel threads; smaller ones on one thread."""

BATCH_SLICE = 4096
"""Targets per compiled call of :func:`solve_ik_batch`: between calls Python lets a
``KeyboardInterrupt`` through."""

MAX_BATCH_RESTARTS = 10_000
"""Largest ``restarts`` of :func:`solve_ik_batch`: a target's restarts run inside one
compiled call, and the batch returns to Python (and Ctrl-C) only between slices of
:data:`BATCH_SLICE` targets."""


def _check_threads(threads: Any) -> int:
    """``threads`` for :func:`solve_ik_batch`: ``None`` means numba's current count."""
    if threads is None:
        return int(numba.get_num_threads())
    available = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
    if isinstance(threads, float):  # an integral float is not a thread count
        raise ArgumentError("threads", threads, f"an integer from 1 to {available}")
    # NUMBA_NUM_THREADS is numba's ceiling: set_num_threads refuses more.
    return check_int("threads", threads, minimum=1, maximum=available)


def _given_starts(
    robot: Robot, q0: Any, n: int, bounds: tuple[FloatArray, FloatArray] | None
) -> FloatArray:
    """The batch's given starts (P, G, dof), each checked like :func:`solve_ik`'s ``q0``.

    ``(1, 0, dof)`` without ``q0``, ``(1, 1, dof)`` for a shared (dof,) ``q0``, ``(n, 1,
    dof)`` for one per target; clipped into ``bounds``.
    """
    if q0 is None:
        return np.empty((1, 0, robot.dof))
    array = as_float_array("q0", q0)
    if array.ndim == 2 and array.shape[1] == robot.dof and len(array) == n:
        # Each row named by its index (a NaN in row 1 was reported at "index (2,)").
        rows = np.array(
            [clip_into_limits(robot, f"q0[{k}]", row) for k, row in enumerate(array)]
        ).reshape(n, 1, robot.dof)
    elif array.ndim == 1:
        rows = check_q0(robot, array).reshape(1, 1, robot.dof)
    else:
        raise ShapeError("q0", f"({robot.dof},) or ({n}, {robot.dof})", array.shape)
    if bounds is not None:
        rows = np.clip(rows, bounds[0], bounds[1])
    return np.ascontiguousarray(rows)


BATCH_STATUSES = ("converged", "unreachable", "outside_limits", "max_iter")
"""Per-target statuses of :func:`solve_ik_batch`. ``unreachable`` and ``outside_limits``
are proofs, as :func:`optik.solve_ik` makes them: the target lies outside the robot's
reach sphere (:attr:`optik.Robot.reach_sphere`), or the closed form has no branch at all
(``unreachable``) or only branches outside the limits (``outside_limits``), and a
cross-check search found no answer either. ``max_iter`` proves nothing."""


@dataclass
class IKBatchResult:
    """Verified outcomes of :func:`solve_ik_batch`, one row per target.

    Attributes:
        q: (N, dof) joint vectors (the best attempt where unsuccessful; NaN where the
            target lies beyond the reach sphere and was not solved, except with graded
            weights, which take their compromise there too, from the row's ``q0``). An
            ``outside_limits`` row holds, as :func:`optik.solve_ik` does, the closed
            form's branch nearest the row's ``q0`` (beyond the limits, reaching the
            target), or with graded weights the compromise inside the limits.
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


def _batch_poses(targets: Any, mode: str, framed: bool = False) -> FloatArray:
    """(N, 4, 4) validated target poses, identity rotations in position mode.

    With ``framed``, poses given with a rotation keep it: the weights are on its axes.
    """
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
        if mode == "position" and not framed:
            poses = poses.copy()
            poses[:, :3, :3] = np.eye(3)
        return np.ascontiguousarray(poses, dtype=np.float64)
    return _bad(array)


def _compromise(
    robot: Robot,
    job: tuple[Task, FloatArray, Any],
    Q: FloatArray,
    iterations: np.ndarray,
    failed: np.ndarray,
) -> None:
    """The graded task's compromise from each failed row's best ``Q`` (in place).

    ``job`` is ``(task, poses (N, 4, 4), bounds)``. The search ran on the
    task's search twin; where it found no answer, the graded weights choose the
    compromise (:func:`optik.solvers._base.compromise`, as for one target).
    """
    task, poses, bounds = job
    for k in failed:
        query = IKQuery(robot, poses[k], task.mode, task.position_tol, task, bounds)
        Q[k], it, _ = compromise(query, Q[k])
        iterations[k] += it


def _row_starts(
    robot: Robot,
    given: FloatArray,
    rows: np.ndarray,
    bounds: tuple[FloatArray, FloatArray] | None,
) -> FloatArray:
    """The first start (M, dof) of each of ``rows`` (M,), as in :func:`optik.solve_ik`.

    The row's ``q0`` (``given``, from :func:`_given_starts`), else the middle of the
    limits clipped into ``bounds``.
    """
    if given.shape[1] > 0:
        return given[rows if given.shape[0] > 1 else np.zeros_like(rows), 0]
    start = robot.mid_limits if bounds is None else np.clip(robot.mid_limits, *bounds)
    return np.tile(start, (len(rows), 1))


def _batch_family(robot: Robot, task: Task) -> AnalyticFamily | None:
    """The robot's (fast) closed-form family where it answers ``task``, else ``None``.

    The rule of :func:`optik.solve_ik` (:func:`optik.analytic.family_solves`).
    """
    family = family_of(robot)
    if family is None or not family.fast:
        return None
    return family if family_solves(family, robot, task) else None


def _roll_family(robot: Robot, task: Task) -> AnalyticFamily | None:
    """The compiled full-pose family that answers the axis ``task`` over its roll, else ``None``.

    The rule of :func:`optik.solve_ik` (:func:`optik.analytic.roll.solves_axis_task`),
    for a family whose batch runs compiled (a grid of rolls is many poses per target).
    """
    family = family_of(robot)
    if family is None or not family.fast or not solves_axis_task(family, task):
        return None
    return family if compiled_batch(robot, "pose") else None


def _roll_grid_rows(
    robot: Robot,
    family: AnalyticFamily,
    poses: FloatArray,
    axis: int,
    refs: FloatArray,
    bounds: tuple[FloatArray, FloatArray] | None,
    threads: int = 1,
) -> FloatArray:
    """Each axis target's closed-form answer on the roll grid nearest its reference (M, dof).

    The grid of :func:`optik.analytic.roll.grid_branches` (:data:`ROLL_GRID` rolls about
    the tool axis, index ``axis``): every rolled pose's branch nearest the target's
    reference inside the query's box (:func:`_branches`), then the nearest over the rolls.
    Each row is a full-pose branch of a rolled pose, so exact in the axis task. NaN rows
    where no roll has a branch in the box: no proof (an answer can lie between two rolls).
    ``poses`` (M, 4, 4), ``refs`` (M, dof).
    """
    M, dof = len(poses), robot.dof
    out = np.full((M, dof), math.nan)
    turns = rolled_poses(np.eye(4), axis, roll_grid())
    per_call = max(1, BATCH_SLICE // ROLL_GRID)
    for lo in range(0, M, per_call):
        hi = min(lo + per_call, M)
        rolled = np.repeat(poses[lo:hi], ROLL_GRID, axis=0).reshape(hi - lo, ROLL_GRID, 4, 4)
        rolled[:, :, :3, :3] = poses[lo:hi, None, :3, :3] @ turns[None, :, :3, :3]
        ref = np.repeat(refs[lo:hi], ROLL_GRID, axis=0)
        rows = _branches(robot, family, "pose", rolled.reshape(-1, 4, 4), ref, bounds, threads)
        rows = rows.reshape(hi - lo, ROLL_GRID, dof)
        distance = np.linalg.norm(rows - refs[lo:hi, None, :], axis=2)
        distance = np.where(np.isfinite(distance), distance, math.inf)
        nearest = np.argmin(distance, axis=1)
        index = np.arange(hi - lo)
        found = np.isfinite(distance[index, nearest])
        out[lo:hi][found] = rows[index, nearest][found]
    return out


def _branches(
    robot: Robot,
    family: AnalyticFamily,
    mode: str,
    poses: FloatArray,
    refs: FloatArray,
    bounds: tuple[FloatArray, FloatArray] | None,
    threads: int = 1,
) -> FloatArray:
    """Each pose's closed-form branch nearest its reference inside the query's box (M, dof).

    ``poses`` (M, 4, 4), ``refs`` (M, dof). Batched calls of :data:`BATCH_SLICE` poses
    (:func:`optik.analytic.checked_batch`, without the polish of a pose that has no
    branch: the search answers there), on ``threads`` worker threads when there are
    several slices (the compiled pipeline releases the GIL); a frozen joint is held to
    rounding (:func:`optik.limits.into_box`). NaN rows where there is none.
    """
    M = len(poses)
    out = np.full((M, robot.dof), math.nan)
    refs = np.ascontiguousarray(refs, dtype=np.float64)
    lower, upper = bounds if bounds is not None else (robot.lower, robot.upper)

    def piece(lo: int) -> None:
        hi = min(lo + BATCH_SLICE, M)
        rows = checked_batch(robot, family, poses[lo:hi], mode, refs[lo:hi], True, polish=False).q
        if bounds is not None:
            # Into the box nearest the reference, as solve_ik (the pipeline wrapped them
            # into the limits: a margin's band can hold a branch a turn away from the box).
            rows = wrap_into_limits(rows, robot, refs[lo:hi, None, :], bounds)
        inside, clipped = into_box(rows, lower, upper)  # (m, B), (m, B, dof)
        # Nearest the reference among those inside (a turn into the box moves a branch).
        distance = np.linalg.norm(clipped - refs[lo:hi, None, :], axis=2)
        nearest = np.argmin(np.where(inside, distance, math.inf), axis=1)
        index = np.arange(hi - lo)
        found = inside[index, nearest]
        out[lo:hi][found] = clipped[index, nearest][found]

    starts = list(range(0, M, BATCH_SLICE))
    if threads > 1 and len(starts) > 1:
        # The family and its compiled plan are cached on the robot already (the caller
        # asked compiled_batch): the workers only read them.
        with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="optik-branches") as pool:
            list(pool.map(piece, starts))
    else:
        for lo in starts:
            piece(lo)
    return out


def _unlimited_branches(
    robot: Robot, family: AnalyticFamily, mode: str, poses: FloatArray, refs: FloatArray
) -> tuple[FloatArray, np.ndarray]:
    """Each pose's closed-form branches with the limits ignored, nearest its reference first.

    ``poses`` (M, 4, 4), ``refs`` (M, dof). What :func:`optik.solve_ik`'s proof takes
    (``analytic_ik(..., within_limits=False)``, polish of a degenerate pose included), for
    every pose at once: ``(branches (M, B, dof) NaN-padded, counts (M,))``.
    """
    refs = np.ascontiguousarray(refs)
    batch = checked_batch(robot, family, poses, mode, refs, False, polish=True)
    return batch.q, batch.counts


def _verdict(
    robot: Robot,
    Q: FloatArray,
    poses: FloatArray,
    task: Task,
    bounds: tuple[FloatArray, FloatArray] | None,
) -> Verdict:
    """:func:`optik.verify.verify` of the rows, a row off the query's box no success.

    The box of frozen joints and a ``limit_margin`` (``bounds``), as
    :func:`optik.ik_result.verified_result` checks one answer.
    """
    verdict = verify(robot, Q, poses, task)
    if bounds is None:
        return verdict
    with np.errstate(invalid="ignore"):  # NaN rows (not solved) are no success anyway
        inside = limit_violation(Q, *bounds) <= LIMIT_TOLERANCE
    return verdict._replace(success=verdict.success & inside)


def _bad(array: np.ndarray) -> FloatArray:
    raise ShapeError("targets", "(N, 4, 4) (or (N, 3) in position mode)", array.shape)


@surfaces_interrupts
def solve_ik_batch(
    robot: Robot,
    targets: Any,
    *,
    mode: str = "pose",
    axis: str = "z",
    weights: Any = None,
    q0: Any = None,
    tol: float | tuple[float, float] = 1e-6,
    max_iter: int | None = None,
    restarts: int = DEFAULT_RESTARTS,
    seed: int = 0,
    threads: int | None = None,
    frozen: Mapping[str, float] | None = None,
    limit_margin: float = 0.0,
    proofs: bool = True,
) -> IKBatchResult:
    """Solve many targets: the closed form where there is one, else the compiled search.

    With a closed form that answers the task (a pose or a point, graded weights too, as
    in :func:`solve_ik`) and runs compiled (:func:`optik.analytic.compiled_batch`), each
    target's branch nearest its ``q0`` (the middle of the limits without one) inside the
    box is its answer, ``iterations`` 0: the row :func:`solve_ik` gives. The other targets
    run the compiled damped least squares in parallel threads, from ``q0`` when given,
    then the seed table's entries nearest it and seeded uniform draws
    (:mod:`optik.solvers._starts`; target ``k`` uses the stream ``seed + k``, so results
    do not depend on the thread count or the slicing); a branch that misses a ``tol``
    tighter than the closed form's own starts its target's search. A closed form run in
    Python (the small textbook families, position mode) answers the targets that search
    missed; in ``mode="axis"``, a compiled full-pose closed form over a grid of rolls
    about the tool axis (:func:`optik.analytic.roll.grid_branches`' grid) does. Targets
    outside the robot's reach sphere are not solved: their status is ``"unreachable"``.
    Where a closed form that proves (with the plain limits: no ``frozen``, no
    ``limit_margin``) has no branch inside the limits and the search missed too, a
    cross-check search runs from its branches clipped into the limits, as in
    :func:`solve_ik`; failing that the target is ``"unreachable"`` (no branch at all) or
    ``"outside_limits"`` (branches only beyond the limits), the statuses :func:`solve_ik`
    gives it. ``"max_iter"`` proves nothing: not found.

    Args:
        robot: the robot.
        targets: (N, 4, 4) world poses (in position mode only translations count; an
            (N, 3) array of positions is accepted too); N may be 0.
        mode: ``"pose"``, ``"position"``, ``"orientation"`` or ``"axis"``, as in
            :func:`solve_ik`.
        axis: the tool axis of ``mode="axis"``.
        weights: (6,) task weights in the target frame (:func:`solve_ik`).
        q0: initial guess: (dof,) shared by every target, or (N, dof), one per target;
            each inside the limits (within :data:`~optik.limits.Q_CLIP_TOLERANCE`,
            clipped onto them).
        tol: one tolerance, or ``(position_tol_m, orientation_tol_rad)``.
        max_iter: iterations per attempt, 1 to :data:`MAX_ITERATIONS` (default: the
            damped least squares' own, 100, as in :func:`solve_ik`).
        restarts: attempts after the first, 0 to :data:`MAX_BATCH_RESTARTS`.
        seed: base seed of the restarts.
        threads: worker threads (default: numba's current thread count,
            ``numba.get_num_threads()``); 1 solves on the calling thread. Batches smaller
            than :data:`PARALLEL_BATCH` always do.
        frozen: ``{joint name: value}`` (rad or m): joints held at these values in every
            target, as in :func:`solve_ik`.
        limit_margin: distance (rad or m) kept free inside every finite limit (hard), as
            in :func:`solve_ik`.
        proofs: run the closed form's proofs of the targets the search missed inside the
            reach sphere (default). ``False`` leaves them ``"max_iter"``, without the
            cross-check search and the closed form's polish of a degenerate pose that
            each costs (about 1 ms a target): for a caller that counts only successes,
            such as a capability map.
    """
    start_time = now()
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    check_options("q0", None, restarts, max_iter, seed)
    check_int("restarts", restarts, minimum=0, maximum=MAX_BATCH_RESTARTS)
    proofs = check_bool("proofs", proofs)
    task = make_task(mode, axis=axis, weights=weights, tol=tol)
    mode = "position" if task.mode == "position" else "pose"  # the targets' form
    if seed > MAX_SEED - 2**40:  # target k uses seed + k, and k may reach 2**40
        raise OptikError(
            f"seed must be at most 2**63 - 1 - 2**40 ({MAX_SEED - 2**40}) in a batch, got {seed!r}"
        )
    threads = _check_threads(threads)
    poses = _batch_poses(targets, mode, task.needs_target_frame)
    bounds = query_bounds(robot, frozen, limit_margin)
    N = poses.shape[0]
    Q = np.full((N, robot.dof), math.nan)
    iterations = np.zeros(N, dtype=np.int64)
    used = np.zeros(N, dtype=np.int64)
    # Beyond the reach sphere: a freed position axis leaves a line (or plane) to miss it.
    reachable = ~beyond_reach_task(robot, poses, task)
    every_frozen = bounds is not None and bool(np.all(bounds[0] == bounds[1]))
    if bounds is not None and every_frozen:
        # One configuration in the box: judged, not searched ("unreachable" where it
        # misses: a proof), as solve_ik does.
        Q[:] = bounds[0]
        reachable[:] = False
    rows = np.flatnonzero(reachable)
    table = seed_table(robot)
    given = _given_starts(robot, q0, N, bounds)
    chain = robot.chain.kernel_args(bounds)
    iterations_each = DLSSolver.default_max_iter if max_iter is None else int(max_iter)
    settings = (iterations_each, DLSSolver.w_bias, int(restarts))
    # Searched with the task's search twin (optik.task), the same success: graded weights
    # at 1, the units balanced for the arm's size.
    search = balanced_search(task, search_length(robot))

    def run(
        targets_rows: np.ndarray, starts: FloatArray, budget: tuple[int, float, int] = settings
    ) -> None:
        """The search of ``targets_rows``; ``starts`` (1 or rows, G, dof) their given starts.

        ``budget``: ``(iterations per attempt, bias weight, restarts)``. A row searched
        again (the cross-check of a proof) adds its iterations and attempts.
        """
        again = iterations[targets_rows] > 0
        for lo in range(0, len(targets_rows), BATCH_SLICE):
            part = targets_rows[lo : lo + BATCH_SLICE]
            workers = threads if len(part) >= PARALLEL_BATCH else 1
            # Target k keeps the stream seed + k whatever slice or thread it falls in.
            targets_part = np.ascontiguousarray(poses[part])
            seeds = part.astype(np.int64) + int(seed)
            own = starts[lo : lo + BATCH_SLICE] if starts.shape[0] > 1 else starts
            job = (targets_part, search.packed, own, table.kernel_args(), budget, seeds)
            Qp, it, u, _ = solve_batch(chain, job, workers)
            Q[part] = Qp
            iterations[part] += it
            used[part] += u + again[lo : lo + BATCH_SLICE]  # its first attempt counts too

    own = given[rows] if given.shape[0] == N else given  # per row, or shared
    family = None if every_frozen else _batch_family(robot, task)
    # Rows whose closed form has no branch inside the limits: with the plain limits (a
    # narrowed box proves nothing) they are proved unreachable or outside the limits
    # where the search missed them too, as solve_ik proves them.
    provable = proofs and family is not None and bounds is None and family.proves_unreachable
    no_branch = np.zeros(N, dtype=bool)
    roll_family = None if every_frozen or family is not None else _roll_family(robot, task)
    if family is not None and compiled_batch(robot, task.mode):
        # As solve_ik: the branch nearest q0 answers; the search runs where there is none,
        # and from the branch first where it misses a tol tighter than the closed form's.
        refs = _row_starts(robot, given, rows, bounds)
        branch = _branches(robot, family, task.mode, poses[rows], refs, bounds, threads)
        has = np.all(np.isfinite(branch), axis=1)
        Q[rows[has]] = branch[has]
        no_branch[rows[~has]] = True
        exact = np.zeros(len(rows), dtype=bool)
        exact[has] = verify(robot, branch[has], poses[rows[has]], task).success
        run(rows[~has], own[~has] if own.shape[0] > 1 else own)
        polish = has & ~exact
        if np.any(polish):
            others = own[polish] if own.shape[0] > 1 else np.repeat(own, polish.sum(), 0)
            polished = rows[polish]
            run(polished, np.ascontiguousarray(np.concatenate([branch[polish, None], others], 1)))
            # A search that fails too leaves the branch, as solve_ik does: the nearest q0.
            missed = ~verify(robot, Q[polished], poses[polished], task).success
            Q[polished[missed]] = branch[polish][missed]
    else:
        run(rows, own)
        if family is not None:  # a closed form run in Python: for the rows the search missed
            missed = np.flatnonzero(~verify(robot, Q[rows], poses[rows], task).success)
            refs = _row_starts(robot, given, rows[missed], bounds)
            branch = _branches(robot, family, task.mode, poses[rows[missed]], refs, bounds)
            has = np.flatnonzero(np.all(np.isfinite(branch), axis=1))
            exact = verify(robot, branch[has], poses[rows[missed[has]]], task).success
            Q[rows[missed[has[exact]]]] = branch[has[exact]]
            no_branch[rows[missed]] = True
            no_branch[rows[missed[has]]] = False
        elif roll_family is not None:
            # The axis task: the closed form over a grid of rolls, as solve_ik answers it,
            # for the targets the search missed (a narrow stretch of roll defeats restarts).
            missed = rows[~verify(robot, Q[rows], poses[rows], task).success]
            refs = _row_starts(robot, given, missed, bounds)
            branch = _roll_grid_rows(
                robot, roll_family, poses[missed], task.axis, refs, bounds, threads
            )
            has = np.flatnonzero(np.all(np.isfinite(branch), axis=1))
            exact = verify(robot, branch[has], poses[missed[has]], task).success
            Q[missed[has[exact]]] = branch[has[exact]]
    outside = np.zeros(N, dtype=bool)
    proved = np.zeros(N, dtype=bool)
    missed = np.flatnonzero(no_branch & reachable) if provable else np.zeros(0, dtype=np.int64)
    missed = missed[~verify(robot, Q[missed], poses[missed], task).success]
    # A slice of rows at a time: their branches (up to 8 a row) stay a slice's worth.
    for lo in range(0, missed.size, BATCH_SLICE):
        part = missed[lo : lo + BATCH_SLICE]
        # solve_ik's cross-check: a short search from the branches clipped into the limits
        # (from q0 where there is none), one group per branch count.
        refs = _row_starts(robot, given, part, bounds)
        branches, counts = _unlimited_branches(
            robot, cast(AnalyticFamily, family), task.mode, poses[part], refs
        )
        clipped = np.clip(branches, robot.lower, robot.upper)
        cross_check = (DLSSolver.default_max_iter, DLSSolver.w_bias, CROSS_CHECK_RESTARTS)
        for count in np.unique(counts).tolist():
            group = counts == count
            starts = clipped[group, :count] if count else refs[group, None]
            run(part[group], np.ascontiguousarray(starts), cross_check)
        found = verify(robot, Q[part], poses[part], task).success
        # An answer within tol may lie by the task's minimum: no proof there (solve_ik's
        # rule); the minimum is the row's best attempt, a success where it meets tol.
        for i in np.flatnonzero(~found).tolist():
            k = int(part[i])
            query = IKQuery(robot, poses[k], task.mode, task.position_tol, task, bounds)
            near, q_min, used_iterations = within_reach_of_tolerance(query, Q[k])
            iterations[k] += used_iterations
            if near:
                Q[k] = q_min
                found[i] = True  # no proof
        beyond = ~found & (counts > 0)
        outside[part[beyond]] = True
        proved[part[~found]] = True
        if not task.is_graded:  # the branch nearest q0, beyond the limits (solve_ik's q)
            Q[part[beyond]] = branches[beyond, 0]
    verdict = _verdict(robot, Q, poses, task, bounds)
    if task.is_graded:
        # Beyond the reach sphere too (no search ran): from the row's q0, as solve_ik. A
        # plain task searched in the arm's units (a balanced twin) has no compromise: its
        # best attempt is the answer, as in solve_ik.
        far = np.flatnonzero(~reachable)
        Q[far] = _row_starts(robot, given, far, bounds)
        failed = np.flatnonzero(~verdict.success)
        _compromise(robot, (task, poses, bounds), Q, iterations, failed)
        verdict = _verdict(robot, Q, poses, task, bounds)
    status = np.where(verdict.success, "converged", np.where(reachable, "max_iter", "unreachable"))
    status = status.astype(object)  # a fixed-width string array would cut "outside_limits"
    status[proved & ~verdict.success] = "unreachable"
    status[outside & ~verdict.success] = "outside_limits"
    return IKBatchResult(
        Q,
        verdict.success,
        status,
        verdict.position_error,
        verdict.orientation_error,
        verdict.limit_violation,
        iterations,
        used,
        now() - start_time,
    )
