"""Joint limits: role defaults and validation.

Limits are float arrays aligned with ``q`` (rad for revolute joints, m for prismatic),
``-inf``/``+inf`` only for continuous revolute joints.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from optik._checks import MAX_LENGTH_M, FloatArray, as_float_array, check_finite
from optik.errors import InvalidLimitsError, ModelError, ShapeError

ROLE_LIMITS_RAD: dict[str, tuple[float, float]] = {
    "arm": (-math.radians(135.0), math.radians(135.0)),
    "wrist": (-math.radians(90.0), math.radians(90.0)),
    "spindle": (-math.pi, math.pi),
}
"""Default limits by joint role: arm 270° range, wrist 180°, drilling spindle 360°."""

LIMIT_TOLERANCE = 1e-12
"""Slack (rad or m) allowed on a bound when deciding whether ``q`` is inside the limits."""

Q_CLIP_TOLERANCE = 1e-6
"""How far (rad or m) a given configuration may lie outside a limit and still be used.

A measured configuration (an encoder reading, the last state of a servo loop) can sit a
hair beyond a limit. ``solve_ik``'s ``q0`` and ``diff_ik``'s ``q`` within this distance of
the limits are clipped onto them; beyond it they raise
:class:`~optik.errors.JointLimitError` naming the joint. 1e-6 rad is about 0.2 arcsec,
finer than the resolution of a typical 20-bit joint encoder (6e-6 rad).
"""


FROZEN_MATCH_TOLERANCE = 1e-9
"""How far (rad or m) a closed-form branch's frozen joint may lie from the frozen value
and still be taken as holding it (then set to it exactly): the rounding of a joint
recovered from a pose, which grows near a singularity."""


def into_box(
    rows: FloatArray, lower: FloatArray, upper: FloatArray
) -> tuple[np.ndarray, FloatArray]:
    """Which closed-form branches (..., dof) lie inside a query's box, and all snapped onto it.

    A frozen joint (``lower == upper``) counts as held within
    :data:`FROZEN_MATCH_TOLERANCE` (a branch recovers it to rounding only), the others
    within :data:`LIMIT_TOLERANCE`. Returns ``(inside (...,), clipped (..., dof))``; NaN
    rows are not inside. (Wrap the rows into the box first,
    :func:`optik.analytic.wrap_into_limits` with ``bounds``: a branch wrapped into the
    limits can sit a turn away from a narrower box.)
    """
    slack = np.where(lower == upper, FROZEN_MATCH_TOLERANCE, LIMIT_TOLERANCE)
    inside = np.all((rows >= lower - slack) & (rows <= upper + slack), axis=-1)
    return inside, np.clip(rows, lower, upper)


def resolve_limits(
    joint: str,
    kind: str,
    role: str | None,
    lower: float | None,
    upper: float | None,
    continuous: bool = False,
) -> tuple[float, float]:
    """Return validated ``(lower, upper)`` for one joint in SI units.

    Args:
        joint: joint name, for messages.
        kind: ``"revolute"`` or ``"prismatic"``.
        role: ``"arm"``, ``"wrist"``, ``"spindle"`` or ``None``; supplies defaults.
        lower: stated lower limit, or ``None``.
        upper: stated upper limit, or ``None``.
        continuous: an unbounded revolute joint (both limits infinite).

    Raises:
        ModelError: unknown role, a prismatic joint without limits, a joint with neither
            limits nor role, or a continuous prismatic joint.
        InvalidLimitsError: NaN, lower > upper, infinite limits on a bounded joint, a
            limit that is not a number, or a finite limit beyond ``MAX_LENGTH_M`` (rad or
            m).
    """
    if role is not None and role not in ROLE_LIMITS_RAD:
        raise ModelError(
            f"joint {joint!r}: unknown role {role!r} (expected one of {sorted(ROLE_LIMITS_RAD)})"
        )
    if continuous:
        if kind != "revolute":
            raise ModelError(f"joint {joint!r}: only a revolute joint can be continuous")
        if lower is not None or upper is not None:
            raise ModelError(f"joint {joint!r}: a continuous joint takes no lower/upper limits")
        return -math.inf, math.inf
    if lower is None and upper is None:
        if kind == "prismatic":
            raise ModelError(f"joint {joint!r}: a prismatic joint must state its range")
        if role is None:
            raise ModelError(
                f"joint {joint!r}: states neither limits nor a role (arm, wrist, spindle)"
            )
        return ROLE_LIMITS_RAD[role]
    if lower is None or upper is None:
        raise ModelError(f"joint {joint!r}: states only one of lower/upper")
    if isinstance(lower, str) or isinstance(upper, str):
        raise InvalidLimitsError(joint, lower, upper, "limits must be numbers, not strings")
    try:
        lo, hi = float(lower), float(upper)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InvalidLimitsError(joint, lower, upper, "limits must be numbers") from exc
    if isinstance(lower, bool) or isinstance(upper, bool):
        raise InvalidLimitsError(joint, lower, upper, "limits must be numbers, not booleans")
    if math.isnan(lo) or math.isnan(hi):
        raise InvalidLimitsError(joint, lo, hi, "NaN limit")
    if kind == "prismatic" and max(abs(lo), abs(hi)) > MAX_LENGTH_M and math.isfinite(lo + hi):
        raise InvalidLimitsError(
            joint, lo, hi, f"a prismatic range must lie within +-{MAX_LENGTH_M:g} m"
        )
    if lo > hi:
        raise InvalidLimitsError(joint, lo, hi)
    if (math.isinf(lo) or math.isinf(hi)) and (
        kind != "revolute" or not (lo == -math.inf and hi == math.inf)
    ):
        raise InvalidLimitsError(
            joint, lo, hi, "only a continuous revolute joint may have infinite limits"
        )
    check_limit_magnitude(joint, kind, lo, hi)
    return lo, hi


def limit_violation(q: FloatArray, lower: FloatArray, upper: FloatArray) -> FloatArray | float:
    """Largest distance (rad or m) by which ``q`` (or each row of a batch) leaves its limits."""
    excess = np.maximum(np.maximum(lower - q, q - upper), 0.0)
    out = np.max(excess, axis=-1) if excess.shape[-1] else np.zeros(excess.shape[:-1])
    return float(out) if np.ndim(out) == 0 else out


def within_limits(
    q: FloatArray, lower: FloatArray, upper: FloatArray, tol: float = LIMIT_TOLERANCE
) -> bool | FloatArray:
    """Whether ``q`` (or each row of a batch) lies inside the limits, up to ``tol``."""
    # The differences, as limit_violation forms them: the same verdict to the last bit.
    inside = np.all((lower - q <= tol) & (q - upper <= tol), axis=-1)
    return bool(inside) if np.ndim(inside) == 0 else inside


def check_limit_magnitude(joint: str, kind: str, lower: float, upper: float) -> None:
    """A range must lie within +-:data:`~optik._checks.MAX_LENGTH_M` (rad or m).

    A prismatic range must also be finite; a revolute one may be infinite (a continuous
    joint), but a finite bound beyond it would let no configuration near it be checked
    (:meth:`optik.Robot.check_q` bounds joint values alike).
    """
    if kind == "prismatic" and not (abs(lower) <= MAX_LENGTH_M and abs(upper) <= MAX_LENGTH_M):
        raise InvalidLimitsError(
            joint, lower, upper, f"a prismatic range must lie within +-{MAX_LENGTH_M:g} m"
        )
    beyond = [b for b in (lower, upper) if math.isfinite(b) and abs(b) > MAX_LENGTH_M]
    if kind != "prismatic" and beyond:
        raise InvalidLimitsError(
            joint,
            lower,
            upper,
            f"a finite revolute range must lie within +-{MAX_LENGTH_M:g} rad "
            "(infinite limits make the joint continuous)",
        )


def finite_or_inf_limits(limits: Any, dof: int) -> FloatArray:
    """Validate a ``(dof, 2)`` limits array (infinities allowed, NaN rejected)."""
    lim = as_float_array("limits", limits)
    if lim.shape != (dof, 2):
        raise ShapeError("limits", f"({dof}, 2)", lim.shape)
    if np.any(np.isnan(lim)):
        check_finite("limits", np.where(np.isinf(lim), 0.0, lim))
    return lim
