"""Seven-joint arms with one joint held: the entry points around the compiled closed form.

:func:`optik.analytic.analytic_ik` and :func:`optik.analytic.analytic_ik_batch` with
``free_joint`` come here: the held joint's plan per robot (:func:`free_plan`, from
:func:`optik.analytic.free_joint.free_joint_plan`), the checks of the held joint and its
values, the compiled call (:mod:`optik.analytic.free_joint`), and the fallback for a
target without a branch (a polish, or the closed form at nearby held values).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optik._checks import FloatArray, check_real, finite_array
from optik._clock import one_time_setup
from optik.analytic import _compiled, free_joint
from optik.analytic._arguments import F64 as _F64
from optik.analytic._arguments import POSE_SHAPE as _SHAPE_4x4
from optik.analytic._arguments import ROW_VIEWS as _ROW_VIEWS
from optik.analytic._arguments import (
    AnalyticBatch,
    batch_refs,
    batch_targets,
    check_ref,
    check_robot,
    check_within,
    plain,
    raise_input_error,
)
from optik.analytic._base import VERIFY_TOLERANCE
from optik.analytic._pipeline_args import SORT as _SORT
from optik.analytic._pipeline_args import WITHIN_LIMITS as _WITHIN_LIMITS
from optik.analytic._polish import near_solution, polish
from optik.analytic._steps import _beyond_reach, _finish, _verified
from optik.errors import AnalyticIKError, OptikError
from optik.limits import LIMIT_TOLERANCE
from optik.model import Robot
from optik.poses import as_target_pose


def free_joint_plans(robot: Robot) -> dict[int, free_joint.FreeJointPlan]:
    """Per robot, the plans of the joints held so far (filled by :func:`free_plan`)."""
    return {}


def free_plan(robot: Robot, k: int) -> free_joint.FreeJointPlan:
    """The cached :func:`optik.analytic.free_joint.free_joint_plan` of joint ``k``."""
    plans = robot.cached(free_joint_plans)
    if k not in plans:
        with one_time_setup():  # a robot's setup, as Robot.cached builds: no timeout counts it
            plans[k] = free_joint.free_joint_plan(robot, k)
    return plans[k]


def free_joint_reason(robot: Robot, free_joint: str) -> str:
    """Why ``robot`` with joint ``free_joint`` held has no closed form; ``""`` if it has one.

    A seven-joint arm whose other six joints fit the held-joint form
    (:mod:`optik.analytic.free_joint`) gets ``""``: :func:`analytic_ik` with this
    ``free_joint`` then returns every branch, and :func:`optik.solve_ik` with that joint
    frozen answers with them.

    Args:
        robot: the robot.
        free_joint: the name of one of its joints.

    Raises:
        OptikError: ``robot`` is not a Robot, or ``free_joint`` is not one of its joints.
    """
    check_robot(robot)
    k = held_index(robot, free_joint, 0.0)
    return free_plan(robot, k).reason


def held_index(robot: Robot, free_joint: Any, free_value: Any) -> int:
    """The held joint's index, checked with ``free_value``'s presence (:func:`analytic_ik`)."""
    names = robot.joint_names
    if not isinstance(free_joint, str) or free_joint not in names:
        raise OptikError(
            f"free_joint must name a joint of robot {robot.name!r} ({', '.join(names)}), "
            f"got {free_joint!r}"
        )
    if free_value is None:
        raise OptikError(f"free_value is required with free_joint={free_joint!r}")
    return names.index(free_joint)


def check_held_values(robot: Robot, k: int, values: FloatArray) -> None:
    """Every held value inside joint ``k``'s limits (finite already), else the first named."""
    lower, upper = float(robot.lower[k]), float(robot.upper[k])
    outside = np.flatnonzero(
        ~((values >= lower - LIMIT_TOLERANCE) & (values <= upper + LIMIT_TOLERANCE))
    )
    if len(outside):
        i = int(outside[0])
        where = "" if values.ndim == 0 or len(values) == 1 else f"[{i}]"
        raise OptikError(
            f"free_value{where} = {float(values.reshape(-1)[i])!r} is outside the limits of "
            f"joint {robot.joint_names[k]!r} [{lower!r}, {upper!r}]"
        )


def free_query(
    robot: Any, mode: Any, within_limits: Any, free_joint_name: Any, free_value: Any
) -> tuple[free_joint.FreeJointPlan, bool]:
    """The held joint's plan and ``within_limits``, checked.

    The errors of :func:`analytic_ik` with ``free_joint``, except the held value's own
    (its caller checks one value or a batch of them).
    """
    check_robot(robot)
    within = check_within(within_limits)
    if free_joint_name is None:
        raise OptikError("free_value is given without free_joint (the joint to hold)")
    k = held_index(robot, free_joint_name, free_value)
    if not isinstance(mode, str) or mode != "pose":
        raise AnalyticIKError(f"with free_joint, mode must be 'pose', got {mode!r}")
    plan = free_plan(robot, k)
    if plan.reason:
        raise AnalyticIKError(
            f"robot {robot.name!r} with joint {free_joint_name!r} held has no closed form: "
            f"{plan.reason}"
        )
    return plan, within


def free_joint_ik(
    robot: Robot,
    target: Any,
    mode: Any,
    q_ref: Any,
    within_limits: Any,
    free_joint_name: Any,
    free_value: Any,
) -> list[FloatArray]:
    """:func:`analytic_ik` with one joint held (:mod:`optik.analytic.free_joint`).

    One compiled call (:func:`optik.analytic.free_joint.solve`) in the usual case; a
    target without a branch goes through :func:`free_joint_fallback`.
    """
    plan, within = free_query(robot, mode, within_limits, free_joint_name, free_value)
    value = check_real("free_value", free_value)
    lower, upper = robot.lower[plan.held], robot.upper[plan.held]
    if not lower - LIMIT_TOLERANCE <= value <= upper + LIMIT_TOLERANCE:  # plain floats: fast
        check_held_values(robot, plan.held, np.array([value]))  # raises, naming the joint
    if (
        type(target) is not np.ndarray
        or target.shape != _SHAPE_4x4
        or target.dtype != _F64
        or not target.flags.carray
    ):
        target = plain(as_target_pose(target, "pose"))
    if q_ref is None:
        ref = robot.mid_limits
        flags = 0
    else:
        ref = plain(check_ref(robot, q_ref))
        flags = _SORT
    if within:
        flags |= _WITHIN_LIMITS
    out = np.empty((_compiled.MAX_BRANCHES, free_joint.FREE_DOF))
    n = free_joint.solve(plan.params, target, ref, value, flags, out)
    if n > 0:
        return _ROW_VIEWS[n](out)
    if n < 0:
        raise_input_error(robot, target, q_ref, n)
    return free_joint_fallback(robot, plan, value, target, ref, q_ref is not None, within)


def free_joint_fallback(
    robot: Robot,
    plan: free_joint.FreeJointPlan,
    value: float,
    T_target: FloatArray,
    ref: FloatArray,
    sort: bool,
    within: bool,
) -> list[FloatArray]:
    """A held-joint target on which the compiled call found no branch (numpy steps).

    Beyond the reach: none (a proof). Else what rounding at a degenerate pose may have
    spoiled is polished: the raw candidates the FK check rejects, and the reference when
    it is a near-solution (:func:`optik.analytic._polish.near_solution`; polishing a
    distant one would be a search). When branches exist only outside the limits and a
    singularity left an angle free (the raw candidates change with the reference), other
    references are tried for it. A sweep over the held joint meets these cases at most
    values: verified candidates are not polished again, and candidates that do not depend
    on the reference are not recomputed (about 1 ms per target before, 20-30 us now).
    """
    if _beyond_reach(robot, T_target, within):
        return []
    k = plan.held
    ref = np.array(ref, dtype=float)
    ref[k] = value
    held = (k, value)
    raw = free_joint_raw(plan, value, T_target, ref)
    exact = _verified(robot, np.array(raw), T_target, "pose") if raw else np.zeros(0, dtype=bool)
    starts = [q for q, ok in zip(raw, exact.tolist(), strict=True) if not ok]
    if near_solution(robot, T_target, ref):
        starts.append(ref)
    branches: list[FloatArray] = []
    if starts:
        polished = polish(robot, T_target, "pose", starts, 0.1 * VERIFY_TOLERANCE, held=k)
        kept = [q for q, ok in zip(raw, exact.tolist(), strict=True) if ok]
        branches = _finish(robot, kept + polished, T_target, "pose", ref, sort, within, held)
    if branches or not raw:
        return branches
    if not np.any(exact):
        # Nothing verified nor polished: where a singularity left an angle free (the
        # candidates change with the reference) its reference's value may be the one
        # from which no Gauss-Newton step reaches the target (the iiwa held at joint 1,
        # its elbow 1e-8 rad from straight: the bend is below the distance equation's
        # resolution, and it points the right way only with the free angle turned).
        return _polished_from_references(robot, plan, value, T_target, ref, sort, within, raw)
    if not within:
        return branches
    # Branches exist, all outside the limits. At a singularity a free angle took the
    # reference and pushed a dependent one out: other references for the free angles.
    found: list[FloatArray] = []
    trials: list[FloatArray] = []
    for trial in _free_trials(robot, ref, k, value):
        trials.append(trial)
        found += free_joint_raw(plan, value, T_target, trial)
    if np.array_equal(np.array(found), np.array(raw * len(_FREE_RETRIES)), equal_nan=True):
        return []  # no angle took the reference: the same candidates, outside the limits
    # Each reference's branches as the compiled call gives them (the Newton step taken,
    # verified), none dropped by the limits yet: the numpy steps judge them together.
    out = np.empty((_compiled.MAX_BRANCHES, free_joint.FREE_DOF))
    refined: list[FloatArray] = []
    for trial in trials:
        n = free_joint.solve(plan.params, T_target, trial, value, 0, out)
        refined += [out[i].copy() for i in range(max(n, 0))]
    return _finish(robot, refined, T_target, "pose", ref, sort, within, held)


_FREE_RETRIES = (0.5, 0.25, 0.75, 0.1, 0.9)
"""References (fractions of each joint's range) retried for the angles a singularity
leaves free, when the reference's own choice puts every branch outside the limits or
leaves every candidate where no polish reaches the target."""


def _free_trials(robot: Robot, ref: FloatArray, k: int, value: float) -> list[FloatArray]:
    """The references (dof,) of :data:`_FREE_RETRIES`, joint ``k`` held at ``value``.

    A joint without finite limits keeps ``ref``'s value.
    """
    trials = []
    for fraction in _FREE_RETRIES:
        trial = np.where(
            np.isfinite(robot.lower + robot.upper),
            robot.lower + fraction * (robot.upper - robot.lower),
            ref,
        )
        trial[k] = value
        trials.append(trial)
    return trials


def _polished_from_references(
    robot: Robot,
    plan: free_joint.FreeJointPlan,
    value: float,
    T_target: FloatArray,
    ref: FloatArray,
    sort: bool,
    within: bool,
    raw: list[FloatArray],
) -> list[FloatArray]:
    """The first of :data:`_FREE_RETRIES`' references whose polished candidates verify.

    ``raw`` holds the reference's own candidates: another reference that gives the same
    ones shows that no angle is free, and the search stops (a target out of reach costs
    one more closed-form call).
    """
    k = plan.held
    for trial in _free_trials(robot, ref, k, value):
        if np.array_equal(trial, ref):
            continue
        candidates = free_joint_raw(plan, value, T_target, trial)
        if np.array_equal(np.array(candidates), np.array(raw), equal_nan=True):
            return []
        polished = polish(robot, T_target, "pose", candidates, 0.1 * VERIFY_TOLERANCE, held=k)
        found = _finish(robot, polished, T_target, "pose", ref, sort, within, (k, value))
        if found:
            return found
    return []


def free_joint_raw(
    plan: free_joint.FreeJointPlan, value: float, T_target: FloatArray, ref: FloatArray
) -> list[FloatArray]:
    """The raw branches of the held-joint closed form (free angles at ``ref``)."""
    cand = np.empty((_compiled.MAX_BRANCHES, len(ref)))
    n = free_joint.free_joint_candidates(plan.params, value, T_target, plain(ref), cand)
    return list(cand[:n])


def free_joint_batch(
    robot: Robot,
    plan: free_joint.FreeJointPlan,
    targets: Any,
    q_ref: Any,
    within: bool,
    free_value: Any,
) -> AnalyticBatch:
    """:func:`analytic_ik_batch` with one joint held: one compiled loop.

    The targets without a branch then go through :func:`free_joint_fallback`, as in
    single calls, so that each target gets what :func:`analytic_ik` gives it.
    """
    T = batch_targets(targets, "pose")
    N = T.shape[0]
    refs = batch_refs(robot, q_ref, N)
    if np.ndim(free_value) == 0:
        values = np.array([check_real("free_value", free_value)])
    else:
        values = finite_array("free_value", free_value, (N,))
    check_held_values(robot, plan.held, values)
    ref = robot.mid_limits.reshape(1, -1) if refs is None else plain(refs)
    flags = (0 if refs is None else _SORT) | (_WITHIN_LIMITS if within else 0)
    Q, counts = free_joint.solve_batch(plan.params, T, plain(ref), plain(values), flags)
    for row in np.flatnonzero(counts == 0).tolist():
        value = float(values[0 if len(values) == 1 else row])
        ref_k = ref[0 if len(ref) == 1 else row]
        found = free_joint_fallback(robot, plan, value, T[row], ref_k, refs is not None, within)
        for b, q in enumerate(found[: Q.shape[1]]):
            Q[row, b] = q
        counts[row] = min(len(found), Q.shape[1])
    return AnalyticBatch(Q, counts)
