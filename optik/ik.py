"""The IK API: :func:`solve_ik`, :func:`solve_ik_all` and :class:`IKResult`.

:func:`solve_ik_batch` and :class:`IKBatchResult` live in :mod:`optik.ik_batch`, and
:class:`IKResult` and its statuses in :mod:`optik.ik_result`; both are importable from
here too.

Warm-start policy: when the robot has a closed-form family that solves the mode, its
branches inside the limits (nearest ``q0`` first) are the starting points; with
``solver="auto"`` the nearest branch *is* the answer (it is exact, verified by FK). An
empty set of branches is a proof: the result says ``"unreachable"``, or
``"outside_limits"`` when branches exist only outside the limits (a family that is not
``fast``, ``general_6r``, is left to :func:`solve_ik_all`: the numeric solvers answer in
a twentieth of its time, and its empty set proves nothing). In ``mode="axis"`` a
family that solves full poses solves the free roll (:mod:`optik.analytic.roll`): the
answers are the local minima of the distance to ``q0`` along each branch's continuation
over a grid of rolls, refined, nearest first; there an empty grid proves nothing, and
the numeric search runs instead (from the grid's branches clipped into the limits).
A seven-joint arm with one joint frozen, whose other six have a closed form around it
(:func:`optik.analytic.free_joint_reason`), is treated as a family: its branches with that
joint held are the answers, and none is a proof (inside the plain limits only: with a
``limit_margin`` they start the search). Without a family,
the solver starts from ``q0`` when given, then from the entries of a seeded table of
configurations whose poses are nearest the target (:mod:`optik.solvers._seeds`), then from
deterministic seeded draws uniform inside the limits, until ``restarts`` or
``timeout_s`` runs out.

``success`` is always computed here, from forward kinematics and the limits, never
copied from a backend.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from optik._checks import (
    FloatArray,
    check_choice,
    check_int,
    check_real,
)
from optik._ik_options import (
    CROSS_CHECK_RESTARTS,
    DEFAULT_RESTARTS,
    FROZEN_RESTARTS,
    MAX_ITERATIONS,
    MAX_SEED,
    UNLIMITED_RESTARTS,
    TaskKeywords,
    check_options,
    check_q0,
    query_bounds,
)
from optik._interrupts import surfaces_interrupts
from optik.analytic import (
    analytic_ik,
    family_of,
    family_solves,
    free_joint_reason,
    wrap_into_limits,
)
from optik.analytic.roll import axis_branches, grid_branches, solves_axis_task
from optik.errors import OptikError

# The batch path lives in its own module; its names stay importable from here.
from optik.ik_batch import (
    BATCH_SLICE,
    BATCH_STATUSES,
    MAX_BATCH_RESTARTS,
    PARALLEL_BATCH,
    IKBatchResult,
    solve_ik_batch,
)
from optik.ik_proofs import (
    AUTO_NUMERIC_SOLVER,
    closed_form_proof,
    every_joint_frozen,
    reach_proof,
)
from optik.ik_result import STATUSES, IKResult, from_run, verified_result, without_run
from optik.limits import FROZEN_MATCH_TOLERANCE as FROZEN_MATCH_TOLERANCE  # its old home
from optik.limits import into_box
from optik.model import Robot
from optik.poses import PositionOnlyTargetError, as_target_pose
from optik.posture import check_posture, nearest_turns, posture_answers, refine_posture
from optik.solvers import get_solver
from optik.solvers._base import (
    IKQuery,
    IKSolver,
    RunOutput,
    budget_now,
    now,
)
from optik.solvers._seeds import start_sequence
from optik.solvers._starts import StartSequence
from optik.task import Task, make_task
from optik.verify import verify_one

if TYPE_CHECKING:
    from typing_extensions import Unpack  # Python 3.10 has no typing.Unpack


def _answer(
    plan: _Plan, q: FloatArray, solver: str, iterations: int = 0, restarts: int = 0
) -> IKResult:
    """A found answer (a closed-form branch, or a run's verified ``q``), verified again."""
    outcome = without_run(q, "max_iter", "", iterations, restarts)
    claim = None if solver == "analytic" else True
    return verified_result(plan.query, plan.start_time, solver, outcome, claim)


ROLL_STARTS = 8
"""Grid branches outside the limits (clipped into them) that start the numeric search
when the roll's closed form finds no answer inside them."""


@surfaces_interrupts
def solve_ik(
    robot: Robot,
    target: Any,
    *,
    mode: str = "pose",
    axis: str = "z",
    weights: Any = None,
    solver: str = "auto",
    q0: Any = None,
    warm_start: str = "analytic",
    tol: float | tuple[float, float] = 1e-6,
    max_iter: int | None = None,
    timeout_s: float | None = None,
    restarts: int | None = None,
    seed: int = 0,
    frozen: Mapping[str, float] | None = None,
    limit_margin: float = 0.0,
    select: str = "first",
    posture: Any = None,
    joint_weights: Any = None,
) -> IKResult:
    """Solve IK for one target, with hard joint limits.

    Args:
        robot: the robot.
        target: world pose of the tool (``mode="pose"``): a 4x4, a ``(p, R)`` pair or a
            mapping of :func:`optik.pose`'s keywords (e.g. ``{"position": p,
            "quat_wxyz": q}``); in position mode also a 3-vector (metres). See
            :func:`optik.as_target_pose`. ``"orientation"`` and ``"axis"`` take a pose too.
        mode: ``"pose"``, ``"position"``, ``"orientation"`` or ``"axis"`` (the tool axis
            ``axis`` points along the target's same axis; the rotation about it is free):
            see :mod:`optik.task`.
        axis: ``"x"``, ``"y"`` or ``"z"``, the tool axis of ``mode="axis"``.
        weights: (6,) >= 0 on ``[x, y, z, rx, ry, rz]`` in the target frame (0 frees that
            axis); the modes are shortcuts for weights (:func:`optik.task.make_task`).
        solver: a name from :func:`optik.available_solvers`, or ``"auto"`` (the closed
            form when the robot has one, else :data:`AUTO_NUMERIC_SOLVER`).
        q0: initial guess (dof,) inside the limits; within
            :data:`~optik.limits.Q_CLIP_TOLERANCE` outside them it is clipped onto them,
            beyond it raises :class:`~optik.errors.JointLimitError`. Default:
            none: numeric solvers start from the seed table's nearest entry, and
            closed-form branches are ordered by their distance to mid-limits.
        warm_start: ``"analytic"`` (closed-form branches as starting points when a family
            exists) or ``"q0"`` (ignore the closed form).
        tol: tolerance of success for both errors, or ``(position_tol_m,
            orientation_tol_rad)``; the errors judged are the task's (:mod:`optik.task`).
        max_iter: iterations per attempt, 1 to :data:`MAX_ITERATIONS` (default: the
            solver's own).
        timeout_s: wall-time budget (s) for all attempts; ``inf`` means no time limit
            (the restart budget then stays :data:`DEFAULT_RESTARTS`). One-time work is
            not counted (:mod:`optik._clock`): compiling numba kernels (a first call in a
            fresh environment), a robot's seed table, and a ``casadi:*`` solver's C code,
            compiled once per robot and task shape and cached on disk (seconds for an
            arm, about 15-60 s for a chain of 60 joints); ``IKResult.time_s`` is the wall
            time, all of it included.
        restarts: attempts after the first (default: :data:`DEFAULT_RESTARTS`, or
            :data:`~optik._ik_options.FROZEN_RESTARTS` with frozen joints, without a
            finite timeout, unlimited within one).
        seed: seed of the restart sequence, 0 to 2**63 - 1 (results are deterministic
            for a seed, and the same with and without ``timeout_s`` until it cuts the run
            short: :mod:`optik.solvers._starts`).
        frozen: ``{joint name: value}`` (rad or m): joints held at these values, which
            must lie inside their limits.
        limit_margin: distance (rad or m) kept free inside every finite limit (hard; not
            more than half a joint's range). Frozen joints are exempt.
        select: ``"first"`` (the first verified answer) or ``"nearest"`` (the verified
            answer nearest ``q0`` among all found within ``restarts`` / ``timeout_s``;
            with a closed form, the branch nearest ``q0``; in ``mode="axis"`` the nearest
            over the roll's grid, refined, see :mod:`optik.analytic.roll`). A numeric
            ``"nearest"`` spends its whole budget: with ``timeout_s``, all of it.
        posture: ``q_ref`` (dof,): an answer nearest it in the ``joint_weights`` norm:
            the answer from a start at ``q_ref``, then up to one more of the ordinary
            starts (a closed form's branches turned and ordered nearest ``q_ref`` first;
            more only while none is found), each refined by
            :func:`optik.posture.refine_posture` (a local optimum of
            ``min ||q - q_ref||_W s.t. the task``, compiled), the nearest kept; with a
            closed form, every branch is refined (in ``mode="axis"``, the roll's refined
            answers nearest ``q_ref``, see :mod:`optik.analytic.roll`).
        joint_weights: (dof,) in [1e-100, 1e100], the norm of ``posture`` (default ones).

    Returns:
        An :class:`IKResult`; a well-formed query that cannot be solved gives
        ``success=False`` and a status, never an exception.

    Raises:
        OptikError: malformed target, ``q0``, options, or an unknown solver name.
    """
    plan = _plan(
        robot, target, solver=solver, q0=q0, warm_start=warm_start, max_iter=max_iter,
        timeout_s=timeout_s, restarts=restarts, seed=seed, frozen=frozen,
        limit_margin=limit_margin, posture=posture, joint_weights=joint_weights, mode=mode,
        axis=axis, weights=weights, tol=tol,
    )  # fmt: skip
    check_choice("select", select, ("first", "nearest"))
    if plan.early is not None:
        return plan.early
    if plan.posture is not None and plan.joint_weights is not None:
        return _posture_answer(plan, plan.posture, plan.joint_weights)
    if plan.branches and plan.numeric is None:
        answer = _answer(plan, plan.branches[0], "analytic")
        return answer if answer.success else _polished_branches(plan, answer)
    numeric = plan.numeric or get_solver(AUTO_NUMERIC_SOLVER)
    if select == "first":
        run = numeric.run(plan.query, plan.starts, plan.max_iter, plan.last, plan.deadline)
        return from_run(plan.query, plan.start_time, numeric.name, run)
    found, last_run, searched = _collect(plan, numeric, want=None, min_separation=0.0)
    if not found:
        return from_run(plan.query, plan.start_time, numeric.name, last_run)
    nearest = min(found, key=lambda f: float(np.linalg.norm(f[0] - plan.q_start)))
    # The whole search's iterations and attempts, not those of the run that ended it.
    return _answer(plan, nearest[0], numeric.name, *searched)


def _polished_branches(plan: _Plan, answer: IKResult) -> IKResult:
    """The closed form's branches polished numerically, when its first misses ``tol``.

    A branch is verified to the closed form's own tolerance (1e-9, relative on large
    arms); a tighter ``tol``, or a tiny arm whose closed form rounds coarser, asks for
    more: ``dls`` from the branches (nearest ``q0`` first). Its verified answer, else
    ``answer`` with the polish's status and counts, and a message that says so.
    """
    numeric = get_solver(AUTO_NUMERIC_SOLVER)
    last = len(plan.branches) - 1
    run = numeric.run(plan.query, plan.starts, plan.max_iter, last, plan.deadline)
    polished = from_run(plan.query, plan.start_time, numeric.name, run)
    if polished.success:
        return polished
    task = plan.query.spec
    message = (
        f"the closed-form branch reaches the target to {answer.position_error:.3g} m, "
        f"{answer.orientation_error:.3g} rad, outside tol ({task.position_tol:.3g} m, "
        f"{task.orientation_tol:.3g} rad); a {numeric.name} polish from every branch "
        f"found no answer within it ({polished.status})"
    )
    return replace(
        answer,
        status=polished.status,
        message=message,
        iterations=polished.iterations,
        restarts=polished.restarts,
        time_s=polished.time_s,
    )


def _posture_answer(plan: _Plan, q_ref: FloatArray, weights: FloatArray) -> IKResult:
    """The answer of :func:`solve_ik` with a checked ``posture`` and its norm's weights."""

    def cost(q: FloatArray) -> float:
        d = q - q_ref
        return float(d @ (weights * d))

    if plan.branches and plan.numeric is None:
        found = [(q, 0, 0) for q in nearest_turns(plan.query, np.array(plan.branches), q_ref)]
        solver_name = "analytic"
        last_run = None
    else:
        numeric = plan.numeric or get_solver(AUTO_NUMERIC_SOLVER)
        # The given starts (closed-form branches, wrapped nearest q0) turned nearest the
        # posture and nearest first: where the start at the posture fails, the next
        # answer comes from the start nearest it (a turn does not move the tool).
        starts = np.array(plan.given).reshape(-1, plan.query.robot.dof)
        given = sorted(nearest_turns(plan.query, starts, q_ref), key=cost)
        found, last_run = posture_answers(
            plan.query, numeric, given, q_ref, weights, plan.seed, plan.max_iter,
            plan.last, plan.deadline,
        )  # fmt: skip
        solver_name = numeric.name
    if not found:
        if last_run is None:  # pragma: no cover - a closed form always has branches here
            raise OptikError("posture: no answer and no run to report")
        return from_run(plan.query, plan.start_time, solver_name, last_run)

    if solver_name == "analytic":
        refined = [refine_posture(plan.query, q, q_ref, weights) for q, _, _ in found]
    else:  # refined already, nearest first
        refined = [q for q, _, _ in found]
    best = min(refined, key=cost)
    iterations = last_run.iterations if last_run is not None else 0
    restarts = found[-1][2]
    return _answer(plan, best, solver_name, iterations, restarts)


@surfaces_interrupts
def solve_ik_all(
    robot: Robot,
    target: Any,
    *,
    k: int = 8,
    min_separation: float = 0.1,
    mode: str = "pose",
    axis: str = "z",
    weights: Any = None,
    solver: str = "auto",
    q0: Any = None,
    warm_start: str = "analytic",
    tol: float | tuple[float, float] = 1e-6,
    max_iter: int | None = None,
    timeout_s: float | None = None,
    restarts: int | None = None,
    seed: int = 0,
    frozen: Mapping[str, float] | None = None,
    limit_margin: float = 0.0,
) -> list[IKResult]:
    """Up to ``k`` distinct verified IK answers for one target, nearest ``q0`` first.

    The order is among the answers found: where they form a continuum (a redundant arm,
    a free roll) they sample it, and ``solve_ik(..., select="nearest")`` or ``posture``
    may find one nearer still.

    With a closed form (``solver="auto"`` and a family that solves the task) these are the
    in-limit branches; in ``mode="axis"`` the answers over the free roll
    (:mod:`optik.analytic.roll`): the refined nearest answer of every branch's
    continuation first, then the grid's branches, each kept when at least
    ``min_separation`` from those kept before. Otherwise the numeric solver's restarts
    are collected until ``k``
    answers pairwise at least ``min_separation`` apart (Euclidean, rad / m) are found or
    ``restarts`` / ``timeout_s`` runs out. Each is verified like :func:`solve_ik`'s.

    Args:
        robot: the robot.
        target: as in :func:`solve_ik`.
        k: most answers to return (>= 1).
        min_separation: smallest distance between two answers (rad / m, >= 0).
        mode: see :func:`solve_ik`; so are ``axis`` to ``limit_margin``.
        axis: see :func:`solve_ik`.
        weights: see :func:`solve_ik`.
        solver: see :func:`solve_ik`.
        q0: see :func:`solve_ik`; answers are sorted by their distance to it.
        warm_start: see :func:`solve_ik`.
        tol: see :func:`solve_ik`.
        max_iter: see :func:`solve_ik`.
        timeout_s: see :func:`solve_ik`.
        restarts: see :func:`solve_ik`.
        seed: see :func:`solve_ik`.
        frozen: see :func:`solve_ik`.
        limit_margin: see :func:`solve_ik`.

    Returns:
        A list of successful :class:`IKResult` (possibly empty: use :func:`solve_ik` for
        the status of a target without an answer).
    """
    count = check_int("k", k, minimum=1, maximum=10**6)
    separation = check_real("min_separation", min_separation, nonnegative=True)
    plan = _plan(
        robot, target, solver=solver, q0=q0, warm_start=warm_start, max_iter=max_iter,
        timeout_s=timeout_s, restarts=restarts, seed=seed, frozen=frozen,
        limit_margin=limit_margin, slow_families=True, mode=mode, axis=axis,
        weights=weights, tol=tol,
    )  # fmt: skip
    if plan.early is not None:
        return [plan.early] if plan.early.success else []
    if plan.branches and plan.numeric is None:
        answers = [*plan.branches, *plan.samples]
        found = _distinct([(q, 0, 0) for q in answers], separation, most=count)
        solver_name = "analytic"
    else:
        numeric = plan.numeric or get_solver(AUTO_NUMERIC_SOLVER)
        found, _, _ = _collect(plan, numeric, want=count, min_separation=separation, turns=True)
        solver_name = numeric.name
    found.sort(key=lambda f: float(np.linalg.norm(f[0] - plan.q_start)))
    results = [_answer(plan, q, solver_name, its, used) for q, its, used in found[:count]]
    return [r for r in results if r.success]


@dataclass
class _Plan:
    """A validated query and what the solvers need to run it."""

    query: IKQuery
    q_start: FloatArray
    numeric: IKSolver | None
    branches: list[FloatArray]
    given: list[FloatArray]
    seed: int
    max_iter: int
    last: int
    deadline: float
    start_time: float
    early: IKResult | None
    samples: list[FloatArray]
    """More closed-form answers after ``branches`` (the roll's grid in ``axis`` mode)."""
    posture: FloatArray | None = None
    """The checked ``posture`` (dof,), rad / m, or ``None``."""
    joint_weights: FloatArray | None = None
    """Its norm's weights (dof,), with a ``posture``."""

    @property
    def starts(self) -> StartSequence:
        """The query's start sequence, built when a solver first needs it."""
        sequence = self.__dict__.get("_starts")
        if sequence is None:
            query = self.query
            sequence = start_sequence(
                query.robot, query.target, query.spec, self.given, self.seed, query.bounds
            )
            self.__dict__["_starts"] = sequence
        return sequence


def _plan(
    robot: Any,
    target: Any,
    *,
    solver: Any = "auto",
    q0: Any = None,
    warm_start: Any = "analytic",
    max_iter: Any = None,
    timeout_s: Any = None,
    restarts: Any = None,
    seed: Any = 0,
    frozen: Any = None,
    limit_margin: Any = 0.0,
    posture: Any = None,
    joint_weights: Any = None,
    slow_families: bool = False,
    **task_keywords: Unpack[TaskKeywords],
) -> _Plan:
    """Validate a query, run the closed form and the proofs; the rest is for a solver.

    The keywords' defaults are those :func:`solve_ik` documents (the task's are
    :func:`optik.task.make_task`'s). ``slow_families``: use a family that is not
    ``fast`` too (``general_6r``), as :func:`solve_ik_all` does. With a ``posture``, the
    free roll's closed form (``mode="axis"``) is refined nearest it rather than ``q0``.
    """
    start_time = now()
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    check_options(warm_start, timeout_s, restarts, max_iter, seed)
    task = make_task(**task_keywords)
    if not isinstance(solver, str):
        raise OptikError(f"solver must be a solver name (str), got {solver!r}")
    T_target = _task_target(target, task)
    flags = T_target.flags
    if not (flags.c_contiguous and flags.writeable):
        # The compiled solvers are specialised on layout and writability: a Fortran-ordered
        # or read-only pose would compile them anew (seconds), a C-ordered copy does not.
        T_target = np.array(T_target, dtype=np.float64, order="C")
    q_start = check_q0(robot, q0)
    bounds = query_bounds(robot, frozen, limit_margin)
    q_ref, norm = check_posture(posture, joint_weights, robot.dof)
    numeric: IKSolver | None = None if solver == "auto" else get_solver(solver)
    plain = task.is_pose_or_position and bounds is None
    if numeric is not None and numeric.plain_tasks_only and not plain:
        raise OptikError(
            f"solver {solver!r} takes a full pose or a point with unit weights inside "
            f"the plain limits; for mode {task.mode!r} with weights "
            f"{task.weights.tolist()}, frozen joints or a limit margin use 'dls', "
            "'pinv' or 'transpose'"
        )
    query = IKQuery(robot, T_target, task.mode, task.position_tol, task, bounds)
    if bounds is not None:
        q_start = np.clip(q_start, bounds[0], bounds[1])
    # timeout_s=inf is "no time limit": the restart budget then stays finite.
    # On the budget clock: compiling a kernel on a first call is not the caller's time.
    deadline = budget_now() + float(timeout_s) if timeout_s is not None else math.inf
    iterations = int(max_iter) if max_iter is not None else 0
    if restarts is not None:
        last = int(restarts)
    else:
        frozen_any = bounds is not None and bool(np.any(bounds[0] == bounds[1]))
        default = FROZEN_RESTARTS if frozen_any else DEFAULT_RESTARTS
        last = UNLIMITED_RESTARTS if math.isfinite(deadline) else default

    def plan(
        starts_given: list[FloatArray],
        branches: list[FloatArray],
        early: IKResult | None = None,
        samples: list[FloatArray] | None = None,
    ) -> _Plan:
        solver_for_run = numeric or get_solver(AUTO_NUMERIC_SOLVER)
        per_attempt = iterations or solver_for_run.default_max_iter
        return _Plan(
            query, q_start, numeric, branches, starts_given, int(seed), per_attempt, last,
            deadline, start_time, early, samples or [], q_ref, norm,
        )  # fmt: skip

    if bounds is not None and bool(np.all(bounds[0] == bounds[1])):
        return plan([], [], every_joint_frozen(query, start_time))

    def closed_form(mode: str, provable: bool, held: tuple[str, float] | None = None) -> _Plan:
        """The closed form's branches inside the box (nearest ``q0`` first) as the answers.

        Without one: a proof when ``provable`` (:func:`closed_form_proof`), else the
        numeric search from the branches (those outside the limits too) clipped into the
        box. ``held``: the frozen joint of a seven-joint arm's form (:func:`_held_joint`).
        """
        name, value = (None, None) if held is None else held
        found = analytic_ik(robot, T_target, mode, q_ref=q_start, free_joint=name, free_value=value)
        branches = found if bounds is None else _into_box(robot, found, bounds, q_start)
        if branches:
            return plan(branches, branches)
        if provable:
            proof = closed_form_proof(robot, query, q_start, start_time, int(seed), held)
            return plan([], [], proof)
        # The branch set proves nothing about a narrowed box; the reach sphere still does.
        far = reach_proof(query, q_start, start_time)
        if far is not None:
            return plan([], [], far)
        lower, upper = bounds if bounds is not None else (robot.lower, robot.upper)
        given = found or analytic_ik(
            robot, T_target, mode, q_ref=q_start, within_limits=False,
            free_joint=name, free_value=value,
        ) or [q_start]  # fmt: skip
        return plan([np.clip(b, lower, upper) for b in given], [])

    family = family_of(robot) if warm_start == "analytic" else None
    if family is not None and not family.fast and not slow_families:
        family = None  # general_6r's 2 ms: the numeric solvers answer sooner
    starts_given = [q_start] if q0 is not None else []
    if family is not None and solves_axis_task(family, task):
        box = bounds if bounds is not None else (robot.lower, robot.upper)
        if numeric is None:  # the answers themselves: the roll refined nearest q0
            # (or the posture: its answer is refined from these).
            reference = q_start if q_ref is None else q_ref
            roll = axis_branches(robot, T_target, task.axis, reference[None], *box)[0]
        else:  # starts for the named solver, which refines them itself
            roll = grid_branches(robot, T_target, task.axis, q_start, *box)
        if roll.nearest:
            return plan(roll.nearest, roll.nearest, samples=list(roll.samples))
        # A sampled roll proves nothing (an answer can lie between two grid rolls, or
        # inside a narrowed box): search numerically, from the grid's branches too.
        clipped = [np.clip(q, box[0], box[1]) for q in roll.outside[:ROLL_STARTS]]
        starts_given = [*starts_given, *clipped]
    elif family is not None and family_solves(family, robot, task):
        # Frozen joints or a margin narrow the box (the branch set proves nothing about
        # it), and a numerical family (general_6r) proves nothing at all. Graded positive
        # weights have the same exact answers (optik.task): the branches answer them.
        provable = bounds is None and family.proves_unreachable
        return closed_form(task.mode, provable=provable)
    held = _held_joint(robot, bounds) if family is None and warm_start == "analytic" else None
    if held is not None and task.search.is_pose_or_position and task.mode == "pose":
        # Complete for the held value inside the limits; a margin narrows the others.
        return closed_form("pose", provable=float(limit_margin) == 0.0, held=held)
    # No closed form (or a sampled roll that found nothing): the reach sphere still proves.
    far = reach_proof(query, q_start, start_time)
    return plan([], [], far) if far is not None else plan(starts_given, [])


def _task_target(target: Any, task: Task) -> FloatArray:
    """The target as a 4x4 pose, its rotation the identity in position mode.

    Unless the weights need the target's frame (:attr:`Task.needs_target_frame`) and the
    target has a rotation: then it is kept.
    """
    if task.mode != "position":
        return as_target_pose(target, "pose")
    if task.needs_target_frame:
        try:
            return as_target_pose(target, "pose")
        except PositionOnlyTargetError:  # a point: its axes are the world's
            pass
    return as_target_pose(target, "position")


def _held_joint(
    robot: Robot, bounds: tuple[FloatArray, FloatArray] | None
) -> tuple[str, float] | None:
    """The frozen joint ``(name, value)`` whose closed form solves the other six, if any.

    A seven-joint arm (without a family of its own) with exactly one joint frozen, when
    the six others fit the held-joint form (:func:`optik.analytic.free_joint_reason`),
    e.g. the Panda's joint 7.
    """
    if bounds is None or robot.dof != 7:
        return None
    frozen = np.flatnonzero(bounds[0] == bounds[1])
    if len(frozen) != 1:
        return None
    name = robot.joint_names[int(frozen[0])]
    if free_joint_reason(robot, name):
        return None
    return name, float(bounds[0][frozen[0]])


def _into_box(
    robot: Robot,
    branches: list[FloatArray],
    bounds: tuple[FloatArray, FloatArray],
    q_ref: FloatArray,
) -> list[FloatArray]:
    """The closed-form branches inside the box ``bounds``, snapped onto it, nearest ``q_ref``.

    A branch recovers a frozen joint's value only to rounding: it counts as holding it
    within :data:`~optik.limits.FROZEN_MATCH_TOLERANCE` and is then given the value
    exactly; an angle a turn away from the box is turned into it
    (:func:`optik.analytic.wrap_into_limits`), which can change which branch is nearest.
    """
    if not branches:
        return []
    # Into the box nearest q_ref first: a branch wrapped into the limits can sit in a
    # margin's band (or off a frozen value) a turn away from the box.
    turned = wrap_into_limits(np.array(branches), robot, q_ref, bounds)
    inside, clipped = into_box(turned, *bounds)
    kept = clipped[inside]
    order = np.argsort(np.linalg.norm(kept - q_ref, axis=1), kind="stable")
    return list(kept[order])


def _distinct(
    found: list[tuple[FloatArray, int, int]], separation: float, most: int | None = None
) -> list[tuple[FloatArray, int, int]]:
    """The answers at least ``separation`` from every earlier one, in order.

    With ``most``, only the first ``most`` such answers.
    """
    kept: list[tuple[FloatArray, int, int]] = []
    for item in found:
        if most is not None and len(kept) >= most:
            break
        distances = [float(np.linalg.norm(item[0] - other[0])) for other in kept]
        if all(d >= separation and d > 0.0 for d in distances):
            kept.append(item)
    return kept


def _collect(
    plan: _Plan,
    numeric: IKSolver,
    want: int | None,
    min_separation: float,
    turns: bool = False,
) -> tuple[list[tuple[FloatArray, int, int]], RunOutput, tuple[int, int]]:
    """Verified answers from successive runs over the start sequence (see the callers).

    With ``turns``, each answer is first shifted by whole turns of its revolute joints to
    the representative nearest the start inside the query's box (as a closed form
    reports one representative per branch), so that answers a turn apart are one: a
    Laikago leg's three continuous joints gave 8 answers that were one configuration.
    Not for coupled joints, where a turn of one moves another by its multiplier.

    Returns the distinct answers ``(q, iterations so far, restarts so far)``, the last
    run's output, and the whole search's ``(iterations, restarts)``.
    """
    found: list[tuple[FloatArray, int, int]] = []
    first = 0
    iterations = 0
    run: RunOutput | None = None
    while first <= plan.last:
        run = numeric.run(
            plan.query, plan.starts, plan.max_iter, plan.last, plan.deadline, start=first
        )
        iterations += run.iterations
        first += run.restarts + 1
        # A run stops at its first verified answer, whatever the backend claims (CasADi's
        # iteration cap on an answer optik verifies): the next run goes on from there.
        if not verify_one(plan.query.robot, run.q, plan.query.target, plan.query.spec)[3]:
            break  # every start left was tried, or the deadline passed
        q = run.q
        if turns and plan.query.robot.chain.identity:
            box = (plan.query.lower, plan.query.upper)
            q = wrap_into_limits(q, plan.query.robot, plan.q_start, bounds=box)
        found = _distinct([*found, (q, iterations, first - 1)], min_separation)
        if want is not None and len(found) >= want:
            break
        if budget_now() > plan.deadline:
            break
    if run is None:  # pragma: no cover - the budget always admits one attempt
        raise OptikError("no IK attempt ran")
    return found, run, (iterations, first - 1)


__all__ = [
    "AUTO_NUMERIC_SOLVER",
    "BATCH_SLICE",
    "BATCH_STATUSES",
    "CROSS_CHECK_RESTARTS",
    "DEFAULT_RESTARTS",
    "MAX_BATCH_RESTARTS",
    "MAX_ITERATIONS",
    "MAX_SEED",
    "PARALLEL_BATCH",
    "STATUSES",
    "UNLIMITED_RESTARTS",
    "IKBatchResult",
    "IKResult",
    "solve_ik",
    "solve_ik_all",
    "solve_ik_batch",
]
