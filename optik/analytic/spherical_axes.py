"""Six revolute joints with three axes through one point, found from the joint axes.

The family ``spherical_axes`` takes any chain of six revolute joints whose axes at
``q = 0`` (:func:`optik.analytic.geometry.joint_axes`, world frame, whatever the robot
was read from) have a spherical wrist (axes 4, 5 and 6 through one point) and an arm the
Paden–Kahan subproblems solve:

- axes 1 and 2 meet, and axis 3 passes through neither that point nor the wrist centre
  (:mod:`optik.analytic.pair_wrist`; EAIK's "spherical, first two intersecting");
- axes 1 and 2 are parallel (:data:`optik.analytic.parallel_arm.PARALLEL_12`; "first two
  parallel");
- axes 2 and 3 are parallel (:data:`optik.analytic.parallel_arm.PARALLEL_23`; "second
  two parallel": the Puma and the UR-less industrial arms with any twists and offsets).

Or the same read backwards (:func:`optik.analytic.geometry.reversed_axes`): a spherical
shoulder (axes 1, 2 and 3 through one point) and an arm among axes 4 to 6. Tolerances are
those of the geometry (:data:`optik.analytic.geometry.ANGLE_TOL`, ``LENGTH_TOL`` times the
arm's size). It is registered after the DH families: a robot that ``spherical_wrist`` or
``ur`` fits keeps that family; this one covers the twists, offsets and joint orders they
do not. The closed forms are compiled; the wrapping, limit filter and FK check run in
numpy (:func:`optik.analytic.analytic_ik`'s Python path).
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import AnalyticFamily, register
from optik.analytic._compiled import MAX_BRANCHES, tolerance_block
from optik.analytic.geometry import (
    ANGLE_TOL,
    LENGTH_TOL,
    Axes,
    joint_axes,
    line_distance,
    point_line_distance,
    reversed_axes,
    revolute_chain_reason,
)
from optik.analytic.pair_wrist import (
    axis_label,
    meeting,
    pair_wrist_candidates,
    structure_reason,
    wrist_reason,
)
from optik.analytic.parallel_arm import PARALLEL_12, PARALLEL_23, parallel_arm_candidates
from optik.model import Robot
from optik.spatial import invert_transform

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")

INTERSECTING = 3
"""Arm kind: axes 1 and 2 meet (:func:`optik.analytic.pair_wrist.pair_wrist_candidates`)."""
KIND_NAMES = {
    INTERSECTING: "axes 1 and 2 meet",
    PARALLEL_12: "axes 1 and 2 parallel",
    PARALLEL_23: "axes 2 and 3 parallel",
}
"""What each arm kind means, for messages and docs."""


class AxesPlan(NamedTuple):
    """How a six-joint robot is solved by ``spherical_axes`` (:func:`axes_plan`).

    Attributes:
        kind: the arm's kind (:data:`INTERSECTING`, ``PARALLEL_12``, ``PARALLEL_23``),
            0 when the robot does not fit.
        reverse: whether the closed form solves the chain read backwards.
        directions: (6, 3) unit joint directions at ``q = 0`` of the chain as solved.
        points: (6, 3) a point on each of its axes (m).
        tool: (4, 4) its tool at ``q = 0``.
        tols: the tolerance block of :mod:`optik.analytic._compiled`.
        reason: ``""`` when the robot fits, else why not.
    """

    kind: int
    reverse: bool
    directions: FloatArray
    points: FloatArray
    tool: FloatArray
    tols: FloatArray
    reason: str


def _parallel(axes: Axes, i: int, j: int) -> bool:
    z = axes.directions
    return float(np.linalg.norm(np.cross(z[i], z[j]))) <= ANGLE_TOL


def arm_kind(axes: Axes, names: tuple[str, ...]) -> tuple[int, str]:
    """The arm kind of six axes with a spherical wrist, or ``(0, why not)``.

    Args:
        axes: the six joint axes at ``q = 0``.
        names: the six joints' names, for the messages.
    """
    why = wrist_reason(axes, names)
    if why is not None:
        return 0, why
    tol = LENGTH_TOL * axes.size
    z, p = axes.directions, axes.points
    W = meeting(axes, 3, 4)
    a1, a2, a3 = (axis_label(names, i) for i in range(3))
    if not _parallel(axes, 0, 1) and structure_reason(axes, names) is None:
        return INTERSECTING, ""
    for i, kind in ((0, PARALLEL_12), (1, PARALLEL_23)):
        if not _parallel(axes, i, i + 1):
            continue
        other = 2 if kind == PARALLEL_12 else 0
        label = f"axes {axis_label(names, i)} and {axis_label(names, i + 1)}"
        if line_distance(z[i], p[i], z[i + 1], p[i + 1]) <= tol:
            return 0, f"{label} are one line"
        if _parallel(axes, other, i):
            return 0, f"axes 1-3 are parallel ({label} and {axis_label(names, other)})"
        if point_line_distance(z[2], p[2], W) <= tol:
            return 0, f"axis {a3} passes through the wrist centre: it does not move it"
        return kind, ""
    # Axes 1 and 2 not parallel (else the loop returned): they fail the pair's test.
    return 0, (
        f"{structure_reason(axes, names)}, and neither axes {a1}, {a2} nor {a2}, {a3} are parallel"
    )


def axes_plan(robot: Robot) -> AxesPlan:
    """Whether (and how) ``spherical_axes`` solves ``robot``: in order, else read backwards.

    Args:
        robot: the robot.
    """
    empty = np.empty((0, 3))
    none = AxesPlan(0, False, empty, empty, np.eye(4), np.empty(0), "")
    reason = revolute_chain_reason(robot, 6)
    if reason is not None:
        return none._replace(reason=reason)
    axes = joint_axes(robot)
    names = robot.chain_names
    kind, why = arm_kind(axes, names)
    if kind:
        return AxesPlan(kind, False, *_arrays(axes), tolerance_block(), "")
    back = reversed_axes(axes)
    kind, why_back = arm_kind(back, names[::-1])
    if kind:
        return AxesPlan(kind, True, *_arrays(back), tolerance_block(), "")
    return none._replace(reason=f"{why}; read backwards: {why_back}")


def _arrays(axes: Axes) -> tuple[FloatArray, FloatArray, FloatArray]:
    return (
        np.ascontiguousarray(axes.directions, dtype=np.float64),
        np.ascontiguousarray(axes.points, dtype=np.float64),
        np.ascontiguousarray(axes.tool, dtype=np.float64),
    )


@_jit
def axes_candidates(
    z: np.ndarray,
    p: np.ndarray,
    M: np.ndarray,
    T: np.ndarray,
    ref: np.ndarray,
    kind: int,
    tols: np.ndarray,
    cand: np.ndarray,
) -> int:
    """Raw branches of arm ``kind`` and a spherical wrist into ``cand`` (8, 6).

    Arguments as :func:`optik.analytic.parallel_arm.parallel_arm_candidates` (world
    frame; ``T`` the tool's target); returns the number of rows written.
    """
    lsq = np.empty((3, 6, 6))
    if kind == INTERSECTING:
        return pair_wrist_candidates(z, p, M, T, ref, tols, cand, lsq)
    return parallel_arm_candidates(z, p, M, T, ref, kind, tols, cand, lsq)


@register
class SphericalAxes(AnalyticFamily):
    """Six revolute joints: a spherical wrist (or shoulder) and an arm of subproblems."""

    name = "spherical_axes"

    def fits(self, robot: Robot) -> bool:
        """Whether ``robot``'s joint axes have the structure (module docstring)."""
        return robot.cached(axes_plan).kind != 0

    def explain(self, robot: Robot) -> str | None:
        """Why the axes do not have the structure, or ``None`` when they do."""
        return robot.cached(axes_plan).reason or None

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to 8 raw branches: the arm's two angles, two each, then the wrist.

        Args:
            robot: the robot (fits this family).
            T_0_target: 4x4 flange target in frame 0.
            mode: ``"pose"``.
            q_ref: (6,) reference for the angles a singularity leaves free.
        """
        plan = robot.cached(axes_plan)
        T = robot.T_world_base @ T_0_target @ robot.T_flange_tool
        ref = np.asarray(q_ref, dtype=np.float64)
        if plan.reverse:
            T = invert_transform(T)
            ref = ref[::-1]
        out = np.empty((MAX_BRANCHES, 6))
        n = axes_candidates(
            plan.directions,
            plan.points,
            plan.tool,
            np.ascontiguousarray(T, dtype=np.float64),
            np.ascontiguousarray(ref),
            plan.kind,
            plan.tols,
            out,
        )
        rows = out[:n, ::-1] if plan.reverse else out[:n]
        return [np.array(row) for row in rows]


__all__ = ["INTERSECTING", "AxesPlan", "SphericalAxes", "arm_kind", "axes_plan"]
