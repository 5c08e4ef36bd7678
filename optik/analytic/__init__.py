"""Closed-form (analytic) IK: every branch, verified by forward kinematics.

One family per module, registered by name; a robot names its family (``analytic`` in a
problem file or the ``analytic=`` argument of its constructor), or
:func:`detect_family` finds the first registered family that fits its joint structure.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from optik._checks import FloatArray, finite_array
from optik.analytic import dobot, planar_2r, spherical_rrp, spherical_wrist, ur  # noqa: F401
from optik.analytic._base import FAMILIES, AnalyticFamily, wrap_to_pi
from optik.errors import AnalyticIKError
from optik.model import Robot
from optik.spatial import as_pose, invert_transform, pose_error, transform

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
        return detect_family(robot)
    family = FAMILIES.get(robot.analytic)
    if family is None:
        raise AnalyticIKError(
            f"robot {robot.name!r}: unknown analytic family {robot.analytic!r} "
            f"(registered: {sorted(FAMILIES)})"
        )
    if not family.fits(robot):
        raise AnalyticIKError(
            f"robot {robot.name!r}: its joint structure does not fit family {family.name!r}"
        )
    return family


def _target_pose(target: Any, mode: str) -> FloatArray:
    if mode == "pose":
        return as_pose("target", target)
    array = np.asarray(target, dtype=float) if not isinstance(target, np.ndarray) else target
    if np.shape(array) == (4, 4):
        return transform(None, as_pose("target", array)[:3, 3])
    return transform(None, finite_array("target", array, (3,)))


def wrap_into_limits(q: FloatArray, robot: Robot, q_ref: FloatArray) -> FloatArray:
    """Shift revolute angles by multiples of 2 pi into the limits, nearest ``q_ref``.

    A joint whose range spans more than 2 pi has several representatives: the one nearest
    ``q_ref`` is kept. An angle with no representative inside stays nearest ``q_ref``.
    """
    out = q.copy()
    two_pi = 2.0 * math.pi
    for i, joint in enumerate(robot.joints):
        if joint.kind != "revolute":
            continue
        base = q_ref[i] + wrap_to_pi(q[i] - q_ref[i])
        lo, hi = joint.lower, joint.upper
        if not math.isfinite(lo):
            out[i] = base
            continue
        k_min = math.ceil((lo - base) / two_pi - 1e-12)
        k_max = math.floor((hi - base) / two_pi + 1e-12)
        if k_min > k_max:
            out[i] = base
            continue
        options = base + two_pi * np.arange(k_min, k_max + 1)
        out[i] = float(options[np.argmin(np.abs(options - q_ref[i]))])
    return out


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
        raise AnalyticIKError(
            f"family {family.name!r} solves mode(s) {family.modes}, not {mode!r}"
        )
    T_target = _target_pose(target, mode)
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
    branches: list[FloatArray] = []
    for raw in family.candidates(robot, T_0_flange, mode, ref):
        if not np.all(np.isfinite(raw)):
            continue
        q = wrap_into_limits(raw, robot, ref)
        if within_limits and not robot.within_limits(q):
            continue
        position_error, orientation_error = pose_error(robot.fk(q), T_target)
        if position_error > VERIFY_TOLERANCE:
            continue
        if mode == "pose" and orientation_error > VERIFY_TOLERANCE:
            continue
        if any(np.max(np.abs(q - other)) < _DUPLICATE for other in branches):
            continue
        branches.append(q)
    if sort:
        branches.sort(key=lambda q: float(np.linalg.norm(q - ref)))
    return branches
