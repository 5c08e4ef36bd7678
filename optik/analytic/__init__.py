"""Closed-form (analytic) IK: every branch, verified by forward kinematics.

One family per module, registered by name; a robot names its family (``analytic`` in a
problem file or the ``analytic=`` argument of its constructor), or
:func:`detect_family` finds the first registered family that fits its joint structure.

:func:`analytic_ik` solves one target and :func:`analytic_ik_batch` many. Families with a
compiled pipeline (``spherical_wrist`` and ``ur``: :mod:`optik.analytic._pipeline`) run
the closed form, the wrapping into the limits, the limit filter, the FK check, the
de-duplication and the sort in one compiled call; the others run their closed form in
Python and the same steps in numpy (:func:`wrap_into_limits`, ``Robot.fk``).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, cast

import numpy as np
from numpy.typing import NDArray

from optik._checks import (
    FloatArray,
    as_float_array,
    check_bool,
    check_finite,
    check_real,
    finite_array,
)
from optik._math import first_bad_pose
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
# After the families: the pipeline imports two of them, which would register them first.
from optik._clock import one_time_setup
from optik.analytic import _pipeline, free_joint
from optik.analytic._base import (
    FAMILIES,
    VERIFY_TOLERANCE,
    AnalyticFamily,
    CompiledPipeline,
    FamilyMatch,
    explain_family,
    match_families,
    places_tool_point,
)
from optik.analytic._polish import near_solution, polish
from optik.analytic._steps import (
    _beyond_reach,
    _finish,
    _verified,
    beyond_reach_rows,
    finish_batch,
    wrap_into_limits,
)
from optik.errors import AnalyticIKError, OptikError, ShapeError
from optik.limits import LIMIT_TOLERANCE
from optik.model import DECLARED_FAMILY_CHECKS, Robot
from optik.poses import as_target_pose
from optik.spatial import as_pose, invert_transform

_F64 = np.dtype(np.float64)
# Constants of the hot path of analytic_ik, bound once (each module attribute lookup
# costs more than the comparison it feeds).
_SHAPE_4x4 = (4, 4)
_SHAPE_DOF = (_compiled.DOF,)
_SHAPE_OUT = (_compiled.MAX_BRANCHES, _compiled.DOF)
_SORT = _pipeline.SORT
_WITHIN_LIMITS = _pipeline.WITHIN_LIMITS

__all__ = [
    "FAMILIES",
    "VERIFY_TOLERANCE",
    "AnalyticBatch",
    "AnalyticFamily",
    "FamilyMatch",
    "analytic_ik",
    "analytic_ik_batch",
    "detect_family",
    "explain_family",
    "family_of",
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


def _plain(array: FloatArray) -> FloatArray:
    """``array`` itself if C-contiguous, aligned and writeable float64, else such a copy.

    The compiled kernels are specialised for exactly this array type; any other layout
    would trigger a new compilation.
    """
    if array.dtype == _F64 and array.flags.carray:
        return array
    return np.array(array, dtype=np.float64, order="C")


def _check_robot(robot: Any) -> None:
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")


def _check_within(within_limits: Any) -> bool:
    """``within_limits`` as a bool (a string ``"false"`` is not taken for true)."""
    if within_limits is True or within_limits is False:  # the common case, ~30 ns
        return within_limits
    return check_bool("within_limits", within_limits)


def _check_mode(robot: Robot, mode: str) -> AnalyticFamily:
    """The robot's family, checked to solve ``mode`` (the errors of :func:`analytic_ik`)."""
    _check_robot(robot)
    if not isinstance(mode, str) or mode not in ("pose", "position"):
        raise AnalyticIKError(f"mode must be 'pose' or 'position', got {mode!r}")
    family = family_of(robot)
    if family is None:
        raise AnalyticIKError(f"robot {robot.name!r} has no closed-form IK family")
    if mode not in family.modes:
        raise AnalyticIKError(f"family {family.name!r} solves mode(s) {family.modes}, not {mode!r}")
    return family


def _check_ref(robot: Robot, q_ref: Any) -> FloatArray:
    """``q_ref`` validated as one configuration (dof,)."""
    ref = robot.check_q(q_ref, "q_ref")
    if ref.ndim != 1:
        raise AnalyticIKError("q_ref must be a single configuration (dof,)")
    return ref


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
        outside the limits). Each reaches the target within ``VERIFY_TOLERANCE``; with
        ``free_joint``, each has exactly ``free_value`` there.

    Raises:
        AnalyticIKError: the robot has no family, or the family does not solve ``mode``
            (e.g. position-only IK of a 6-dof arm, which has infinitely many solutions);
            with ``free_joint``: the other six joints fit no closed form (and why).
        OptikError: malformed target or ``q_ref``; an unknown ``free_joint``, a
            ``free_value`` missing, not finite or outside the joint's limits.
    """
    if free_joint is not None or free_value is not None:
        return _free_joint_ik(robot, target, mode, q_ref, within_limits, free_joint, free_value)
    if not isinstance(robot, Robot):
        _check_robot(robot)
    within_limits = _check_within(within_limits)
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
            target = _plain(as_target_pose(target, mode))
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
                ref = _plain(_check_ref(robot, q_ref))
            else:
                ref = q_ref
        if within_limits:
            flags |= _WITHIN_LIMITS
        out = np.empty(_SHAPE_OUT)
        n = solve(params, target, ref, flags, out)
        if n > 0:
            return [out[i] for i in range(n)]  # cheaper than list(out[:n]): no slice view
        if n < 0:
            _raise_input_error(robot, target, q_ref, n)
        family = cast(AnalyticFamily, family_of(robot))
        return _degenerate(robot, family, target, mode, ref, q_ref is not None, within_limits)
    family = _check_mode(robot, mode)
    if mode == "pose" and robot.cached(_compiled_plan) is not None:
        return analytic_ik(robot, target, mode, q_ref, within_limits)
    T_target = as_target_pose(target, mode)
    sort = q_ref is not None
    ref = robot.mid_limits if q_ref is None else _check_ref(robot, q_ref)
    if _beyond_reach(robot, T_target):
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


def _frame_inverses(robot: Robot) -> tuple[FloatArray, FloatArray]:
    """``(T_world_base^-1, T_flange_tool^-1)`` (4, 4) each, kept per robot.

    A world target ``T`` is the flange pose ``T_world_base^-1 @ T @ T_flange_tool^-1`` in
    frame 0.
    """
    inverses = invert_transform(robot.T_world_base), invert_transform(robot.T_flange_tool)
    for inverse in inverses:
        inverse.flags.writeable = False
    return inverses


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

    Runs only when no branch passed the FK check: the raw candidates and the reference
    are polished by Gauss–Newton, then wrapped, filtered and verified as usual.
    """
    if _beyond_reach(robot, T_target):
        return []
    if raw is None:
        inverse_base, inverse_tool = robot.cached(_frame_inverses)
        raw = family.candidates(robot, inverse_base @ T_target @ inverse_tool, mode, ref)
    starts = [*raw, ref]
    polished = polish(robot, T_target, mode, starts, 0.1 * VERIFY_TOLERANCE)
    return _finish(robot, polished, T_target, mode, ref, sort, within_limits)


def _compiled_plan(robot: Robot) -> CompiledPipeline | None:
    """The compiled pose pipeline of the robot's family (DH families by ``kernel``)."""
    family = cast(AnalyticFamily, family_of(robot))
    if not family.kernel:
        return family.compiled(robot)
    params = _compiled.params_of(robot, family.kernel)
    return CompiledPipeline(
        _pipeline.solve, _pipeline.solve_batch, params, _compiled.mid_limits(params)
    )


def _raise_input_error(robot: Robot, target: Any, q_ref: Any, code: int) -> None:
    """Raise the optik error for an input the compiled checks rejected (``code < 0``)."""
    as_target_pose(target, "pose")  # raises for a bad target
    if q_ref is not None:
        _check_ref(robot, q_ref)  # ... or for a bad q_ref
    raise OptikError(  # pragma: no cover - the compiled checks replicate the Python ones
        f"target or q_ref rejected by the compiled checks (code {code}) but not by Python"
    )


# ---------------------------------------------------------------------- a held joint
def _free_joint_plans(robot: Robot) -> dict[int, free_joint.FreeJointPlan]:
    """Per robot, the plans of the joints held so far (filled by :func:`_free_plan`)."""
    return {}


def _free_plan(robot: Robot, k: int) -> free_joint.FreeJointPlan:
    """The cached :func:`optik.analytic.free_joint.free_joint_plan` of joint ``k``."""
    plans = robot.cached(_free_joint_plans)
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
    _check_robot(robot)
    k = _held_index(robot, free_joint, 0.0)
    return _free_plan(robot, k).reason


def _held_index(robot: Robot, free_joint: Any, free_value: Any) -> int:
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


def _check_held_values(robot: Robot, k: int, values: FloatArray) -> None:
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


def _free_query(
    robot: Any, mode: Any, within_limits: Any, free_joint_name: Any, free_value: Any
) -> tuple[free_joint.FreeJointPlan, bool]:
    """The held joint's plan and ``within_limits``, checked.

    The errors of :func:`analytic_ik` with ``free_joint``, except the held value's own
    (its caller checks one value or a batch of them).
    """
    _check_robot(robot)
    within = _check_within(within_limits)
    if free_joint_name is None:
        raise OptikError("free_value is given without free_joint (the joint to hold)")
    k = _held_index(robot, free_joint_name, free_value)
    if not isinstance(mode, str) or mode != "pose":
        raise AnalyticIKError(f"with free_joint, mode must be 'pose', got {mode!r}")
    plan = _free_plan(robot, k)
    if plan.reason:
        raise AnalyticIKError(
            f"robot {robot.name!r} with joint {free_joint_name!r} held has no closed form: "
            f"{plan.reason}"
        )
    return plan, within


def _free_joint_ik(
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
    target without a branch goes through :func:`_free_joint_fallback`.
    """
    plan, within = _free_query(robot, mode, within_limits, free_joint_name, free_value)
    value = check_real("free_value", free_value)
    lower, upper = robot.lower[plan.held], robot.upper[plan.held]
    if not lower - LIMIT_TOLERANCE <= value <= upper + LIMIT_TOLERANCE:  # plain floats: fast
        _check_held_values(robot, plan.held, np.array([value]))  # raises, naming the joint
    if (
        type(target) is not np.ndarray
        or target.shape != _SHAPE_4x4
        or target.dtype != _F64
        or not target.flags.carray
    ):
        target = _plain(as_target_pose(target, "pose"))
    if q_ref is None:
        ref = robot.mid_limits
        flags = 0
    else:
        ref = _plain(_check_ref(robot, q_ref))
        flags = _SORT
    if within:
        flags |= _WITHIN_LIMITS
    out = np.empty((_compiled.MAX_BRANCHES, free_joint.FREE_DOF))
    n = free_joint.solve(plan.params, target, ref, value, flags, out)
    if n > 0:
        return [out[i] for i in range(n)]
    if n < 0:
        _raise_input_error(robot, target, q_ref, n)
    return _free_joint_fallback(robot, plan, value, target, ref, q_ref is not None, within)


def _free_joint_fallback(
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
    if _beyond_reach(robot, T_target):
        return []
    k = plan.held
    ref = np.array(ref, dtype=float)
    ref[k] = value
    held = (k, value)
    raw = _free_joint_raw(plan, value, T_target, ref)
    exact = _verified(robot, np.array(raw), T_target, "pose") if raw else np.zeros(0, dtype=bool)
    starts = [q for q, ok in zip(raw, exact.tolist(), strict=True) if not ok]
    if near_solution(robot, T_target, ref):
        starts.append(ref)
    branches: list[FloatArray] = []
    if starts:
        polished = polish(robot, T_target, "pose", starts, 0.1 * VERIFY_TOLERANCE, held=k)
        kept = [q for q, ok in zip(raw, exact.tolist(), strict=True) if ok]
        branches = _finish(robot, kept + polished, T_target, "pose", ref, sort, within, held)
    if branches or not within or not np.any(exact):
        return branches
    # Branches exist, all outside the limits. At a singularity a free angle took the
    # reference and pushed a dependent one out: other references for the free angles.
    found: list[FloatArray] = []
    trials: list[FloatArray] = []
    for fraction in _FREE_RETRIES:
        trial = np.where(
            np.isfinite(robot.lower + robot.upper),
            robot.lower + fraction * (robot.upper - robot.lower),
            ref,
        )
        trial[k] = value
        trials.append(trial)
        found += _free_joint_raw(plan, value, T_target, trial)
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
leaves free, when the reference's own choice puts every branch outside the limits."""


def _free_joint_raw(
    plan: free_joint.FreeJointPlan, value: float, T_target: FloatArray, ref: FloatArray
) -> list[FloatArray]:
    """The raw branches of the held-joint closed form (free angles at ``ref``)."""
    cand = np.empty((_compiled.MAX_BRANCHES, len(ref)))
    n = free_joint.free_joint_candidates(plan.params, value, T_target, _plain(ref), cand)
    return list(cand[:n])


# ---------------------------------------------------------------------- batches
IntArray = NDArray[np.int64]


class AnalyticBatch(NamedTuple):
    """Every branch of a batch of targets: :func:`analytic_ik_batch`'s result.

    Unpacks as ``Q, counts = analytic_ik_batch(robot, targets)``.

    Attributes:
        q: (N, B, dof) branches of target ``i`` in ``q[i, :counts[i]]`` (rad, m), in
            :func:`analytic_ik`'s order; the rows past ``counts[i]`` are NaN. ``B`` is
            :data:`optik.analytic._compiled.MAX_BRANCHES` (8), or more for a Python
            family that returned more.
        counts: (N,) number of branches of each target (0: unreachable, or only outside
            the limits when they are applied).
    """

    q: FloatArray
    counts: IntArray

    def branches(self, i: int) -> list[FloatArray]:
        """The branches of target ``i``, as :func:`analytic_ik` returns them.

        Args:
            i: index of the target in the batch, in ``[0, N)``.
        """
        return list(self.q[i, : int(self.counts[i])])

    @property
    def first(self) -> FloatArray:
        """(N, dof) the first branch of each target, NaN where there is none.

        With a ``q_ref`` it is the branch nearest the reference.
        """
        return self.q[:, 0, :]

    @property
    def solved(self) -> NDArray[np.bool_]:
        """(N,) whether each target has at least one branch."""
        return self.counts > 0


def _batch_targets(targets: Any, mode: str) -> FloatArray:
    """Validate a batch of targets: (N, 4, 4) poses, or in position mode (N, 3) points.

    Returns (N, 4, 4) C-contiguous float64 poses (identity rotations in position mode).

    Raises:
        ShapeError: wrong shape (also a bad last row, as :func:`optik.spatial.as_pose`).
        NonFiniteError: a NaN or infinite entry.
        InvalidRotationError: a rotation block that is not a proper rotation (the message
            names the first bad target, ``targets[i]``).
    """
    T = as_float_array("targets", targets)
    if mode == "position" and T.ndim == 2 and T.shape[1] == 3:
        check_finite("targets", T)
        poses = np.zeros((len(T), 4, 4))
        poses[:, 0, 0] = poses[:, 1, 1] = poses[:, 2, 2] = poses[:, 3, 3] = 1.0
        poses[:, :3, 3] = T
        return poses
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        expected = "(N, 4, 4)" + (" or (N, 3)" if mode == "position" else "")
        raise ShapeError("targets", expected, T.shape)
    T = _plain(T)
    bad = first_bad_pose(T, *_compiled.pose_tolerances())
    if bad >= 0:
        as_pose(f"targets[{bad}]", T[bad])  # raises the error naming the first bad target
        raise OptikError(  # pragma: no cover - the compiled checks replicate as_pose
            f"targets[{bad}] rejected by the compiled checks but not by as_pose"
        )
    if mode == "position":
        positions = T[:, :3, 3]
        T = np.zeros_like(T)
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = T[:, 3, 3] = 1.0
        T[:, :3, 3] = positions
    return T


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
        plan, within = _free_query(robot, mode, within_limits, free_joint, free_value)
        return _free_joint_batch(robot, plan, targets, q_ref, within, free_value)
    family = _check_mode(robot, mode)
    within_limits = _check_within(within_limits)
    T = _batch_targets(targets, mode)
    refs = _batch_refs(robot, q_ref, T.shape[0])
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
        ref = pipeline.mid.reshape(1, dof) if refs is None else _plain(refs)
        flags = (0 if refs is None else _SORT) | (_WITHIN_LIMITS if within_limits else 0)
        Q, counts = pipeline.solve_batch(pipeline.params, T, ref, flags)
        for row in np.flatnonzero(counts == 0).tolist() if polish else []:
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
    beyond = beyond_reach_rows(robot, T).tolist()
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


def _batch_refs(robot: Robot, q_ref: Any, N: int) -> FloatArray | None:
    """``q_ref`` of a batch of ``N`` targets as (1, dof) or (N, dof), or ``None``."""
    if q_ref is None:
        return None
    dof = robot.dof
    refs = finite_array("q_ref", q_ref, (dof,), batch=True)
    refs = refs.reshape(1, dof) if refs.ndim == 1 else refs
    if refs.shape[0] not in (1, N):
        raise ShapeError("q_ref", f"({dof},) or ({N}, {dof})", refs.shape)
    return refs


def _free_joint_batch(
    robot: Robot,
    plan: free_joint.FreeJointPlan,
    targets: Any,
    q_ref: Any,
    within: bool,
    free_value: Any,
) -> AnalyticBatch:
    """:func:`analytic_ik_batch` with one joint held: one compiled loop.

    The targets without a branch then go through :func:`_free_joint_fallback`, as in
    single calls, so that each target gets what :func:`analytic_ik` gives it.
    """
    T = _batch_targets(targets, "pose")
    N = T.shape[0]
    refs = _batch_refs(robot, q_ref, N)
    if np.ndim(free_value) == 0:
        values = np.array([check_real("free_value", free_value)])
    else:
        values = finite_array("free_value", free_value, (N,))
    _check_held_values(robot, plan.held, values)
    ref = robot.mid_limits.reshape(1, -1) if refs is None else _plain(refs)
    flags = (0 if refs is None else _SORT) | (_WITHIN_LIMITS if within else 0)
    Q, counts = free_joint.solve_batch(plan.params, T, _plain(ref), _plain(values), flags)
    for row in np.flatnonzero(counts == 0).tolist():
        value = float(values[0 if len(values) == 1 else row])
        ref_k = ref[0 if len(ref) == 1 else row]
        found = _free_joint_fallback(robot, plan, value, T[row], ref_k, refs is not None, within)
        for b, q in enumerate(found[: Q.shape[1]]):
            Q[row, b] = q
        counts[row] = min(len(found), Q.shape[1])
    return AnalyticBatch(Q, counts)


DECLARED_FAMILY_CHECKS.append(family_of)
