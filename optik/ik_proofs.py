"""The proofs behind :func:`optik.solve_ik`'s ``unreachable`` and ``outside_limits``.

The reach sphere's proof (a target beyond every tool position inside the limits), the
closed form's (no branch, or branches only beyond the limits, cross-checked by a short
search and held against the tolerance), and the judgement of a query whose every joint
is frozen.
"""

from __future__ import annotations

import math

import numpy as np

from optik._checks import FloatArray
from optik._ik_options import CROSS_CHECK_RESTARTS
from optik.analytic import analytic_ik
from optik.ik_result import IKResult, from_run, verified_result, without_run
from optik.model import Robot
from optik.solvers import get_solver
from optik.solvers._base import IKQuery, compromise, within_reach_of_tolerance
from optik.solvers._seeds import start_sequence
from optik.verify import beyond_reach_task, verify_one

AUTO_NUMERIC_SOLVER = "dls"
"""What ``solver="auto"`` uses without a closed form: the fastest solver that meets the
tolerance in ``benchmarks/bench_ik.py`` (compiled damped least squares)."""


def closed_form_proof(
    robot: Robot,
    query: IKQuery,
    q_start: FloatArray,
    start_time: float,
    seed: int,
    held: tuple[str, float] | None = None,
) -> IKResult:
    """The result when the closed form finds no branch inside the limits, cross-checked.

    Before ``unreachable`` or ``outside_limits`` is reported, a short ``dls`` run
    (:data:`CROSS_CHECK_RESTARTS`, from the out-of-limit branches clipped into the query's
    box, then the seed table) looks for an answer the closed form missed at a degenerate
    pose; if it finds a verified one, that answer is returned. A target beyond the reach
    sphere needs neither: the sphere's proof (:func:`reach_proof`) answers (a graded
    task's run still goes, for its compromise). ``held``: the frozen joint
    ``(name, value)`` of a seven-joint arm's closed form (:func:`_held_joint`).
    """
    name, value = (None, None) if held is None else held
    # Beyond the reach sphere first, as solve_ik_batch judges: the sphere holds every
    # tool position inside the limits, so no branch of a slide stretched beyond its
    # stroke (by 1 m, or by a kilometre) makes such a target "outside_limits". A graded
    # task's compromise starts from the run's best answer, so its run still goes (from
    # no branch: one stretched beyond a stroke is no start).
    graded = query.spec.is_graded
    far = None if graded else reach_proof(query, q_start, start_time)
    if far is not None:
        return far
    beyond = beyond_reach_reason(query) if graded else None
    outside = [] if beyond is not None else analytic_ik(
        robot, query.target, query.mode, q_ref=q_start, within_limits=False,
        free_joint=name, free_value=value,
    )  # fmt: skip
    given = [np.clip(q, query.lower, query.upper) for q in outside] or [q_start]
    numeric = get_solver(AUTO_NUMERIC_SOLVER)
    sequence = start_sequence(robot, query.target, query.spec, given, seed)
    run = numeric.run(query, sequence, numeric.default_max_iter, CROSS_CHECK_RESTARTS, math.inf)
    if verify_one(robot, run.q, query.target, query.spec)[3]:
        return from_run(query, start_time, numeric.name, run)
    # The sphere's proof counts tol already; the closed form's proves no exact answer.
    near, q_min, used = (False, run.q, 0) if beyond else within_reach_of_tolerance(query, run.q)
    if near:
        # An answer within tol may lie by the task's minimum: the branch set proves nothing.
        position, orientation, _, _ = verify_one(robot, q_min, query.target, query.spec)
        reason = (
            "closed form: no branch reaches the target exactly, and the task's minimum found "
            f"misses it by {position:.3g} m and {orientation:.3g} rad, close to tol: no proof"
        )
        outcome = without_run(q_min, "max_iter", reason, run.iterations + used, run.restarts)
        return verified_result(query, start_time, numeric.name, outcome, None)
    status = "outside_limits" if outside else "unreachable"
    form = "closed form" if held is None else f"closed form with {held[0]!r} at {held[1]:g}"
    if beyond is not None:
        reason = beyond
    elif outside:
        reason = f"{form}: every branch lies outside the joint limits"
    else:
        reason = f"{form}: no branch reaches the target"
    reason += f" (a {numeric.name} cross-check found no answer either)"
    # Graded weights ask for a compromise where the target cannot be met: the run's.
    q = run.q if graded else (outside[0] if outside else q_start)
    outcome = without_run(q, status, reason, run.iterations, run.restarts)
    solver = "analytic" if beyond is None else "reach"
    return verified_result(query, start_time, solver, outcome, None)


def every_joint_frozen(query: IKQuery, start_time: float) -> IKResult:
    """The result of a query whose every joint is frozen: its one configuration, judged.

    Nothing is left to search (a search ran restart after restart to its budget): the
    frozen configuration meets the target (``converged``) or the target is out of the
    query's reach (``unreachable``, a proof: it is the only configuration in the box).
    """
    q = query.lower.copy()
    reason = "every joint is frozen, and the frozen configuration does not reach the target"
    return verified_result(query, start_time, "frozen", without_run(q, "unreachable", reason), None)


def reach_proof(query: IKQuery, q_start: FloatArray, start_time: float) -> IKResult | None:
    """``"unreachable"`` for a target beyond the reach sphere, else ``None``.

    :attr:`optik.Robot.reach_sphere` holds every tool position inside the robot's limits
    (its prismatic strokes), so the proof needs no closed form and holds for frozen joints
    and margins, which only narrow that box. Over the constrained position axes of the
    target frame (a freed axis leaves a line or plane to miss the sphere,
    :func:`optik.verify.beyond_reach_task`). Graded weights still get their compromise,
    the weighted minimum from ``q_start``.
    """
    reason = beyond_reach_reason(query)
    if reason is None:
        return None
    q_end, used = q_start, 0
    if query.spec.is_graded:
        q_end, used, _ = compromise(query, q_start)
    return verified_result(
        query, start_time, "reach", without_run(q_end, "unreachable", reason, used), None
    )


def beyond_reach_reason(query: IKQuery) -> str | None:
    """Why the target is beyond the reach sphere (distance and radius, m), else ``None``."""
    robot, T_target, task = query.robot, query.target, query.spec
    if not beyond_reach_task(robot, T_target, task):
        return None
    centre, radius = robot.reach_sphere
    free = [axis for axis, w in zip("xyz", task.weights[:3], strict=True) if w == 0.0]
    # Over the constrained axes of the target frame; math.hypot is exact in the range
    # (no overflow: a target 1e155 m away is beyond).
    local = T_target[:3, :3].T @ (T_target[:3, 3] - centre)
    distance = math.hypot(*(v for v, w in zip(local, task.weights[:3], strict=True) if w))
    where = (
        "the target lies"
        if not free
        else f"the target's {'line' if len(free) == 1 else 'plane'} along its free "
        f"{' and '.join(free)} passes"
    )
    return (
        f"{where} {distance:.6g} m from the reach sphere's centre, beyond its radius {radius:.6g} m"
    )
