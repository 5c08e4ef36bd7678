"""Newton polish of closed-form candidates at degenerate poses.

At a singular pose (a wrist or an elbow aligned, a joint left free) a closed form's
tangent and free-angle rules round a candidate by up to the rules' tolerances, which can
exceed the FK check's 1e-9: the branch exists but is not returned. When a family returns
no verified branch, :func:`polish` takes its raw candidates (and the reference) a few
Gauss–Newton steps towards the target, with the pseudoinverse of the task Jacobian
(rank-deficient Jacobians included); the results then go through the family's ordinary
wrapping, limit filter and FK check, so nothing unverified is returned.
"""

from __future__ import annotations

import numpy as np

from optik._checks import MAX_LENGTH_M, FloatArray
from optik.model import Robot
from optik.spatial import rotation_angle
from optik.task import make_task, task_error, task_rows

POLISH_STEPS = 12
"""Gauss–Newton steps per candidate (quadratic convergence from 1e-6 needs two or three;
the rest serve rank-deficient Jacobians, where convergence is linear)."""

MAX_STEP = 0.5
"""Largest step (rad or m): a pseudoinverse step next to a singularity can be huge."""

STALL = 0.5
"""A candidate whose error did not fall below this fraction of its value three steps
before is dropped (a projected search that has stalled on a bound)."""

GIVE_UP = 1e-3
"""A candidate still this far (m or rad) from the target after three steps is dropped:
the polish refines near-solutions, it does not search."""


def near_solution(robot: Robot, target: FloatArray, q: FloatArray) -> bool:
    """Whether ``q`` (dof,) reaches the world pose ``target`` (4x4) within :data:`GIVE_UP`.

    Position (m) and rotation angle (rad) both: a start that :func:`polish` refines
    rather than searches from.
    """
    T = robot.fk(q)
    if not float(np.linalg.norm(T[:3, 3] - target[:3, 3])) <= GIVE_UP:
        return False
    return float(rotation_angle(T[:3, :3].T @ target[:3, :3])) <= GIVE_UP


def polish(
    robot: Robot,
    target: FloatArray,
    mode: str,
    starts: list[FloatArray],
    tol: float,
    held: int | None = None,
    bounds: tuple[FloatArray, FloatArray] | None = None,
    give_up: float = GIVE_UP,
) -> list[FloatArray]:
    """Candidates refined towards ``target`` (4x4 world pose; a point in position mode).

    Args:
        robot: the robot.
        target: the world target pose (its translation only in position mode).
        mode: ``"pose"`` or ``"position"``.
        starts: configurations (dof,) to refine.
        tol: stop a candidate once both errors are below this (m, rad).
        held: index of a joint that keeps its start value (its Jacobian column is
            zeroed, so the pseudoinverse never moves it).
        bounds: ``(lower, upper)`` (dof,): a projected Gauss–Newton inside them, each
            start clipped into them; a joint on a bound that the step would push
            outwards is held there for that step (its column zeroed), so the others
            take the whole correction.
        give_up: drop a candidate still this far (m, rad) after three steps (default
            :data:`GIVE_UP`; a start clipped into the bounds may begin farther).

    Returns:
        The refined configurations, unverified (the caller's FK check decides).
    """
    task = make_task(mode, tol=tol)
    out: list[FloatArray] = []
    e = np.empty(6)
    M = np.empty((3, 4))
    for start in starts:
        q = np.array(start, dtype=np.float64)
        if not np.all(np.abs(q) <= MAX_LENGTH_M):
            continue  # not finite, or beyond the length range that FK takes
        if bounds is not None:
            q = np.clip(q, bounds[0], bounds[1])
        errors: list[float] = []
        for step in range(POLISH_STEPS):
            T, J = robot.fk_jacobian(q)
            position, orientation = task_error(T, target, task.packed, e, M)
            if position <= tol and orientation <= tol:
                break
            worst = max(position, orientation)
            if step >= 3 and worst > give_up:
                break
            if step >= 3 and worst > STALL * errors[-3]:
                break  # not converging: three steps did not halve the error
            errors.append(worst)
            rows = np.ascontiguousarray(J)
            m = task_rows(rows, target, task.packed)
            if held is not None:
                rows[:m, held] = 0.0
            dq = _step(rows[:m], e[:m])
            if bounds is not None:
                pushed = ((q <= bounds[0]) & (dq < 0.0)) | ((q >= bounds[1]) & (dq > 0.0))
                if pushed.any():
                    rows[:m, pushed] = 0.0
                    dq = _step(rows[:m], e[:m])
            with np.errstate(over="ignore"):  # a target 1e300 m away: an infinite norm
                norm = float(np.linalg.norm(dq))
            if not np.isfinite(norm):
                break
            if norm > MAX_STEP:
                dq *= MAX_STEP / norm
            q = q + dq
            if bounds is not None:
                q = np.clip(q, bounds[0], bounds[1])
        out.append(q)
    return out


def _step(rows: FloatArray, error: FloatArray) -> FloatArray:
    """The Gauss–Newton step: the pseudoinverse of the task rows times the error."""
    return np.asarray(np.linalg.pinv(rows, rcond=1e-10) @ error)
