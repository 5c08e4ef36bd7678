"""Closed-form (analytic) IK: every branch, verified by forward kinematics.

One family per module, registered by name; a robot names its family (``analytic`` in a
problem file or the ``analytic=`` argument of its constructor), or
:func:`detect_family` finds the first registered family that fits its joint structure.

:func:`analytic_ik` solves one target and :func:`analytic_ik_batch` many. Families with a
compiled pipeline (``spherical_wrist`` and ``ur``: :mod:`optik.analytic._pipeline`) run
the closed form, the wrapping into the limits, the limit filter, the FK check, the
de-duplication and the sort in one compiled call; the others run their closed form in
Python and the same steps in numpy (:func:`wrap_into_limits`, ``Robot.fk``). The
arguments are checked in :mod:`optik.analytic._arguments`; a call with ``free_joint``
goes to :mod:`optik.analytic.held_joint`.
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np
from scipy.optimize import minimize_scalar

from optik._checks import FloatArray
from optik._interrupts import reraise_interrupt, surfaces_interrupts
from optik.analytic import (  # noqa: F401  (importing a family registers it: this order)
    _compiled,
    dobot,
    planar_2r,
    spherical_rrp,
    spherical_wrist,
    ur,
)

# isort: split
# The families found from the joint axes alone, after the DH families: detected last.
from optik.analytic import spherical_axes  # noqa: F401

# isort: split
from optik.analytic import rrp_wrist  # noqa: F401

# isort: split
# Any six revolute joints, numerically: after every exact family.
from optik.analytic import general_6r  # noqa: F401

# isort: split
# After the families: the pipeline imports two of them, which would register them first.
from optik.analytic import _pipeline, _pipeline_args
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
from optik.analytic._base import (
    FAMILIES,
    VERIFY_TOLERANCE,
    AnalyticFamily,
    CompiledPipeline,
    FamilyMatch,
    explain_family,
    family_solves,
    match_families,
    places_tool_point,
)
from optik.analytic._outside import proven_outside
from optik.analytic._polish import polish
from optik.analytic._steps import (
    _beyond_reach,
    _finish,
    beyond_reach_rows,
    finish_batch,
    wrap_into_limits,
)
from optik.analytic.held_joint import (
    free_joint_batch,
    free_joint_ik,
    free_joint_reason,
    free_query,
)
from optik.errors import AnalyticIKError
from optik.model import DECLARED_FAMILY_CHECKS, Robot
from optik.poses import as_target_pose
from optik.spatial import invert_transform

# Constants of the hot path of analytic_ik, bound once (each module attribute lookup
# costs more than the comparison it feeds).
_SHAPE_DOF = (_compiled.DOF,)
_SHAPE_OUT = (_compiled.MAX_BRANCHES, _compiled.DOF)
_SORT = _pipeline_args.SORT
_WITHIN_LIMITS = _pipeline_args.WITHIN_LIMITS

__all__ = [
    "FAMILIES",
    "VERIFY_TOLERANCE",
    "AnalyticBatch",
    "AnalyticFamily",
    "FamilyMatch",
    "analytic_ik",
    "analytic_ik_batch",
    "compiled_batch",
    "detect_family",
    "explain_family",
    "family_of",
    "family_solves",
    "free_joint_reason",
    "match_families",
    "places_tool_point",
    "wrap_into_limits",
]


def detect_family(robot: Robot) -> AnalyticFamily | None:
    """The first registered family whose structure fits ``robot``, or ``None``."""
    for family in FAMILIES.values():
        if family.fits(robot):
            return family
    return None


def family_of(robot: Robot) -> AnalyticFamily | None:
    """The robot's declared family (checked to fit), else a detected one, else ``None``.

    Args:
        robot: the robot.

    Raises:
        AnalyticIKError: the declared family is unknown or does not fit the robot.
    """
    if robot.analytic is None:
        return robot.cached(detect_family)
    family = FAMILIES.get(robot.analytic)
    if family is None:
        raise AnalyticIKError(
            f"robot {robot.name!r}: unknown analytic family {robot.analytic!r} "
            f"(registered: {sorted(FAMILIES)})"
        )
    if not robot.cached(_declared_family_fits):
        raise AnalyticIKError(
            f"robot {robot.name!r}: its joint structure does not fit family "
            f"{family.name!r}: {family.explain(robot)}"
        )
    return family


def _declared_family_fits(robot: Robot) -> bool:
    """Whether the robot's declared (registered) family fits its joint structure."""
    return FAMILIES[cast(str, robot.analytic)].fits(robot)


def _check_mode(robot: Robot, mode: str) -> AnalyticFamily:
    """The robot's family, checked to solve ``mode`` (the errors of :func:`analytic_ik`)."""
    check_robot(robot)
    if not isinstance(mode, str) or mode not in ("pose", "position"):
        raise AnalyticIKError(f"mode must be 'pose' or 'position', got {mode!r}")
    family = family_of(robot)
    if family is None:
        raise AnalyticIKError(f"robot {robot.name!r} has no closed-form IK family")
    if mode not in family.modes:
        raise AnalyticIKError(f"family {family.name!r} solves mode(s) {family.modes}, not {mode!r}")
    return family


def analytic_ik(
    robot: Robot,
    target: Any,
    mode: str = "pose",
    q_ref: Any = None,
    within_limits: bool = True,
    free_joint: str | None = None,
    free_value: float | None = None,
) -> list[FloatArray]:
    """Every closed-form IK branch reaching ``target``, each verified by FK.

    Args:
        robot: a robot whose joint structure has a closed-form family.
        target: 4x4 world pose of the tool (``mode="pose"``), or a 3-vector (or a 4x4 whose
            translation is used) for ``mode="position"``; metres.
        mode: ``"pose"`` or ``"position"``.
        q_ref: reference configuration (dof,): representatives of angles and joints left
            free at singularities are chosen nearest it, and branches are sorted by their
            distance to it. Default: mid-limits (branches then keep the family's order).
        within_limits: drop branches outside the joint limits (default; a bool). With ``False``
            they are kept (still wrapped into the limits where a 2 pi shift allows).
        free_joint: for a seven-joint arm, the name of the joint held at ``free_value``;
            the other six are solved in closed form (:mod:`optik.analytic.free_joint`:
            a spherical-shoulder, spherical-wrist arm such as the KUKA iiwa, holding
            joint 1, 3, 5 or 7; the Franka Panda holding joint 7; see
            :func:`free_joint_reason`). Pose mode only.
        free_value: the held joint's value (rad), inside its limits; required with
            ``free_joint``. ``q_ref``'s entry for the held joint is not used.

    Returns:
        A list of joint vectors (dof,), possibly empty (unreachable, or reachable only
        outside the limits). Each reaches the target within ``VERIFY_TOLERANCE`` (rad;
        in metres relative to an arm larger than 1 m,
        :func:`optik.analytic._base.verify_position_tolerance`); with ``free_joint``,
        each has exactly ``free_value`` there.

    Raises:
        AnalyticIKError: the robot has no family, or the family does not solve ``mode``
            (e.g. position-only IK of a 6-dof arm, which has infinitely many solutions);
            with ``free_joint``: the other six joints fit no closed form (and why).
        OptikError: malformed target or ``q_ref``; an unknown ``free_joint``, a
            ``free_value`` missing, not finite or outside the joint's limits.
    """
    # Ctrl-C that a kernel handed back inside a SystemError (optik._interrupts), caught
    # here rather than by a decorator: a try costs nothing, a wrapper 0.1-0.4 us per call.
    try:
        if free_joint is not None or free_value is not None:
            return free_joint_ik(robot, target, mode, q_ref, within_limits, free_joint, free_value)
        if not isinstance(robot, Robot):
            check_robot(robot)
        within_limits = check_within(within_limits)
        plan = robot.cached_value(_compiled_plan)
        if plan is not None and type(mode) is str and mode == "pose":
            # The hot path (a compiled family, already found and checked to fit): a float64
            # C-contiguous (4, 4) target and (dof,) q_ref go to the kernel as they are; it
            # validates them (finite; last row and rotation as optik.spatial.as_pose).
            solve, _, params, mid = plan
            if (
                type(target) is not np.ndarray
                or target.shape != _SHAPE_4x4
                or target.dtype != _F64
                or not target.flags.carray
            ):
                target = plain(as_target_pose(target, mode))
            if q_ref is None:
                ref = mid
                flags = 0
            else:
                flags = _SORT
                if (
                    type(q_ref) is not np.ndarray
                    or q_ref.shape != _SHAPE_DOF
                    or q_ref.dtype != _F64
                    or not q_ref.flags.carray
                ):
                    ref = plain(check_ref(robot, q_ref))
                else:
                    ref = q_ref
            if within_limits:
                flags |= _WITHIN_LIMITS
            out = np.empty(_SHAPE_OUT)
            n = solve(params, target, ref, flags, out)
            if n > 0:
                return _ROW_VIEWS[n](out)
            if n < 0:
                raise_input_error(robot, target, q_ref, n)
            if _beyond_reach(robot, target, within_limits):
                return []  # a proof: no branch to recover at a degenerate pose
            if (
                within_limits
                and proven_outside(
                    robot, plan, target[None], ref[None], flags & ~_WITHIN_LIMITS, SINGULAR_GATE
                )[0]
            ):
                return []
            family = cast(AnalyticFamily, family_of(robot))
            return _degenerate(robot, family, target, mode, ref, q_ref is not None, within_limits)
        family = _check_mode(robot, mode)
        if mode == "pose" and robot.cached(_compiled_plan) is not None:
            return analytic_ik(robot, target, mode, q_ref, within_limits)
        T_target = as_target_pose(target, mode)
        sort = q_ref is not None
        ref = robot.mid_limits if q_ref is None else check_ref(robot, q_ref)
        if _beyond_reach(robot, T_target, within_limits):
            return []  # a proof, before the family's arithmetic could overflow (1e155 m)
        if mode == "position" and not places_tool_point(family, robot):
            raise AnalyticIKError(
                f"robot {robot.name!r}: position-only closed forms need a tool without offset"
            )
        inverse_base, inverse_tool = robot.cached(_frame_inverses)
        raw = family.candidates(robot, inverse_base @ T_target @ inverse_tool, mode, ref)
        branches = _finish(robot, raw, T_target, mode, ref, sort, within_limits)
        if branches:
            return branches
        return _degenerate(robot, family, T_target, mode, ref, sort, within_limits, raw)
    except SystemError as exc:
        reraise_interrupt(exc)
        raise


def _frame_inverses(robot: Robot) -> tuple[FloatArray, FloatArray]:
    """``(T_world_base^-1, T_flange_tool^-1)`` (4, 4) each, kept per robot.

    A world target ``T`` is the flange pose ``T_world_base^-1 @ T @ T_flange_tool^-1`` in
    frame 0.
    """
    inverses = invert_transform(robot.T_world_base), invert_transform(robot.T_flange_tool)
    for inverse in inverses:
        inverse.flags.writeable = False
    return inverses


FREE_REFERENCES = 24
"""References spread over the limits that a degenerate pose's closed form is rerun from
when every branch lies outside the limits (:func:`_free_references`)."""

SINGULAR_GATE = 1e-6
"""Smallest singular value of the Jacobian (m or rad per rad) below which a branch is
taken as singular, one point of a continuum of answers (:func:`_degenerate`)."""


def _singular(robot: Robot, q: FloatArray) -> bool:
    """Whether ``q`` is a singular configuration (:data:`SINGULAR_GATE`)."""
    return bool(np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1] < SINGULAR_GATE)


def _degenerate(
    robot: Robot,
    family: AnalyticFamily,
    T_target: FloatArray,
    mode: str,
    ref: FloatArray,
    sort: bool,
    within_limits: bool,
    raw: list[FloatArray] | None = None,
) -> list[FloatArray]:
    """Branches the closed form's rounding lost at a degenerate pose (:mod:`._polish`).

    Runs only when no branch passed the FK check or the limits: the raw candidates and
    the reference are polished by Gauss–Newton, then wrapped, filtered and verified as
    usual (a compiled family without any finite candidate, asked without ``q_ref``,
    has nothing to polish: ``[]`` at once). If every branch then lies outside the
    limits and one of them is singular (:data:`SINGULAR_GATE`), the answers form a
    continuum (a shoulder over its axis leaves joint 1 free, an aligned wrist only fixes
    ``q4 + q6``) of which the closed form returned one point, the reference's, and the
    continuum may enter the limits elsewhere: the branches are polished inside the
    limits (projected Gauss–Newton), and failing that the closed form is rerun from
    :data:`FREE_REFERENCES` references spread over the limits. Isolated branches outside
    the limits stay a proof.
    """
    if _beyond_reach(robot, T_target, within_limits):
        return []
    if raw is None:
        inverse_base, inverse_tool = robot.cached(_frame_inverses)
        raw = family.candidates(robot, inverse_base @ T_target @ inverse_tool, mode, ref)
    if not sort and robot.cached_value(_compiled_plan) is not None and not _any_finite(raw):
        # Nothing to refine: the compiled closed form's bands already keep the branches
        # that rounding could lose (tangent roots, the elbow's reach, near misses), and
        # mid-limits is no near-solution (from 7,754 such poses of six arms, singular
        # ones included, its polish reached none). A caller's q_ref may be one.
        return []
    tol = 0.1 * VERIFY_TOLERANCE
    polished = polish(robot, T_target, mode, [*raw, ref], tol)
    found = _finish(robot, polished, T_target, mode, ref, sort, within_limits)
    if found or not within_limits:
        return found
    outside = _finish(robot, [*raw, *polished], T_target, mode, ref, sort, False)
    if not any(_singular(robot, q) for q in outside):
        return []  # isolated branches: outside the limits, no continuum to follow
    bounds = (robot.lower, robot.upper)
    inside = polish(robot, T_target, mode, outside, tol, bounds=bounds, give_up=math.inf)
    found = _finish(robot, inside, T_target, mode, ref, sort, True)
    if found:
        return found
    # A joint left free takes the reference's value, which may be the one that puts the
    # others out of their limits (the drill's shoulder over its axis): other references.
    return _free_references(robot, family, T_target, mode, ref, sort)


def _any_finite(raw: list[FloatArray]) -> bool:
    """Whether any raw candidate (dof,) is finite (the closed form found a branch)."""
    return any(bool(np.all(np.isfinite(q))) for q in raw)


def _free_references(
    robot: Robot,
    family: AnalyticFamily,
    T_target: FloatArray,
    mode: str,
    ref: FloatArray,
    sort: bool,
) -> list[FloatArray]:
    """In-limit branches of a continuum, the closed form rerun from other references.

    References ``low + s (high - low)`` over the limits: :data:`FREE_REFERENCES` values
    of ``s`` spread over ``[0, 1]``, then, around each of the lowest :data:`FREE_DIPS`
    local minima of the branches' excursion beyond the limits (the least sum over
    joints, :func:`_excursion`), a bounded scalar search of ``s`` down to
    :data:`FREE_REFINE_XTOL`: along a branch the excursion is continuous, so a window of
    in-limit answers narrower than the spread (the drill with narrowed limits: 3 % of
    joint 1's range) is found from its edge. The closed form's own branches at each
    reference are exact; the FK check decides. Not a proof either way.
    """
    inverse_base, inverse_tool = robot.cached(_frame_inverses)
    T_0 = inverse_base @ T_target @ inverse_tool
    low = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    high = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    found: list[FloatArray] = []

    def excursion(s: float) -> float:
        nonlocal found
        other = low + s * (high - low)
        raws = family.candidates(robot, T_0, mode, other)
        if not found:
            found = _finish(robot, raws, T_target, mode, ref, sort, True)
        return 0.0 if found else _excursion(robot, _finish(robot, raws, T_target, mode, other,
                                                           False, False))  # fmt: skip

    grid = (np.arange(FREE_REFERENCES) + 0.5) / FREE_REFERENCES
    values = []
    for s in grid:
        values.append(excursion(float(s)))
        if found:
            return found  # a point of the continuum inside the limits
    padded = np.concatenate([[math.inf], values, [math.inf]])
    dips = [
        i for i in range(len(grid))
        if math.isfinite(values[i]) and values[i] <= min(padded[i], padded[i + 2])
    ]  # fmt: skip
    # The excursion jumps where the nearest branch changes: each dip of the spread is
    # searched, lowest first.
    for i in sorted(dips, key=lambda i: values[i])[:FREE_DIPS]:
        lo = grid[i - 1] if i > 0 else 0.0
        hi = grid[i + 1] if i + 1 < len(grid) else 1.0
        minimize_scalar(
            excursion, bounds=(lo, hi), method="bounded",
            options={"xatol": FREE_REFINE_XTOL, "maxiter": FREE_REFINE_STEPS},
        )  # fmt: skip
        if found:
            break
    return found


FREE_REFINE_XTOL = 1e-6
"""Smallest step (a fraction of each joint's range) of :func:`_free_references`' search."""

FREE_REFINE_STEPS = 40
"""Most closed-form runs of each bounded search of :func:`_free_references`."""

FREE_DIPS = 3
"""Local minima of the spread's excursions that :func:`_free_references` searches."""


def _excursion(robot: Robot, branches: list[FloatArray]) -> float:
    """The least excursion beyond the limits among ``branches``; ``inf`` without any.

    Per branch (verified, wrapped) the sum over joints of how far each lies beyond its
    limits (rad or m).
    """
    if not branches:
        return math.inf
    rows = np.array(branches)
    beyond = np.maximum(robot.lower - rows, 0.0) + np.maximum(rows - robot.upper, 0.0)
    return float(np.min(np.sum(beyond, axis=1)))


def _compiled_plan(robot: Robot) -> CompiledPipeline | None:
    """The compiled pose pipeline of the robot's family (DH families by ``kernel``)."""
    family = cast(AnalyticFamily, family_of(robot))
    if not family.kernel:
        return family.compiled(robot)
    params = _compiled.params_of(robot, family.kernel)
    return CompiledPipeline(
        _pipeline.solve, _pipeline.solve_batch, params, _compiled.mid_limits(params)
    )


def compiled_batch(robot: Robot, mode: str) -> bool:
    """Whether :func:`analytic_ik_batch` solves ``mode`` on ``robot`` in one compiled loop.

    A family with a compiled pose pipeline, in ``"pose"`` mode; other families (and
    position mode) run their closed form per target in Python.
    """
    return (
        mode == "pose" and family_of(robot) is not None and robot.cached(_compiled_plan) is not None
    )


@surfaces_interrupts
def analytic_ik_batch(
    robot: Robot,
    targets: Any,
    mode: str = "pose",
    q_ref: Any = None,
    within_limits: bool = True,
    free_joint: str | None = None,
    free_value: Any = None,
) -> AnalyticBatch:
    """:func:`analytic_ik` over a batch of targets, in one compiled loop where possible.

    For a family with a compiled pipeline (``spherical_wrist``, ``ur``) the whole batch is
    one call of :func:`optik.analytic._pipeline.solve_batch` (serial, one core); other
    families run their closed form per target in Python and its checks once over the
    batch (numpy). Either way target ``i`` gets exactly
    the branches, in the same order, that ``analytic_ik(robot, targets[i], mode,
    q_ref_i, within_limits)`` returns.

    Args:
        robot: a robot whose joint structure has a closed-form family.
        targets: (N, 4, 4) world poses of the tool; in position mode also (N, 3) points
            (m).
        mode: ``"pose"`` or ``"position"``.
        q_ref: ``None`` (mid-limits, branches in the family's order), one reference
            (dof,) for every target, or one per target (N, dof); with a reference the
            branches are sorted by their distance to it.
        within_limits: drop branches outside the joint limits (default).
        free_joint: for a seven-joint arm, the joint held (as in :func:`analytic_ik`);
            the batch is then one call of :func:`optik.analytic.free_joint.solve_batch`.
        free_value: the held joint's value (rad): one for every target, or (N,) one per
            target; each inside the joint's limits.

    Returns:
        An :class:`AnalyticBatch` ``(q, counts)``: ``q`` (N, B, dof) NaN-padded branches,
        ``counts`` (N,).

    Raises:
        AnalyticIKError: the robot has no family, or the family does not solve ``mode``;
            with ``free_joint``, as :func:`analytic_ik`.
        ShapeError: ``targets``, ``q_ref`` or ``free_value`` has the wrong shape.
        NonFiniteError: a NaN or infinite entry in ``targets``, ``q_ref`` or
            ``free_value``.
        InvalidRotationError: a target whose rotation is not proper (first one named).
        OptikError: an unknown ``free_joint``; a ``free_value`` missing or outside the
            joint's limits (the first such target named).
    """
    if free_joint is not None or free_value is not None:
        plan, within = free_query(robot, mode, within_limits, free_joint, free_value)
        return free_joint_batch(robot, plan, targets, q_ref, within, free_value)
    family = _check_mode(robot, mode)
    within_limits = check_within(within_limits)
    T = batch_targets(targets, mode)
    refs = batch_refs(robot, q_ref, T.shape[0])
    if mode == "position" and not places_tool_point(family, robot):
        raise AnalyticIKError(
            f"robot {robot.name!r}: position-only closed forms need a tool without offset"
        )
    return checked_batch(robot, family, T, mode, refs, within_limits, polish=True)


def checked_batch(
    robot: Robot,
    family: AnalyticFamily,
    T: FloatArray,
    mode: str,
    refs: FloatArray | None,
    within_limits: bool,
    *,
    polish: bool,
) -> AnalyticBatch:
    """:func:`analytic_ik_batch` on checked arguments, with or without the polish.

    ``T`` (N, 4, 4) valid world targets (of ``mode``), ``refs`` (1, dof), (N, dof) or
    ``None``. With ``polish`` a target without a branch gets the single call's polish
    (a degenerate pose, :func:`_degenerate`), so the batch gives what :func:`analytic_ik`
    gives, target by target; without it such a target keeps none. A caller that samples
    a continuum of targets (:mod:`optik.analytic.roll`) needs no polish: a pose where
    rounding loses a branch is isolated, and unreachable poses, which have none, cost
    a Gauss-Newton search each.
    """
    N = T.shape[0]
    dof = robot.dof
    pipeline = robot.cached(_compiled_plan) if mode == "pose" else None
    if pipeline is not None:
        ref = pipeline.mid.reshape(1, dof) if refs is None else plain(refs)
        flags = (0 if refs is None else _SORT) | (_WITHIN_LIMITS if within_limits else 0)
        Q, counts = pipeline.solve_batch(pipeline.params, T, ref, flags)
        empty = np.flatnonzero(counts == 0) if polish else np.zeros(0, dtype=np.int64)
        if within_limits and empty.size:
            rows_ref = ref if len(ref) == 1 else ref[empty]
            unlimited = flags & ~_WITHIN_LIMITS
            proven = proven_outside(robot, pipeline, T[empty], rows_ref, unlimited, SINGULAR_GATE)
            empty = empty[~proven]
        for row in empty.tolist():
            ref_k = ref[0 if len(ref) == 1 else row]
            found = _degenerate(robot, family, T[row], mode, ref_k, refs is not None, within_limits)
            for b, q in enumerate(found[: Q.shape[1]]):
                Q[row, b] = q
            counts[row] = min(len(found), Q.shape[1])
        return AnalyticBatch(Q, counts)
    results = _python_family_batch(robot, family, T, mode, refs, within_limits, polish)
    width = max([_compiled.MAX_BRANCHES, *(len(r) for r in results)])
    Q = np.full((N, width, dof), math.nan)
    counts = np.zeros(N, dtype=np.int64)
    for k, branches in enumerate(results):
        counts[k] = len(branches)
        if branches:
            Q[k, : len(branches)] = branches
    return AnalyticBatch(Q, counts)


def _python_family_batch(
    robot: Robot,
    family: AnalyticFamily,
    T: FloatArray,
    mode: str,
    refs: FloatArray | None,
    within_limits: bool,
    polish: bool,
) -> list[list[FloatArray]]:
    """:func:`analytic_ik` of each target of ``T`` (N, 4, 4) for a family run in Python.

    The closed form runs per target; its rows' wrap, limits and FK check run once over
    the batch (:func:`optik.analytic._steps.finish_batch`), which gives each target the
    branches :func:`analytic_ik` gives it alone, in the same order (with ``polish``, as
    :func:`checked_batch`).
    """
    N = T.shape[0]
    R = np.broadcast_to(robot.mid_limits if refs is None else refs, (N, robot.dof))
    inverse_base, inverse_tool = robot.cached(_frame_inverses)
    beyond = beyond_reach_rows(robot, T, within_limits).tolist()
    raws = [
        [] if beyond[k] else family.candidates(robot, inverse_base @ T[k] @ inverse_tool, mode, ref)
        for k, ref in enumerate(R)
    ]
    sort = refs is not None
    results = finish_batch(robot, raws, T, mode, R, sort, within_limits)
    for k in range(N) if polish else []:
        if not results[k] and not beyond[k]:
            results[k] = _degenerate(robot, family, T[k], mode, R[k], sort, within_limits, raws[k])
    return results


DECLARED_FAMILY_CHECKS.append(family_of)
