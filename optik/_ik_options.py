"""What :func:`optik.solve_ik` and :func:`optik.solve_ik_batch` validate alike.

The budget limits (iterations per attempt, restarts, seeds) and the checks of ``q0`` and
of the keywords both entry points take.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypedDict

import numpy as np

from optik._checks import FloatArray, check_choice, check_int, check_real
from optik.chain import read_only
from optik.diffik import clip_into_limits
from optik.errors import JointLimitError, OptikError
from optik.limits import LIMIT_TOLERANCE
from optik.model import Robot

DEFAULT_RESTARTS = 100
"""Restarts after the first attempt when neither ``restarts`` nor ``timeout_s`` is given."""

CROSS_CHECK_RESTARTS = 20
"""Restarts of the numeric attempt that checks a closed form's "no branch" before it is
reported as a proof (:func:`optik.solve_ik` and :func:`optik.solve_ik_batch`): at
singular poses (a wrist or elbow aligned, a joint free) a closed form can miss the
one-parameter family of solutions that passes through them."""

FROZEN_RESTARTS = 300
"""Default ``restarts`` of a query with frozen joints: the narrowed arm's answers are
rarer and the seed table's entries, clipped onto the frozen values, start farther from
them (measured: of 500 random reachable Panda targets with joint 3 frozen, one needed 114
restarts)."""

UNLIMITED_RESTARTS = 2**62
"""The restart budget within a finite ``timeout_s`` when ``restarts`` is not given."""

MAX_ITERATIONS = 100_000
"""Largest ``max_iter``: one attempt runs inside compiled code without looking at the
clock, so its length must be bounded (100,000 LM iterations of a 7-dof arm take about
0.1 s); the deadline is checked between attempts."""

MAX_SEED = 2**63 - 1
"""Largest ``seed`` (the streams are 64-bit)."""


class TaskKeywords(TypedDict, total=False):
    """The task keywords every IK entry point takes, as :func:`optik.task.make_task` does.

    ``make_task`` holds their defaults (``mode="pose"``, ``axis="z"``, ``weights=None``,
    ``tol=1e-6``) and checks them.
    """

    mode: str
    axis: str
    weights: Any
    tol: float | tuple[float, float]


def check_q0(robot: Robot, q0: Any) -> FloatArray:
    """``q0`` as a (dof,) array inside the limits; see :func:`optik.diffik.clip_into_limits`."""
    if q0 is None:
        return robot.mid_limits
    return clip_into_limits(robot, "q0", q0)


def check_options(
    warm_start: Any,
    timeout_s: Any,
    restarts: Any,
    max_iter: Any = None,
    seed: Any = 0,
) -> None:
    """Validate the budget keywords shared by :func:`solve_ik` and :func:`solve_ik_batch`.

    (The task keywords are :func:`optik.task.make_task`'s to check.)
    """
    check_choice("warm_start", warm_start, ("analytic", "q0"))
    if timeout_s is not None:
        check_real("timeout_s", timeout_s, positive=True, allow_inf=True)
    if restarts is not None:
        check_int("restarts", restarts, minimum=0, maximum=UNLIMITED_RESTARTS)
    if max_iter is not None:
        check_int("max_iter", max_iter, minimum=1, maximum=MAX_ITERATIONS)
    check_int("seed", seed, minimum=0, maximum=MAX_SEED)


def query_bounds(
    robot: Robot, frozen: Any, limit_margin: Any
) -> tuple[FloatArray, FloatArray] | None:
    """The box of ``frozen`` joints and ``limit_margin`` (``None``: the plain limits).

    Args:
        robot: the robot.
        frozen: ``{joint name: value}`` (rad or m) or ``None``; each value inside its
            joint's limits (within :data:`~optik.limits.LIMIT_TOLERANCE`).
        limit_margin: distance (rad or m) kept free inside every finite limit, at most
            half of each such joint's range; frozen joints are exempt.

    Returns:
        ``(lower, upper)`` read-only (dof,) arrays, ``lower == upper`` on frozen joints,
        or ``None`` when neither narrows the limits.
    """
    margin = check_real("limit_margin", limit_margin, nonnegative=True)
    if frozen is None:
        frozen = {}
    if not isinstance(frozen, Mapping):
        raise OptikError(f"frozen must map joint names to values, got {frozen!r}")
    if margin == 0.0 and not frozen:
        return None
    lower = robot.lower.copy()
    upper = robot.upper.copy()
    if margin > 0.0:
        span = upper - lower
        finite = np.isfinite(span)
        too_narrow = np.flatnonzero(finite & (2.0 * margin > span))
        if too_narrow.size:
            joint = robot.joints[int(too_narrow[0])]
            raise OptikError(
                f"limit_margin {margin:g} is wider than half the range of joint "
                f"{joint.name!r} ({joint.upper - joint.lower:g})"
            )
        lower[finite] += margin
        upper[finite] -= margin
    if frozen:
        names = robot.joint_names
        for name, value in frozen.items():
            if name not in names:
                raise OptikError(
                    f"frozen: {name!r} is not a joint of {robot.name!r} (joints: "
                    f"{', '.join(names)})"
                )
            i = names.index(name)
            v = check_real(f"frozen[{name!r}]", value)
            joint = robot.joints[i]
            if not joint.lower - LIMIT_TOLERANCE <= v <= joint.upper + LIMIT_TOLERANCE:
                unit = "m" if joint.kind == "prismatic" else "rad"
                raise JointLimitError(name, v, joint.lower, joint.upper, unit, argument="frozen")
            lower[i] = upper[i] = min(max(v, joint.lower), joint.upper)
    return read_only(lower), read_only(upper)
