"""Closed-form (analytic) IK: every branch, verified by forward kinematics.

One family per module, registered by name; a robot names its family (``analytic`` in a
problem file or the ``analytic=`` argument of its constructor), or
:func:`detect_family` finds the first registered family that fits its joint structure.
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np

from optik._checks import FloatArray
from optik.analytic import dobot, planar_2r, spherical_rrp, spherical_wrist, ur  # noqa: F401
from optik.analytic._base import FAMILIES, AnalyticFamily
from optik.errors import AnalyticIKError
from optik.model import Robot
from optik.spatial import as_target, invert_transform, rotation_angle

VERIFY_TOLERANCE = 1e-9
"""Largest position (m) and orientation (rad) error of a returned branch."""

_DUPLICATE = 1e-9

__all__ = ["FAMILIES", "AnalyticFamily", "analytic_ik", "detect_family", "family_of"]


def detect_family(robot: Robot) -> AnalyticFamily | None:
    """The first registered family whose structure fits ``robot``, or ``None``."""
    for family in FAMILIES.values():
        if family.fits(robot):
            return family
    return None


def family_of(robot: Robot) -> AnalyticFamily | None:
    """The robot's declared family (checked to fit), else a detected one, else ``None``.

    Raises:
        AnalyticIKError: the declared family is unknown or does not fit the robot.
    """
    if robot.analytic is None:
        if "family" not in robot._cache:
            robot._cache["family"] = detect_family(robot)
        return cast("AnalyticFamily | None", robot._cache["family"])
    family = FAMILIES.get(robot.analytic)
    if family is None:
        raise AnalyticIKError(
            f"robot {robot.name!r}: unknown analytic family {robot.analytic!r} "
            f"(registered: {sorted(FAMILIES)})"
        )
    if robot._cache.get("declared_fits") is None:
        robot._cache["declared_fits"] = family.fits(robot)
    if not robot._cache["declared_fits"]:
        raise AnalyticIKError(
            f"robot {robot.name!r}: its joint structure does not fit family {family.name!r}"
        )
    return family


def wrap_into_limits(Q: FloatArray, robot: Robot, q_ref: FloatArray) -> FloatArray:
    """Shift revolute angles by multiples of 2 pi into the limits, nearest ``q_ref``.

    ``Q`` is (k, dof). A joint whose range spans more than 2 pi has several
    representatives: the one nearest ``q_ref`` is kept. An angle with no representative
    inside its limits stays at the representative nearest ``q_ref``.
    """
    two_pi = 2.0 * math.pi
    revolute = np.array([j.kind == "revolute" for j in robot.joints])
    base = q_ref + np.remainder(Q - q_ref + math.pi, two_pi) - math.pi
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.inf)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.inf)
    # Representatives base + 2 pi k inside [lower, upper]: k in [k_min, k_max].
    with np.errstate(invalid="ignore"):
        k_min = np.ceil((lower - base) / two_pi - 1e-12)
        k_max = np.floor((upper - base) / two_pi + 1e-12)
        k_near = np.round((q_ref - base) / two_pi)
    k = np.where(np.isfinite(k_min), np.maximum(k_near, k_min), k_near)
    k = np.where(np.isfinite(k_max), np.minimum(k, k_max), k)
    k = np.where(k_min > k_max, 0.0, k)
    k = np.where(np.isfinite(k), k, 0.0)
    return np.where(revolute, base + two_pi * k, Q)


def analytic_ik(
    robot: Robot,
    target: Any,
    mode: str = "pose",
    q_ref: Any = None,
    within_limits: bool = True,
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
        within_limits: drop branches outside the joint limits (default). With ``False``
            they are kept (still wrapped into the limits where a 2 pi shift allows).

    Returns:
        A list of joint vectors (dof,), possibly empty (unreachable, or reachable only
        outside the limits). Each reaches the target within ``VERIFY_TOLERANCE``.

    Raises:
        AnalyticIKError: the robot has no family, or the family does not solve ``mode``
            (e.g. position-only IK of a 6-dof arm, which has infinitely many solutions).
        OptikError: malformed target or ``q_ref``.
    """
    if mode not in ("pose", "position"):
        raise AnalyticIKError(f"mode must be 'pose' or 'position', got {mode!r}")
    family = family_of(robot)
    if family is None:
        raise AnalyticIKError(f"robot {robot.name!r} has no closed-form IK family")
    if mode not in family.modes:
        raise AnalyticIKError(f"family {family.name!r} solves mode(s) {family.modes}, not {mode!r}")
    T_target = as_target(target, mode)
    sort = q_ref is not None
    ref = robot.mid_limits if q_ref is None else robot.check_q(q_ref, "q_ref")
    if ref.ndim != 1:
        raise AnalyticIKError("q_ref must be a single configuration (dof,)")
    if mode == "position" and np.any(np.abs(robot.T_flange_tool[:3, 3]) > 0.0):
        raise AnalyticIKError(
            f"robot {robot.name!r}: position-only closed forms need a tool without offset"
        )
    T_0_flange = (
        invert_transform(robot.T_world_base) @ T_target @ invert_transform(robot.T_flange_tool)
    )
    raw = family.candidates(robot, T_0_flange, mode, ref)
    if not raw:
        return []
    Q = np.array(raw, dtype=float)
    Q = wrap_into_limits(Q[np.all(np.isfinite(Q), axis=1)], robot, ref)
    if within_limits:
        Q = Q[np.asarray(robot.within_limits(Q), dtype=bool).reshape(-1)]
    if len(Q) == 0:
        return []
    T = robot.fk(Q)
    good = np.linalg.norm(T[:, :3, 3] - T_target[:3, 3], axis=1) <= VERIFY_TOLERANCE
    if mode == "pose":
        R_rel = np.swapaxes(T[:, :3, :3], 1, 2) @ T_target[:3, :3]
        angle = np.asarray(rotation_angle(R_rel), dtype=float).reshape(-1)
        good &= angle <= VERIFY_TOLERANCE
    branches: list[FloatArray] = []
    for q in Q[good]:
        if any(np.max(np.abs(q - other)) < _DUPLICATE for other in branches):
            continue
        branches.append(q)
    if sort:
        branches.sort(key=lambda q: float(np.linalg.norm(q - ref)))
    return branches
